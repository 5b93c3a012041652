"""MUJOCO_GL: a bad value breaks only the commands that render, and they name what was tried."""

from __future__ import annotations

import pytest

from mbctl import gl
from mbctl.gl import INSTALL_HINT, VideoError
from tests.conftest import run_mbctl


@pytest.mark.parametrize("value", ["bogus", "osmesa"])
def test_a_bad_mujoco_gl_breaks_no_command_that_does_not_render(value):
    out = run_mbctl("inspect", "two_link", timeout=120, env={"MUJOCO_GL": value}, unset=["PYOPENGL_PLATFORM"])
    assert out.returncode == 0, out.stderr
    assert "shoulder" in out.stdout and out.stderr == ""


def test_a_command_that_renders_exits_2_naming_the_value(tmp_path):
    out = run_mbctl("render", "two_link", "--output", str(tmp_path / "a.png"), timeout=120,
                    env={"MUJOCO_GL": "bogus"}, unset=["PYOPENGL_PLATFORM"])
    assert out.returncode == 2, out.stderr
    assert out.stderr.startswith("error: MUJOCO_GL=bogus cannot render here (bogus: RuntimeError: invalid "
                                 "value for environment variable MUJOCO_GL: bogus)")
    assert "Traceback" not in out.stderr and not (tmp_path / "a.png").exists()


def test_when_nothing_renders_every_value_tried_is_named(monkeypatch):
    monkeypatch.setattr(gl, "_probe", lambda backend: f"no {backend} here")
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    with pytest.raises(VideoError) as err:
        gl.choose_gl_backend()
    assert str(err.value) == ("MUJOCO_GL=osmesa cannot render here and no headless OpenGL backend works "
                              f"(tried osmesa: no osmesa here; egl: no egl here); {INSTALL_HINT}")
    monkeypatch.delenv("MUJOCO_GL")
    with pytest.raises(VideoError, match="no headless OpenGL backend works \\(tried egl: no egl here; "
                                         "osmesa: no osmesa here\\); install an EGL driver"):
        gl.choose_gl_backend()


def test_a_backend_without_its_library_says_what_to_install(monkeypatch):
    import ctypes.util

    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    assert gl._probe("osmesa") == "libOSMesa is not installed (apt install libosmesa6)"
    assert gl._probe("egl") == "libEGL is not installed (apt install libegl1)"
    assert gl._probe("off") == "MUJOCO_GL=off switches MuJoCo's OpenGL off"
