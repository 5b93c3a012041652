"""A 3-D view of the plant in the browser: MuJoCo's geoms drawn by viser, served on loopback only.

Most users run on machines without a display, where MuJoCo's viewer cannot open. :class:`WebView`
serves the model on ``127.0.0.1`` (a free port by default; from another machine, forward it with
``ssh -L``): every visible geom becomes a mesh under its body's frame, and :meth:`WebView.show`
moves the body frames to a ``qpos`` (MuJoCo's own ``mj_kinematics``). :meth:`WebView.timeline`
adds play, pause and a time slider over a recorded trajectory; :meth:`WebView.add_path` and
:meth:`WebView.add_arrows` draw a reference path and per-frame arrows (contact forces).

Library: viser (the ``mbctl[web]`` extra), picked over meshcat and a hand-written three.js page:
it installs from the package registry with its client prebuilt (no Node, no CDN: the page loads
nothing from outside the loopback server), has GUI widgets (slider, buttons) driven from Python,
batched arrows and line segments, and is maintained (mjlab's browser viewer is built on it).
"""

from __future__ import annotations

import contextlib
import io
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from mbctl.sim.exceptions import SimError
from mbctl.sim.video import default_camera

#: The only address the viewer listens on.
LOOPBACK = "127.0.0.1"
#: Planes of size 0 (infinite in MuJoCo) are drawn this large [m].
PLANE_SIZE_M = 8.0


class WebViewError(SimError):
    """The web viewer cannot start (viser missing, port taken) or was given bad data."""


def _viser() -> Any:
    try:
        import viser
    except ImportError:
        raise WebViewError("the web viewer needs viser: pip install 'mbctl[web]'") from None
    return viser


