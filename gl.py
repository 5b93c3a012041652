"""Pick MuJoCo's headless OpenGL backend before MuJoCo is imported (no mujoco import here).

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported, and a failed backend cannot be
unloaded from a process; so each candidate is probed in a subprocess, EGL first, then OSMesa.
"""

from __future__ import annotations

import os
import subprocess
import sys

from mbctl.exceptions import ToolkitError

#: Headless OpenGL backends, in the order they are tried.
GL_BACKENDS = ("egl", "osmesa")

INSTALL_HINT = (
    "install an EGL driver (e.g. apt install libegl1; NVIDIA drivers ship one) or OSMesa "
    "(apt install libosmesa6), or run where a display exists with MUJOCO_GL=glfw"
)


class VideoError(ToolkitError):
    """Video cannot be made here: no OpenGL backend, no encoder, or a bad size."""


def choose_gl_backend() -> str:
    """Set ``MUJOCO_GL`` to the first headless backend that works, unless it is set already.

    Call before ``mujoco`` is imported in this process; each probe costs about 0.3 s.

    Raises:
        VideoError: Neither EGL nor OSMesa works; the message says what to install.
    """
    if os.environ.get("MUJOCO_GL"):
        return os.environ["MUJOCO_GL"]
    probe = "import mujoco; c = mujoco.GLContext(16, 16); c.make_current(); c.free()"
    errors = []
    for backend in GL_BACKENDS:
        env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
        out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                             timeout=60)
        if out.returncode == 0:
            os.environ["MUJOCO_GL"] = backend
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
            return backend
        errors.append(f"{backend}: {(out.stderr.strip().splitlines() or ['failed'])[-1]}")
    raise VideoError(f"no headless OpenGL backend works ({'; '.join(errors)}); {INSTALL_HINT}")
