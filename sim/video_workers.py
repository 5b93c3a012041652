"""Video frames rendered in worker processes while the simulation runs, and the MP4 encoder.

``mbctl.sim.video_pool.RenderPool`` starts ``workers`` processes, each with its own OpenGL context
and one ``mujoco.Renderer`` kept for the whole video. The parent sends each frame's state (qpos,
mocap poses and the extra geoms of the frame: contact-force arrows, overlay markers), a few
hundred bytes, and goes on simulating; frame k goes to worker ``k % workers``. Worker 0, the lead,
owns the encoder (ffmpeg): it renders its own frames, takes the others' from their workers, in
frame order, and writes them. Every pipe is a bounded kernel buffer, so a parent that films faster
than the workers render waits (memory stays bounded) and a frame sent is never lost: if the parent
dies (SIGKILL), the workers read what is left in their pipes, the lead writes it and closes the
MP4. Workers run in their own session: a Ctrl-C at the terminal reaches the parent only, which
finishes the video through ``RenderPool.close``.

Software OpenGL (Mesa llvmpipe, OSMesa) draws a G1 frame in ~45 ms without multisampling and
shadows against ~310 ms with them, and most of the 45 ms is the G1's 393k mesh triangles, many
smaller than a pixel; so on software GL a worker switches both off (and the horizon's haze) and
merges the meshes' vertices closer than a pixel at the camera's distance (:func:`simplify_meshes`:
102k triangles at 640x480, ~20 ms a frame with the haze off; bench/README.md, video section). On a
GPU all stay.
"""

from __future__ import annotations

import contextlib
import functools
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from fractions import Fraction
from multiprocessing.connection import Connection
from pathlib import Path
from typing import IO, NamedTuple

import mujoco
import numpy as np

from mbctl.gl import INSTALL_HINT, VideoError

#: Keyframe interval and x264 lookahead [s of video]. The fragmented MP4 is written a fragment per
#: keyframe, once the encoder has emitted the next keyframe, so the file on disk lags the frames
#: sent by about one interval plus the lookahead. x264's defaults (a keyframe every 250 frames, 40
#: frames of lookahead) kept a 3 s clip unplayable until it was closed; with 0.5 s and 0.33 s the
#: file plays to within 0.6 s of the last frame sent (tests/sim/test_video.py), for 15 % more bytes.
KEYFRAME_INTERVAL_S, LOOKAHEAD_S = 0.5, 1.0 / 3.0

#: Niceness a render worker adds to its own: the job's simulation or control loop keeps its core
#: while the workers render with what is left.
WORKER_NICE = 10

#: Mode of the MP4 (``mbctl.sim.atomic.FILE_MODE``; not imported: the workers load this module
#: without the ``mbctl.sim`` package, whose imports cost them a second).
FILE_MODE = 0o644

#: GL_RENDERER names of software rasterisers (Mesa's llvmpipe, softpipe, swrast; OpenSWR).
SOFTWARE_GL = ("llvmpipe", "softpipe", "swrast", "swr", "software")


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
        # little information.
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        return renderer
    except Exception as exc:  # GL errors come as several types (RuntimeError, AttributeError, ...)
        raise VideoError(
            f"MuJoCo's renderer cannot start with MUJOCO_GL={os.environ.get('MUJOCO_GL', '(unset)')}: "
            f"{type(exc).__name__}: {exc}; {INSTALL_HINT}"
        ) from exc


@functools.cache
def gl_renderer_name() -> str:
    """The OpenGL renderer's name (GL_RENDERER), '' when it cannot be read (probed once a process)."""
    try:
        ctx = mujoco.GLContext(16, 16)
        ctx.make_current()
        try:
            from OpenGL import GL

            return bytes(GL.glGetString(GL.GL_RENDERER) or b"").decode(errors="replace")
        finally:
            ctx.free()
    except Exception:  # noqa: BLE001 - any failure reads as unknown (treated as software)
        return ""


def is_software_gl(name: str) -> bool:
    """True for a software rasteriser's GL_RENDERER name, or an unknown one ('')."""
    return not name or any(s in name.lower() for s in SOFTWARE_GL)


