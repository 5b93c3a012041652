"""Headless video of the plant: MuJoCo's renderer, frames streamed into an MP4 as they are drawn.

A :class:`VideoRecorder` is a simulator observer: it renders a frame whenever simulated time
passes the next frame time (``fps`` frames per simulated second) and hands it to the encoder at
once, so an interrupted run leaves a playable video of what ran. The MP4 is fragmented
(``-movflags frag_keyframe+empty_moov``, a keyframe every 0.5 s, each fragment flushed to disk):
playable up to about 0.6 s before its end even if the process and its encoder die before closing
it. It is written at its own name from the first frame (ffmpeg writes to its stdout, a file we
create after removing whatever was at the name: a symbolic link planted there is never
followed), so a process killed outright (SIGKILL) leaves ``video.mp4`` where a user and ``mbctl
replay`` look for it; the encoder, which outlives it, then reads the end of its input and
finishes the file.
With no recorder the simulator pays nothing.

Encoder: imageio-ffmpeg, which ships its own ffmpeg binary (no system install);
the ``mbctl[video]`` extra. OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is first
imported; ``mbctl.gl.choose_gl_backend`` probes EGL, then OSMesa, in subprocesses before that.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import IO

import mujoco
import numpy as np

from mbctl.gl import INSTALL_HINT, VideoError
from mbctl.sim.atomic import FILE_MODE
from mbctl.sim.simulator import Simulator
from mbctl.sim.trajectory import base_body


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


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """MuJoCo's offscreen renderer at width x height [px] (the offscreen buffer grown if needed).

    Raises:
        VideoError: OpenGL cannot be initialised (the message says what to install).
    """
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    try:
        renderer = mujoco.Renderer(model, height, width)
        # Floor reflections cost ~60 ms of a G1 frame in software GL (bench/bench_video.py) for
        # little information; shadows stay (they show contact with the floor).
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        return renderer
    except Exception as exc:  # GL errors come as several types (RuntimeError, AttributeError, ...)
        raise VideoError(
            f"MuJoCo's renderer cannot start with MUJOCO_GL={os.environ.get('MUJOCO_GL', '(unset)')}: "
            f"{type(exc).__name__}: {exc}; {INSTALL_HINT}"
        ) from exc


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


#: Keyframe interval and x264 lookahead [s of video]. The fragmented MP4 is written a fragment per
#: keyframe, once the encoder has emitted the next keyframe, so the file on disk lags the frames
#: sent by about one interval plus the lookahead. x264's defaults (a keyframe every 250 frames, 40
#: frames of lookahead) kept a 3 s clip unplayable until it was closed; with 0.5 s and 0.33 s the
#: file plays to within 0.6 s of the last frame sent (tests/sim/test_video.py), for 15 % more bytes.
KEYFRAME_INTERVAL_S, LOOKAHEAD_S = 0.5, 1.0 / 3.0


def _create_new(path: Path) -> int:
    """A write descriptor on a new file at ``path`` (mode 0644).

    Whatever was there (a file, a symbolic link) is removed first, never followed or written
    through (``O_EXCL | O_NOFOLLOW``).
    """
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, FILE_MODE)


class _Writer:
    """An MP4 written at ``path`` as it is encoded.

    ffmpeg reads raw frames on its stdin and writes the fragmented MP4 on its stdout, which is
    the file (created by us, ``_create_new``).

    ffmpeg never opens a file by name, so no symbolic link is ever followed; the video is at its
    final name from the first frame, so a run killed outright (SIGKILL) leaves ``video.mp4``
    itself, playable up to its last fragment (and whole once ffmpeg, which outlives the killed
    process, reads the end of its input). A video without frames is never created.
    """

    def __init__(self, path: Path, fps: float):
        try:
            import imageio_ffmpeg
        except ImportError:
            raise VideoError("video needs imageio and imageio-ffmpeg: pip install 'mbctl[video]'") from None
        try:
            self._exe = imageio_ffmpeg.get_ffmpeg_exe()
        except RuntimeError as exc:
            raise VideoError(f"no ffmpeg for the video: {exc}; pip install 'mbctl[video]'") from None
        if path.is_dir():
            raise VideoError(f"{path} is a directory; give a file name for the video")
        self.path, self.fps = path, fps
        self._proc: subprocess.Popen[bytes] | None = None  # started by the first frame (its size)
        self._log: IO[bytes] | None = None

    def _command(self, width: int, height: int) -> list[str]:
        keyframes, lookahead = (max(1, round(t * self.fps)) for t in (KEYFRAME_INTERVAL_S, LOOKAHEAD_S))
        return [self._exe, "-y", "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{width}x{height}",
                "-pix_fmt", "rgb24", "-r", str(Fraction(self.fps).limit_denominator()), "-i", "-", "-an",
                "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-v", "error", "-crf", "23",
                "-g", str(keyframes), "-x264-params", f"rc-lookahead={lookahead}",
                # fragmented, each fragment flushed: playable up to the last fragment if the process dies
                "-movflags", "frag_keyframe+empty_moov", "-flush_packets", "1", "-f", "mp4", "pipe:1"]

    def _start(self, width: int, height: int) -> subprocess.Popen[bytes]:
        try:
            fd = _create_new(self.path)
        except OSError as exc:
            raise VideoError(f"cannot create the video {str(self.path)!r}: {exc.strerror or exc}") from None
        self._log = tempfile.TemporaryFile()
        try:
            return subprocess.Popen(self._command(width, height), stdin=subprocess.PIPE, stdout=fd,
                                    stderr=self._log, start_new_session=True)
        except OSError as exc:
            raise VideoError(f"cannot start the video encoder for {str(self.path)!r}: {exc}; "
                             "pip install 'mbctl[video]'") from exc
        finally:
            os.close(fd)  # ffmpeg holds the file now

    def append_data(self, frame: np.ndarray) -> None:
        """Encode one frame (height, width, 3) uint8."""
        if self._proc is None:
            self._proc = self._start(frame.shape[1], frame.shape[0])
        stdin = self._proc.stdin
        try:
            if stdin is None:
                raise BrokenPipeError
            stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
            stdin.flush()  # the whole frame reaches ffmpeg now: none is lost if this process is killed
        except (BrokenPipeError, ValueError):
            raise VideoError(f"the video encoder stopped writing {str(self.path)!r}: "
                             f"{self._errors(self._proc.wait())}") from None

    def _errors(self, code: int) -> str:
        """The encoder's exit code and the end of what it printed."""
        text = b""
        if self._log is not None:
            self._log.seek(0)
            text = self._log.read()
        tail = text.decode(errors="replace").strip()[-500:]
        return f"ffmpeg exit {code}" + (f": {tail}" if tail else "")

    def close(self) -> None:
        """Finish the file (idempotent; a video without frames is never created)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            if proc.stdin is not None:
                with contextlib.suppress(BrokenPipeError):
                    proc.stdin.close()
            code = proc.wait()
            if code != 0:
                raise VideoError(f"the video encoder failed on {str(self.path)!r}: {self._errors(code)}")
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None


def _open_writer(path: Path, fps: float) -> _Writer:
    return _Writer(Path(path), fps)


class VideoRecorder:
    """Films a simulator into an MP4: a frame every ``1 / fps`` simulated seconds.

    Use as an observer (``sim.add_observer(recorder)``, done by :meth:`attach`) and ``close()``
    in every case (the job runner does).

    Args:
        sim: The plant to film.
        path: The MP4 file.
        spec: Frame size, rate and what to draw.
        overlay: Adds markers to each frame's scene (e.g. the reference path).
        frame_qpos: Plant configurations (k, nq) of the motion to come, which a fixed robot's
            camera frames (see :func:`default_camera`).
        frame_points_W: Points (m, 3) [m] in W the fixed camera frames too.
    """

    def __init__(self, sim: Simulator, path: Path, spec: VideoSpec = VideoSpec(),
                 overlay: Overlay | None = None, frame_qpos: np.ndarray | None = None,
                 frame_points_W: np.ndarray | None = None):
        self.sim, self.path, self.spec, self.overlay = sim, Path(path), spec, overlay
        self.renderer = make_renderer(sim.model, spec.width, spec.height)
        data = mujoco.MjData(sim.model)
        data.qpos[:] = sim.data.qpos
        # A fixed robot is framed on the motion to come (frame_qpos: plant qpos samples) and the
        # points drawn with it (a reference path), not only on where it starts.
        self.camera = default_camera(sim.model, data, base_body(sim.robot), frame_qpos, frame_points_W)
        self.options = mujoco.MjvOption()
        if spec.contact_forces:
            self.options.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = True
        self._writer = _open_writer(self.path, spec.fps)
        self.frames = 0
        self._next_t = float(sim.data.time) + 1.0 / spec.fps

    def attach(self) -> VideoRecorder:
        """Start filming: register as the simulator's observer."""
        self.sim.add_observer(self)
        return self

    def __call__(self, sim: Simulator) -> None:
        """Observer hook: render the frames that simulated time has reached."""
        if sim.data.time + 1e-9 < self._next_t:
            return
        frame = self.render()
        while sim.data.time + 1e-9 >= self._next_t:  # a long sync() may span several frames
            self._writer.append_data(frame)
            self.frames += 1
            self._next_t += 1.0 / self.spec.fps

    def render(self) -> np.ndarray:
        """The current frame (height, width, 3) uint8."""
        self.renderer.update_scene(self.sim.data, self.camera, self.options)
        if self.overlay is not None:
            self.overlay(self.renderer.scene)
        return self.renderer.render()

    def close(self) -> None:
        """Stop filming and finish the file (idempotent)."""
        self.sim.remove_observer(self)
        self._writer.close()
        self.renderer.close()