def geom_mesh(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices (V, 3) [m] and triangles (F, 3) of ``geom`` in its own frame; None for a plane.

    Meshes come from MuJoCo's compiled mesh (already in the geom frame); primitives from trimesh
    with MuJoCo's size conventions (half lengths, capsule and cylinder along z).
    """
    import trimesh  # a dependency of viser

    kind, size = int(model.geom_type[geom]), model.geom_size[geom]
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_MESH:
        mesh = int(model.geom_dataid[geom])
        v0, nv = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        f0, nf = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        return model.mesh_vert[v0:v0 + nv].copy(), model.mesh_face[f0:f0 + nf].copy()
    if kind == t.mjGEOM_SPHERE:
        shape = trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    elif kind == t.mjGEOM_CAPSULE:
        shape = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[16, 16])
    elif kind == t.mjGEOM_CYLINDER:
        shape = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=24)
    elif kind == t.mjGEOM_BOX:
        shape = trimesh.creation.box(extents=2 * size)
    elif kind == t.mjGEOM_ELLIPSOID:
        shape = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        shape.apply_scale(size)
    else:  # planes are drawn as grids; heightfields and SDFs are not drawn
        return None
    return np.asarray(shape.vertices), np.asarray(shape.faces)


def geom_rgb(model: mujoco.MjModel, geom: int) -> tuple[tuple[int, int, int], float]:
    """The colour of ``geom`` as MuJoCo shows it (its material's, else its own): RGB 0-255, alpha."""
    mat = int(model.geom_matid[geom])
    rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[geom]
    r, g, b = (int(round(255 * float(c))) for c in rgba[:3])
    return (r, g, b), float(rgba[3])


def camera_pose(
    model: mujoco.MjModel, data: mujoco.MjData, track_body: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """(position, look_at) [m] in W of the camera the videos use (``sim.video.default_camera``)."""
    cam = default_camera(model, data, track_body)
    look_at = np.array(data.xpos[track_body]) if track_body is not None else np.array(cam.lookat)
    az, el = np.radians(cam.azimuth), np.radians(cam.elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return look_at - cam.distance * forward, look_at


@dataclass(frozen=True)
class Timeline:
    """Frames to play: times (n,) [s] ascending; ``on_frame(i)`` draws frame i."""

    t_s: np.ndarray
    on_frame: Callable[[int], None]


class WebView:
    """A MuJoCo model served to the browser on ``127.0.0.1:port`` (0: a free port).

    Args:
        model: The plant's model.
        port: TCP port on the loopback interface; 0 picks a free one (see :attr:`url`).
        track_body: A floating base the initial camera looks at, or None (frame the model).
        title: Shown at the top of the control panel.

    Raises:
        WebViewError: viser is not installed, or the port cannot be bound.
    """

    def __init__(self, model: mujoco.MjModel, port: int = 0, track_body: int | None = None,
                 title: str = "mbctl"):
        viser = _viser()
        if not 0 <= int(port) <= 65535:
            raise WebViewError(f"port must be in [0, 65535] (0: a free port); got {port}")
        self.model, self.data = model, mujoco.MjData(model)
        try:  # viser prints a banner whatever `verbose` says; we print our own URL line
            with contextlib.redirect_stdout(io.StringIO()):
                self.server = viser.ViserServer(host=LOOPBACK, port=int(port), label=title, verbose=False)
        except OSError as exc:
            raise WebViewError(f"cannot serve on {LOOPBACK}:{port}: {exc}") from exc
        if port and self.server.get_port() != int(port):  # viser moves on to the next free port
            with contextlib.redirect_stdout(io.StringIO()):
                self.server.stop()
            raise WebViewError(f"cannot serve on {LOOPBACK}:{port}: the port is taken; choose another "
                               "or --port 0 for a free one")
        self.server.scene.set_up_direction("+z")
        self._stop = threading.Event()
        self.bodies: dict[int, Any] = {}
        self.playback: Playback | None = None
        #: Scene handles of the overlays (paths, arrows) by name.
        self.overlays: dict[str, Any] = {}
        self._build()
        mujoco.mj_kinematics(model, self.data)
        position, look_at = camera_pose(model, self.data, track_body)
        self.server.initial_camera.position = tuple(position)
        self.server.initial_camera.look_at = tuple(look_at)

    @property
    def port(self) -> int:
        """The bound TCP port."""
        return int(self.server.get_port())

    @property
    def url(self) -> str:
        """The page's address (loopback)."""
        return f"http://{LOOPBACK}:{self.port}/"

    def _build(self) -> None:
        m, scene = self.model, self.server.scene
        shown = mujoco.MjvOption().geomgroup  # the groups MuJoCo's viewer shows by default
        for g in range(m.ngeom):
            rgb, alpha = geom_rgb(m, g)
            group = int(m.geom_group[g])
            if alpha == 0 or not (0 <= group < len(shown) and shown[group]):
                continue
            body = int(m.geom_bodyid[g])
            if body not in self.bodies:
                self.bodies[body] = scene.add_frame(f"/model/body{body}", show_axes=False)
            name = f"/model/body{body}/geom{g}"
            pos, quat = m.geom_pos[g], m.geom_quat[g]  # in the body frame, quaternion w, x, y, z
            if int(m.geom_type[g]) == mujoco.mjtGeom.mjGEOM_PLANE:
                half = [s if s > 0 else PLANE_SIZE_M / 2 for s in m.geom_size[g][:2]]
                scene.add_grid(name, 2 * half[0], 2 * half[1], cell_size=0.1, section_size=1.0,
                               position=pos, wxyz=quat)
                continue
            mesh = geom_mesh(m, g)
            if mesh is not None:
                scene.add_mesh_simple(name, *mesh, color=rgb, opacity=None if alpha >= 1 else alpha,
                                      position=pos, wxyz=quat)

    def set_robot_visible(self, visible: bool) -> None:
        """Show or hide every moving body (the world's own geoms stay)."""
        for body, frame in self.bodies.items():
            if body != 0:
                frame.visible = visible

    def show(self, qpos: np.ndarray) -> None:
        """Move the bodies to ``qpos`` (model nq, MuJoCo convention)."""
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        with self.server.atomic():
            for body, frame in self.bodies.items():
                frame.position = self.data.xpos[body]
                frame.wxyz = self.data.xquat[body]

    def add_path(self, points_m: np.ndarray, rgb: tuple[int, int, int] = (30, 160, 60),
                 name: str = "/overlay/path") -> None:
        """A polyline through ``points_m`` (n, 3) [m] in W (e.g. a reference path)."""
        p = np.asarray(points_m, dtype=float).reshape(-1, 3)
        if len(p) >= 2:
            self.overlays[name] = self.server.scene.add_line_segments(
                name, np.stack([p[:-1], p[1:]], axis=1), rgb, thickness=3.0, thickness_units="screen")

    def add_arrows(self, name: str, start_m: np.ndarray, vector_m: np.ndarray,
                   rgb: tuple[int, int, int], shaft_radius_m: float = 0.008) -> Callable[[int], None]:
        """Arrows that change per frame: ``start_m``, ``vector_m`` (n_frames, k, 3) [m] in W.

        The handle is kept in :attr:`overlays` under ``name``. Returns ``draw(i)``, which shows
        frame i's k arrows (zero-length arrows are hidden).
        """
        start, vec = np.asarray(start_m, dtype=float), np.asarray(vector_m, dtype=float)
        handle = self.server.scene.add_arrows(
            name, np.stack([start[0], start[0] + vec[0]], axis=1), rgb,
            shaft_radius=shaft_radius_m, head_radius=2.5 * shaft_radius_m, head_length=5 * shaft_radius_m)
        self.overlays[name] = handle

        def draw(i: int) -> None:
            visible = np.linalg.norm(vec[i], axis=1) > 1e-6
            pts = np.stack([start[i], start[i] + vec[i]], axis=1)
            pts[~visible, 1] = pts[~visible, 0] + 1e-6  # a degenerate arrow draws nothing visible
            handle.points = pts.astype(np.float32)

        return draw

    def timeline(self, timeline: Timeline, fps: float = 30.0) -> Playback:
        """Play, pause and a time slider over ``timeline`` (kept as :attr:`playback`).

        Playback runs in a thread at ``fps`` updates per wall-clock second, in real time times
        the chosen speed; moving the slider shows the frame at or before that time.
        """
        t = np.asarray(timeline.t_s, dtype=float)
        if t.ndim != 1 or not len(t) or np.any(np.diff(t) < 0) or not np.all(np.isfinite(t)):
            raise WebViewError("a timeline needs finite, ascending times (n >= 1)")
        self.playback = Playback(self.server.gui, t, timeline.on_frame, self._stop, fps)
        return self.playback

    def note(self, markdown: str) -> None:
        """A paragraph of text in the control panel."""
        self.server.gui.add_markdown(markdown)

    def close(self) -> None:
        """Stop playback and the server (idempotent)."""
        if not self._stop.is_set():
            self._stop.set()
            if self.playback is not None:
                self.playback.thread.join(timeout=5.0)
            with contextlib.redirect_stdout(io.StringIO()):
                self.server.stop()

    def __enter__(self) -> WebView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Playback:
    """Play, pause and scrub a timeline: a slider, a Play/Pause button and a speed choice.

    Attributes:
        frame: The frame shown last.
        slider: The time slider [s].
    """

    def __init__(self, gui: Any, t_s: np.ndarray, on_frame: Callable[[int], None],
                 stop: threading.Event, fps: float):
        self.t, self.on_frame, self.frame = t_s, on_frame, -1
        span = float(t_s[-1] - t_s[0])
        step = max(span / 1000.0, 1e-3)
        self.slider = gui.add_slider("time (s)", float(t_s[0]), float(t_s[0]) + max(span, step), step,
                                     float(t_s[0]))
        self.button = gui.add_button("Play")
        self.speed = gui.add_dropdown("speed", ("0.25x", "0.5x", "1x", "2x"), initial_value="1x")
        self._playing = threading.Event()
        self._lock = threading.Lock()  # the frame shown, vs. the slider's callback and the player
        self._tick = threading.RLock()  # a player's step, vs. play/pause: no step lands after a pause
        self.slider.on_update(lambda _: self._draw(self.slider.value))
        self.button.on_click(lambda _: self.pause() if self.playing else self.play())
        self.thread = threading.Thread(target=self._run, args=(stop, fps), name="mbctl-web-playback",
                                       daemon=True)
        self._draw(float(t_s[0]))
        self.thread.start()

    @property
    def playing(self) -> bool:
        """Whether the timeline is playing."""
        return self._playing.is_set()

    def _draw(self, t_s: float) -> None:
        i = max(int(np.searchsorted(self.t, t_s + 1e-9, side="right")) - 1, 0)
        with self._lock:
            if i != self.frame:
                self.on_frame(i)
                self.frame = i

    def seek(self, t_s: float) -> None:
        """Show the frame at or before ``t_s`` [s] (what moving the slider does)."""
        self.slider.value = float(np.clip(t_s, self.t[0], self.t[-1]))
        self._draw(self.slider.value)

    def play(self) -> None:
        """Play from the slider's time (from the start when at the end)."""
        with self._tick:
            if self.slider.value >= self.t[-1] - 1e-9:
                self.seek(float(self.t[0]))
            self._playing.set()
            self.button.label = "Pause"

    def pause(self) -> None:
        """Stop at the current frame (a step the player is drawing finishes first; none comes after)."""
        with self._tick:
            self._playing.clear()
            self.button.label = "Play"

    def _run(self, stop: threading.Event, fps: float) -> None:
        while not stop.wait(1.0 / fps):
            with self._tick:  # checked and drawn as one: a pause between the two would be overrun
                if not self._playing.is_set():
                    continue
                now = self.slider.value + float(self.speed.value[:-1]) / fps
                if now >= self.t[-1]:
                    now = float(self.t[-1])
                    self.pause()
                self.seek(now)