def simplify_meshes(model: mujoco.MjModel, cell_m: float) -> tuple[int, int]:
    """Merge each mesh's vertices that share a ``cell_m`` [m] grid cell (vertex clustering), in place.

    Each vertex is replaced by the first of its cell; faces that collapse, and repeated faces,
    are dropped (each mesh keeps the first ``mesh_facenum`` faces of its range); corners keep
    their vertex's normal and texture coordinate. For drawing only: the collision data (convex
    hulls) are left as they were. Returns the face count (before, after).
    """
    before = int(model.mesh_facenum.sum())
    for i in range(model.nmesh):
        va, vn = int(model.mesh_vertadr[i]), int(model.mesh_vertnum[i])
        fa, fn = int(model.mesh_faceadr[i]), int(model.mesh_facenum[i])
        faces = model.mesh_face[fa:fa + fn]
        cells = np.floor(model.mesh_vert[va:va + vn] / cell_m).astype(np.int64)
        _, first, inverse = np.unique(cells, axis=0, return_index=True, return_inverse=True)
        merged = first[inverse.ravel()][faces]  # each corner: the first vertex of its cell
        a, b, c = merged.T
        merged = merged[(a != b) & (b != c) & (a != c)]
        _, once = np.unique(np.sort(merged, axis=1), axis=0, return_index=True)
        merged = merged[np.sort(once)]
        textured = model.mesh_texcoordnum[i] > 0
        for per_corner, used in ((model.mesh_facenormal, True), (model.mesh_facetexcoord, textured)):
            if used:
                of_vertex = np.zeros(vn, dtype=np.int64)
                of_vertex[faces.ravel()] = per_corner[fa:fa + fn].ravel()
                per_corner[fa:fa + len(merged)] = of_vertex[merged]
        model.mesh_face[fa:fa + len(merged)] = merged
        model.mesh_facenum[i] = len(merged)
    return before, int(model.mesh_facenum.sum())


def fast_renderer(model: mujoco.MjModel, width: int, height: int, software: bool) -> mujoco.Renderer:
    """A video renderer: on software GL without multisampling, shadows and haze (see the module doc)."""
    if software:
        model.vis.quality.offsamples = 0
    renderer = make_renderer(model, width, height)
    if software:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        # the horizon's haze: ~8 of a G1 frame's ~34 ms, for a softer line where floor meets sky
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_HAZE] = False
    return renderer


class ExtraGeoms(NamedTuple):
    """Geoms drawn on top of the model in one frame (arrows, markers), as ``mjv_initGeom`` takes them.

    Attributes:
        type: mjtGeom per geom (k,).
        size: Sizes (k, 3) [m].
        pos: Positions (k, 3) [m] in W.
        mat: Orientations (k, 9), row-major, in W.
        rgba: Colours (k, 4) in [0, 1].
    """

    type: np.ndarray
    size: np.ndarray
    pos: np.ndarray
    mat: np.ndarray
    rgba: np.ndarray

    @staticmethod
    def of(scene: mujoco.MjvScene, start: int = 0) -> ExtraGeoms:
        """The geoms ``scene`` holds from index ``start`` on."""
        geoms = [scene.geoms[i] for i in range(start, scene.ngeom)]
        return ExtraGeoms(np.array([g.type for g in geoms], dtype=int),
                          np.array([g.size for g in geoms]).reshape(-1, 3),
                          np.array([g.pos for g in geoms]).reshape(-1, 3),
                          np.array([g.mat.ravel() for g in geoms]).reshape(-1, 9),
                          np.array([g.rgba for g in geoms]).reshape(-1, 4))

    def add_to(self, scene: mujoco.MjvScene) -> None:
        """Append the geoms to ``scene`` (as many as it has room for)."""
        for i in range(len(self.type)):
            if scene.ngeom >= scene.maxgeom:
                return
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], int(self.type[i]), self.size[i], self.pos[i],
                                self.mat[i], self.rgba[i].astype(np.float32))
            scene.ngeom += 1


class FrameState(NamedTuple):
    """What a worker needs to draw one frame: the plant's pose and the frame's extra geoms.

    Attributes:
        qpos: Plant configuration (nq,).
        mocap_pos: Mocap body positions (nmocap, 3) [m] in W.
        mocap_quat: Mocap body orientations (nmocap, 4), wxyz.
        extra: Geoms drawn on top (contact forces, markers), or None.
    """

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    extra: ExtraGeoms | None = None


@dataclass(frozen=True)
class CameraSpec:
    """A picklable ``mujoco.MjvCamera`` (the fields the videos set)."""

    type: int
    trackbodyid: int
    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float

    @staticmethod
    def of(cam: mujoco.MjvCamera) -> CameraSpec:
        """The fields of ``cam``."""
        x, y, z = (float(v) for v in cam.lookat)
        return CameraSpec(int(cam.type), int(cam.trackbodyid), (x, y, z),
                          float(cam.distance), float(cam.azimuth), float(cam.elevation))

    def camera(self) -> mujoco.MjvCamera:
        """A new ``mujoco.MjvCamera`` with these fields."""
        cam = mujoco.MjvCamera()
        cam.type, cam.trackbodyid = self.type, self.trackbodyid
        cam.lookat[:] = self.lookat
        cam.distance, cam.azimuth, cam.elevation = self.distance, self.azimuth, self.elevation
        return cam


