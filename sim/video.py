"""Headless video of the plant: MuJoCo's renderer, frames streamed into an MP4 as they are drawn.

A :class:`VideoRecorder` is a simulator observer: whenever simulated time passes the next frame
time (``fps`` frames per simulated second) it sends the plant's pose and the frame's extra geoms
(contact-force arrows, overlay markers) to render workers (:mod:`mbctl.sim.video_workers`), which
draw and encode while the simulation goes on; an interrupted run leaves a playable video of what
ran. The MP4 is fragmented (``-movflags frag_keyframe+empty_moov``, a keyframe every 0.5 s, each
fragment flushed to disk): playable up to about 0.6 s before its end even if the processes die
before closing it. It is written at its own name from the first frame (ffmpeg writes to its
stdout, a file created after removing whatever was at the name: a symbolic link planted there is
never followed), so a process killed outright (SIGKILL) leaves ``video.mp4`` where a user and
``mbctl replay`` look for it; the workers and the encoder, which outlive it, render and encode
every frame it had sent and finish the file.
With no recorder the simulator pays nothing.

Contact forces are drawn as MuJoCo draws them: at each contact point, the force the other side
(the floor) exerts on the robot, so a standing robot's arrows point up (the browser view,
:mod:`mbctl.jobs.web_view`, draws the same force).

Encoder: imageio-ffmpeg, which ships its own ffmpeg binary (no system install);
the ``mbctl[video]`` extra. OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is first
imported; ``mbctl.gl.choose_gl_backend`` probes EGL, then OSMesa, in subprocesses before that.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from mbctl.gl import VideoError
from mbctl.sim.simulator import Simulator
from mbctl.sim.trajectory import base_body
from mbctl.sim.video_pool import RenderPool
from mbctl.sim.video_workers import CameraSpec, ExtraGeoms, FrameState, default_workers, make_renderer

__all__ = ["VideoError", "VideoRecorder", "VideoSpec", "add_markers", "contact_force_geoms",
           "default_camera", "film_trajectory", "make_renderer", "parse_size", "still"]


@dataclass(frozen=True)
class VideoSpec:
    """How a run is filmed.

    Attributes:
        width: Frame width [px].
        height: Frame height [px].
        fps: Frames per simulated second.
        contact_forces: Draw contact force arrows.
    """

    width: int = 640
    height: int = 480
    fps: float = 30.0
    contact_forces: bool = False

    def __post_init__(self) -> None:
        for name, value in (("width", self.width), ("height", self.height)):
            if not 16 <= value <= 4096 or value % 2:
                raise VideoError(
                    f"video {name} must be an even number of pixels in [16, 4096]; got {value}"
                )
        if not 0 < self.fps <= 240:
            raise VideoError(f"video fps must be in (0, 240]; got {self.fps}")


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` -> (width, height) [px]; VideoError naming the text otherwise."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match:
        raise VideoError(f"video size must be WIDTHxHEIGHT in pixels, e.g. 640x480; got {text!r}")
    return int(match.group(1)), int(match.group(2))


def default_camera(
    model: mujoco.MjModel, data: mujoco.MjData, track_body: int | None,
    qpos_samples: np.ndarray | None = None, points_W: np.ndarray | None = None,
) -> mujoco.MjvCamera:
    """A camera that tracks ``track_body`` (a floating base) or frames the whole model (fixed).

    A fixed robot is framed on the body origins (with mass) at ``data``'s configuration and at
    each of ``qpos_samples`` (k, nq) (the motion to come: a planned trajectory, or a recorded
    one), and on ``points_W`` (m, 3) [m] (a reference path). A fixed robot whose hinges all share
    one axis (a planar arm) is seen along that axis, the framed box filling most of the image.
    """
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    mujoco.mj_kinematics(model, data)
    # Frame the bodies (not MuJoCo's stat.extent, which a floor plane or far props inflate):
    # the bounding box of the body origins that carry mass, world excluded.
    heavy = np.flatnonzero(model.body_mass[1:] > 0) + 1
    if not heavy.size:
        heavy = np.arange(1, model.nbody)
    points = [data.xpos[heavy].copy()]
    if qpos_samples is not None and track_body is None:
        scratch = mujoco.MjData(model)
        for q in np.asarray(qpos_samples, dtype=float).reshape(-1, model.nq):
            scratch.qpos[:] = q
            mujoco.mj_kinematics(model, scratch)
            points.append(scratch.xpos[heavy].copy())
    if points_W is not None and track_body is None:
        points.append(np.asarray(points_W, dtype=float).reshape(-1, 3))
    cloud = np.vstack(points)
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    size = max(float(np.linalg.norm(hi - lo)), 0.2)
    if track_body is not None:
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = track_body
        cam.distance, cam.elevation, cam.azimuth = 2.2 * size, -15.0, 140.0
        return cam
    cam.lookat[:] = (lo + hi) / 2
    cam.distance = 2.5 * size
    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    axes = [data.xaxis[j] / np.linalg.norm(data.xaxis[j]) for j in hinges]
    if axes and all(abs(float(a @ axes[0])) > 0.999 for a in axes):
        ax = axes[0] if axes[0][2] >= 0 else -axes[0]  # look down the common axis
        cam.elevation = float(-np.degrees(np.arcsin(np.clip(ax[2], -1, 1))))
        cam.azimuth = float(np.degrees(np.arctan2(-ax[1], -ax[0]))) if abs(ax[2]) < 0.999 else 90.0
        # Fill the image: the framed points' box across the view axis, 25 % larger, fits the
        # vertical field of view and the width of a 4:3 frame. Screen axes as MuJoCo draws them:
        # looking down z, x right and y up; looking horizontally, z up.
        forward = -ax
        up = np.array([0.0, 1.0, 0.0]) if abs(ax[2]) >= 0.999 else np.array([0.0, 0.0, 1.0])
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        u, v = cloud @ right, cloud @ up
        centre = right * (u.max() + u.min()) / 2 + up * (v.max() + v.min()) / 2
        cam.lookat[:] = centre + ax * float(np.mean(cloud @ ax))
        half = 1.25 * max((v.max() - v.min()) / 2, (u.max() - u.min()) / 2 / (4 / 3), 0.05)
        cam.distance = half / np.tan(np.radians(float(model.vis.global_.fovy)) / 2)
    return cam


Overlay = Callable[[mujoco.MjvScene], None]


def add_markers(
    scene: mujoco.MjvScene, points: np.ndarray, radius_m: float, rgba: tuple[float, ...]
) -> None:
    """Append small spheres at ``points`` (n, 3) [m] to ``scene`` (as many as it has room for)."""
    for p in points:
        if scene.ngeom >= scene.maxgeom:
            return
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                            np.array([radius_m, 0, 0]), np.asarray(p, dtype=float), np.eye(3).ravel(),
                            np.asarray(rgba, dtype=np.float32))
        scene.ngeom += 1


def contact_force_geoms(model: mujoco.MjModel, data: mujoco.MjData,
                        scene: mujoco.MjvScene | None = None) -> ExtraGeoms:
    """The contact-force arrows MuJoCo draws for ``data`` (``mjVIS_CONTACTFORCE``), one per contact.

    Each arrow starts at its contact point (``pos`` [m] in W) and points along its z axis (the
    third column of ``mat``): the force the other side exerts on the body of higher id, the
    robot for a contact with the floor (world body 0), so up for a standing robot.
    """
    options = mujoco.MjvOption()
    options.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = True
    scene = scene if scene is not None else mujoco.MjvScene(model, maxgeom=1000)
    scene.ngeom = 0
    mujoco.mjv_updateScene(model, data, options, None, mujoco.MjvCamera(), mujoco.mjtCatBit.mjCAT_DECOR,
                           scene)
    return ExtraGeoms.of(scene)


class VideoRecorder:
    """Films a simulator into an MP4: a frame every ``1 / fps`` simulated seconds.

    Use as an observer (``sim.add_observer(recorder)``, done by :meth:`attach`) and ``close()``
    in every case (the job runner does). Frames are drawn and encoded by ``workers`` processes
    (default: the cores the simulation leaves, 1 to 3) while the simulation runs.

    Args:
        sim: The plant to film.
        path: The MP4 file.
        spec: Frame size, rate and what to draw.
        overlay: Adds markers to each frame's scene (e.g. the reference path).
        frame_qpos: Plant configurations (k, nq) of the motion to come, which a fixed robot's
            camera frames (see :func:`default_camera`).
        frame_points_W: Points (m, 3) [m] in W the fixed camera frames too.
        workers: Render processes (None: :func:`~mbctl.sim.video_workers.default_workers`).
    """

    def __init__(self, sim: Simulator, path: Path, spec: VideoSpec = VideoSpec(),
                 overlay: Overlay | None = None, frame_qpos: np.ndarray | None = None,
                 frame_points_W: np.ndarray | None = None, workers: int | None = None):
        self.sim, self.path, self.spec, self.overlay = sim, Path(path), spec, overlay
        data = mujoco.MjData(sim.model)
        data.qpos[:] = sim.data.qpos
        # A fixed robot is framed on the motion to come (frame_qpos: plant qpos samples) and the
        # points drawn with it (a reference path), not only on where it starts.
        self.camera = default_camera(sim.model, data, base_body(sim.robot), frame_qpos, frame_points_W)
        self._scene = mujoco.MjvScene(sim.model, maxgeom=1000)  # the frame's extra geoms
        self._renderer: mujoco.Renderer | None = None  # in-process, for render() only
        self._pool = RenderPool(sim.model, spec.width, spec.height, CameraSpec.of(self.camera), self.path,
                                spec.fps, default_workers() if workers is None else workers)
        self.frames = 0
        self._next_t = float(sim.data.time) + 1.0 / spec.fps

    def attach(self) -> VideoRecorder:
        """Start filming: register as the simulator's observer."""
        self.sim.add_observer(self)
        return self

    def __call__(self, sim: Simulator) -> None:
        """Observer hook: send the frames that simulated time has reached."""
        if sim.data.time + 1e-9 < self._next_t:
            return
        repeat = 0
        while sim.data.time + 1e-9 >= self._next_t:  # a long sync() may span several frames
            repeat += 1
            self._next_t += 1.0 / self.spec.fps
        self._pool.submit(self.frame_state(), repeat)
        self.frames += repeat

    def extra(self) -> ExtraGeoms | None:
        """The geoms drawn on the model in this frame (contact forces, overlay), None without any."""
        if not self.spec.contact_forces and self.overlay is None:
            return None
        if self.spec.contact_forces:
            contact_force_geoms(self.sim.model, self.sim.data, self._scene)
        else:
            self._scene.ngeom = 0
        if self.overlay is not None:
            self.overlay(self._scene)
        return ExtraGeoms.of(self._scene)

    def frame_state(self) -> FrameState:
        """What the render workers need for the current frame (copies)."""
        d = self.sim.data
        return FrameState(d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), self.extra())

    def render(self) -> np.ndarray:
        """The current frame (height, width, 3) uint8, drawn in this process (a check, a still)."""
        if self._renderer is None:
            self._renderer = make_renderer(self.sim.model, self.spec.width, self.spec.height)
        self._renderer.update_scene(self.sim.data, self.camera)
        extra = self.extra()
        if extra is not None:
            extra.add_to(self._renderer.scene)
        return self._renderer.render()

    def close(self) -> None:
        """Stop filming, render what was sent and finish the file (idempotent)."""
        self.sim.remove_observer(self)
        try:
            self._pool.close()
        finally:
            if self._renderer is not None:
                self._renderer.close()
                self._renderer = None