def film_trajectory(model: mujoco.MjModel, t_s: np.ndarray, qpos: np.ndarray, path: Path,
                    spec: VideoSpec = VideoSpec(), track_body: int | None = None) -> int:
    """Render a recorded trajectory (``qpos`` (n, nq) at times ``t_s`` (n,)) into an MP4.

    Frame k shows the last sample at or before ``t_s[0] + k / fps``. Returns the frame count.
    """
    renderer = make_renderer(model, spec.width, spec.height)
    data = mujoco.MjData(model)
    if len(qpos):
        data.qpos[:] = qpos[0]
    camera = default_camera(model, data, track_body, qpos[:: max(1, len(qpos) // 100)])
    writer = _open_writer(Path(path), spec.fps)
    frames = 0
    try:
        n = int(np.floor((t_s[-1] - t_s[0]) * spec.fps + 1e-9)) + 1 if len(t_s) else 0
        for k in range(n):
            i = int(np.searchsorted(t_s, t_s[0] + k / spec.fps + 1e-9, side="right")) - 1
            data.qpos[:] = qpos[max(i, 0)]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera)
            writer.append_data(renderer.render())
            frames += 1
    finally:
        writer.close()
        renderer.close()
    return frames


def still(model: mujoco.MjModel, data: mujoco.MjData, spec: VideoSpec, track_body: int | None) -> np.ndarray:
    """One frame (height, width, 3) uint8 of ``data``'s current state."""
    renderer = make_renderer(model, spec.width, spec.height)
    try:
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, default_camera(model, data, track_body))
        return renderer.render()
    finally:
        renderer.close()