def _create_new(path: Path) -> int:
    """A write descriptor on a new file at ``path`` (mode 0644).

    Whatever was there (a file, a symbolic link) is removed first, never followed or written
    through (``O_EXCL | O_NOFOLLOW``).
    """
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, FILE_MODE)


class Writer:
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
                # veryfast: half medium's CPU (6 against 12.5 ms a G1 frame), no larger a file here
                "-vcodec", "libx264", "-preset", "veryfast", "-pix_fmt", "yuv420p", "-v", "error",
                "-crf", "23", "-g", str(keyframes), "-x264-params", f"rc-lookahead={lookahead}",
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


def default_workers() -> int:
    """Render workers for this machine: one a core (1 to 4), also while a simulation runs.

    Workers run at a lower priority (:data:`WORKER_NICE`), so while a simulation runs they take
    the cores it leaves, and when it ends the frames still to render spread over every core (one
    worker fewer than the cores left a core idle then: bench/README.md, video section).
    """
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores, 4))


def _render(renderer: mujoco.Renderer, model: mujoco.MjModel, data: mujoco.MjData,
            camera: mujoco.MjvCamera, options: mujoco.MjvOption, sent: tuple) -> np.ndarray:
    """One frame (height, width, 3) uint8 of a frame state sent as a plain tuple."""
    qpos, mocap_pos, mocap_quat, extra = sent
    state = FrameState(qpos, mocap_pos, mocap_quat, ExtraGeoms(*extra) if extra is not None else None)
    data.qpos[:] = state.qpos
    if model.nmocap:
        data.mocap_pos[:], data.mocap_quat[:] = state.mocap_pos, state.mocap_quat
    mujoco.mj_fwdPosition(model, data)  # poses, the tracked body's CoM, camera and lights
    renderer.update_scene(data, camera, options)
    if state.extra is not None:
        state.extra.add_to(renderer.scene)
    return renderer.render()


def _worker_main() -> None:
    """A render worker (see the module doc): argv holds its pipes' descriptors."""
    jobs_fd, status_fd, out_fd, *follower_fds = (int(a) for a in sys.argv[1:])
    with contextlib.suppress(OSError):
        os.nice(WORKER_NICE)  # below the simulation and a control loop (ffmpeg, its child, inherits it)
    jobs, status = Connection(jobs_fd, writable=False), Connection(status_fd, readable=False)
    out = Connection(out_fd, readable=False) if out_fd >= 0 else None
    followers = [Connection(fd, writable=False) for fd in follower_fds]
    writer: Writer | None = None
    sent = 0
    try:
        setup = jobs.recv()
        model = mujoco.MjModel.from_binary_path(setup["model"])
        if setup["software"]:
            simplify_meshes(model, setup["pixel_m"])
        renderer = fast_renderer(model, setup["width"], setup["height"], setup["software"])
        camera, options = CameraSpec(*setup["camera"]).camera(), mujoco.MjvOption()
        data = mujoco.MjData(model)
        if out is None:
            writer = Writer(Path(setup["path"]), setup["fps"])
        status.send(("ready", ""))
        shape = (setup["height"], setup["width"], 3)
        while True:
            try:
                msg = jobs.recv()
            except EOFError:  # the parent died: what it sent is in, finish the video
                break
            if msg is None:
                break
            if out is not None:  # a follower: render, hand the frame to the lead
                try:
                    out.send_bytes(_render(renderer, model, data, camera, options, msg).tobytes())
                except (BrokenPipeError, OSError):
                    break  # the lead is gone
                continue
            owner, repeat, state = msg
            if owner == 0:
                frame = _render(renderer, model, data, camera, options, state)
            else:
                try:
                    frame = np.frombuffer(followers[owner - 1].recv_bytes(), dtype=np.uint8).reshape(shape)
                except EOFError:
                    raise VideoError(f"render worker {owner} stopped before its frame {sent}") from None
            assert writer is not None
            for _ in range(repeat):
                writer.append_data(frame)
            if not sent:
                status.send(("started", ""))  # the encoder holds the file: the parent may go on
            sent += 1
        if writer is not None:
            writer.close()
        status.send(("closed", str(sent)))
    except Exception as exc:  # noqa: BLE001 - every failure goes to the parent, as a VideoError
        with contextlib.suppress(Exception):
            text = str(exc) if isinstance(exc, VideoError) else f"{type(exc).__name__}: {exc}"
            status.send(("error", text))
        with contextlib.suppress(Exception):
            if writer is not None:
                writer.close()