def film_trajectory(model: mujoco.MjModel, t_s: np.ndarray, qpos: np.ndarray, path: Path,
                    spec: VideoSpec = VideoSpec(), track_body: int | None = None,
                    workers: int | None = None) -> int:
    """Render a recorded trajectory (``qpos`` (n, nq) at times ``t_s`` (n,)) into an MP4.

    Frame k shows the last sample at or before ``t_s[0] + k / fps``. The frames are drawn by
    ``workers`` processes (default: one per core, 1 to 4). Returns the frame count.
    """
    data = mujoco.MjData(model)
    if len(qpos):
        data.qpos[:] = qpos[0]
    camera = default_camera(model, data, track_body, qpos[:: max(1, len(qpos) // 100)])
    n = int(np.floor((t_s[-1] - t_s[0]) * spec.fps + 1e-9)) + 1 if len(t_s) else 0
    if not n:
        return 0
    pool = RenderPool(model, spec.width, spec.height, CameraSpec.of(camera), Path(path), spec.fps,
                      default_workers() if workers is None else workers)
    try:
        for k in range(n):
            i = int(np.searchsorted(t_s, t_s[0] + k / spec.fps + 1e-9, side="right")) - 1
            pool.submit(FrameState(qpos[max(i, 0)], data.mocap_pos, data.mocap_quat))
    finally:
        pool.close()
    return n


def still(model: mujoco.MjModel, data: mujoco.MjData, spec: VideoSpec, track_body: int | None) -> np.ndarray:
    """One frame (height, width, 3) uint8 of ``data``'s current state."""
    renderer = make_renderer(model, spec.width, spec.height)
    try:
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, default_camera(model, data, track_body))
        return renderer.render()
    finally:
        renderer.close()
