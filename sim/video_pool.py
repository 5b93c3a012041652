"""The parent's side of the video's render workers: started, fed with frame states, closed.

:class:`RenderPool` starts the processes :mod:`mbctl.sim.video_workers` describes (its module doc
says who renders and who encodes, and why a frame sent is never lost), hands each its setup, and
sends each frame's state to its worker.
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import tempfile
from dataclasses import astuple
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import IO

import mujoco

from mbctl.gl import VideoError
from mbctl.sim import video_workers
from mbctl.sim.video_workers import CameraSpec, FrameState, gl_renderer_name, is_software_gl


def pixel_size_m(model: mujoco.MjModel, camera: CameraSpec, height: int) -> float:
    """The height [m] one pixel of a ``height``-pixel frame covers at the camera's look-at distance."""
    return 2.0 * camera.distance * math.tan(math.radians(float(model.vis.global_.fovy)) / 2.0) / height


#: A worker's ``python -c``: ``video_workers.py`` loaded by its path, so that the ``mbctl.sim`` package (the
#: simulator, Pinocchio) is not imported: a worker needs mujoco, numpy and ``mbctl.gl`` only.
_BOOTSTRAP = ("import importlib.util as u, sys; "
              "s = u.spec_from_file_location('_mbctl_video_worker', {path!r}); "
              "m = sys.modules[s.name] = u.module_from_spec(s); s.loader.exec_module(m); m._worker_main()")


class RenderPool:
    """Render workers filming one MP4 (see the module doc); the parent sends frame states.

    Args:
        model: The model drawn (copied to each worker).
        width: Frame width [px].
        height: Frame height [px].
        camera: The camera of every frame.
        path: The MP4 file.
        fps: Frames per second of video.
        workers: Number of render processes (>= 1).

    Raises:
        VideoError: A worker cannot render or encode here (the message says why).
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, camera: CameraSpec,
                 path: Path, fps: float, workers: int = 1):
        self.workers, self.frames, self._closed = max(1, int(workers)), 0, False
        self._jobs: list[Connection] = []
        self._status: list[Connection] = []
        self._procs: list[subprocess.Popen[bytes]] = []
        self._logs: list[IO[bytes]] = []
        frames = [Pipe(duplex=False) for _ in range(self.workers - 1)]  # (lead's end, follower's end)
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "0")  # llvmpipe rasterises in the worker's own thread
        try:
            for k in range(self.workers):
                job_r, job_w = Pipe(duplex=False)
                stat_r, stat_w = Pipe(duplex=False)
                out = frames[k - 1][1].fileno() if k else -1
                ins = [f[0].fileno() for f in frames] if k == 0 else []
                fds = [job_r.fileno(), stat_w.fileno(), *([out] if k else []), *ins]
                log = tempfile.TemporaryFile()
                code = _BOOTSTRAP.format(path=str(Path(video_workers.__file__).resolve()))
                argv = [sys.executable, "-c", code, str(job_r.fileno()), str(stat_w.fileno()), str(out),
                        *(str(i) for i in ins)]
                self._procs.append(subprocess.Popen(argv, pass_fds=fds, env=env, stdin=subprocess.DEVNULL,
                                                    stdout=log, stderr=log, start_new_session=True))
                self._logs.append(log)
                job_r.close()
                stat_w.close()
                self._jobs.append(job_w)
                self._status.append(stat_r)
            for lead_end, follower_end in frames:  # each end lives in its worker only now
                lead_end.close()
                follower_end.close()
            # while the workers start: the model as one MJB file they all read (the G1: 80 MB, read
            # in ~0.3 s against ~1.4 s unpickled), and the GL renderer's name, probed once here
            with tempfile.TemporaryDirectory(dir="/dev/shm" if os.path.isdir("/dev/shm") else None) as tmp:
                mjb = os.path.join(tmp, "model.mjb")
                mujoco.mj_saveModel(model, mjb, None)
                setup = {"model": mjb, "width": width, "height": height, "camera": astuple(camera),
                         "path": str(path), "fps": fps, "software": is_software_gl(gl_renderer_name()),
                         "pixel_m": pixel_size_m(model, camera, height)}
                for k in range(self.workers):
                    self._jobs[k].send(setup)
                for k in range(self.workers):
                    self._expect(k, "ready")
        except BaseException:
            self._kill()
            raise

    def _expect(self, k: int, what: str) -> str:
        """Wait for worker ``k``'s next status; VideoError unless it is ``what``."""
        try:
            kind, text = self._status[k].recv()
        except (EOFError, OSError):
            kind, text = "error", f"render worker {k} exited: {self._log_tail(k)}"
        if kind != what:
            raise VideoError(text if kind == "error" else f"render worker {k} said {kind!r}, not {what!r}")
        return text

    def _log_tail(self, k: int) -> str:
        proc, log = self._procs[k], self._logs[k]
        code = proc.wait(timeout=30)
        log.seek(0)
        tail = log.read().decode(errors="replace").strip()[-500:]
        return f"exit {code}" + (f": {tail}" if tail else "")

    def _check(self) -> None:
        """Raise a worker's error as soon as it is reported (no wait)."""
        for k, status in enumerate(self._status):
            if status.poll():
                self._expect(k, "running")  # any report mid-video is an error

    def submit(self, state: FrameState, repeat: int = 1) -> None:
        """Film ``state`` as the next ``repeat`` frames (the first waits until the encoder has started)."""
        if self._closed:
            raise VideoError("the video is closed")
        self._check()
        k = self.frames % self.workers
        # plain tuples: the workers unpickle them without importing mbctl.sim
        sent = (state.qpos, state.mocap_pos, state.mocap_quat,
                None if state.extra is None else tuple(state.extra))
        try:
            if k:
                self._jobs[k].send(sent)
            self._jobs[0].send((k, repeat, None if k else sent))
        except (BrokenPipeError, OSError):
            self._check()
            raise VideoError(f"render worker {k} stopped: {self._log_tail(k)}") from None
        if not self.frames:
            self._expect(0, "started")
        self.frames += 1

    def close(self) -> None:
        """Render what was sent, finish the MP4 and stop the workers (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            for job in self._jobs:
                with contextlib.suppress(OSError):
                    job.send(None)
                job.close()
            self._expect(0, "closed")
            for proc in self._procs:
                proc.wait(timeout=60)
        finally:
            self._kill()

    def _kill(self) -> None:
        for proc in self._procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for conn in (*self._jobs, *self._status):
            conn.close()
        for log in self._logs:
            log.close()

