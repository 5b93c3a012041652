"""Pick MuJoCo's headless OpenGL backend before MuJoCo is imported (no mujoco import here).

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported, and a failed backend cannot be
unloaded from a process; so each candidate is probed in a subprocess: the user's ``MUJOCO_GL`` if
set, else EGL first, then OSMesa. Processes that do not render switch OpenGL off instead
(:func:`disable_gl`), so a bad ``MUJOCO_GL`` breaks only the commands that render.
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


#: MUJOCO_GL values that switch MuJoCo's OpenGL off (MuJoCo's own list).
GL_OFF = ("disable", "disabled", "off", "false", "0")

#: The library each headless backend loads, and the package that provides it.
_LIBRARIES = {"egl": ("EGL", "libegl1"), "osmesa": ("OSMesa", "libosmesa6")}

_PROBE = "import mujoco; c = mujoco.GLContext(16, 16); c.make_current(); c.free()"


def _probe(backend: str) -> str | None:
    """None if MuJoCo can make an OpenGL context with ``MUJOCO_GL=backend``, else why not."""
    import ctypes.util

    if backend.lower() in GL_OFF:
        return f"MUJOCO_GL={backend} switches MuJoCo's OpenGL off"
    library = _LIBRARIES.get(backend.lower())
    if library is not None and ctypes.util.find_library(library[0]) is None:
        return f"lib{library[0]} is not installed (apt install {library[1]})"
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                         timeout=60)
    return None if out.returncode == 0 else (out.stderr.strip().splitlines() or ["failed"])[-1]


def choose_gl_backend() -> str:
    """Set ``MUJOCO_GL`` to a backend that renders here: the user's value if it works, else EGL or OSMesa.

    Call before ``mujoco`` is imported in this process; each probe (in a subprocess, since a
    backend that fails to load cannot be unloaded) costs about 0.3 s.

    Raises:
        VideoError: The ``MUJOCO_GL`` the user set cannot render (the message names the headless
            backend that would), or neither EGL nor OSMesa works; the message names every value
            tried, why it failed, and what to install.
    """
    requested = os.environ.get("MUJOCO_GL", "").strip()
    errors = []
    for backend in [requested] if requested else GL_BACKENDS:
        error = _probe(backend)
        if error is None:
            os.environ["MUJOCO_GL"] = backend
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
            return backend
        errors.append(f"{backend}: {error}")
    if requested:
        for backend in (b for b in GL_BACKENDS if b != requested.lower()):
            error = _probe(backend)
            if error is None:
                raise VideoError(f"MUJOCO_GL={requested} cannot render here ({errors[0]}); "
                                 f"{backend} works: set MUJOCO_GL={backend}, or unset MUJOCO_GL and "
                                 "mbctl picks a headless backend")
            errors.append(f"{backend}: {error}")
        raise VideoError(f"MUJOCO_GL={requested} cannot render here and no headless OpenGL backend "
                         f"works (tried {'; '.join(errors)}); {INSTALL_HINT}")
    raise VideoError(f"no headless OpenGL backend works (tried {'; '.join(errors)}); {INSTALL_HINT}")


def disable_gl() -> None:
    """Switch MuJoCo's OpenGL off (``MUJOCO_GL=disable``) for a process that never renders offscreen.

    MuJoCo loads the backend ``MUJOCO_GL`` names when imported, and a bad value (``bogus``, or
    ``osmesa`` without OSMesa) makes the import itself fail. Commands that do not render need no
    backend; MuJoCo's interactive viewer opens its window through GLFW, without it. Call before
    ``mujoco`` is imported.
    """
    os.environ["MUJOCO_GL"] = "disable"
