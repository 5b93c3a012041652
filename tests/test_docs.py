"""The API reference builds from the docstrings with warnings as errors (Sphinx -W -n).

A public name without a docstring, a cross-reference that resolves nowhere, or a numbered example
whose docstring is not valid reStructuredText fails this test, so it fails CI. The second test
shows the build catching both on a module made for the purpose, and passing once it is fixed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import mbctl
from tests.conftest import require

require("sphinx")
DOCS = Path(mbctl.__file__).resolve().parent / "docs" / "api"
EXAMPLES = Path(mbctl.__file__).resolve().parent / "examples"


def _build(source: Path, out: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-W", "-n", "-q", "-E",
                           str(source), str(out)], capture_output=True, text=True, timeout=300, env=env)


def test_api_reference_builds_without_a_warning(tmp_path):
    out = _build(DOCS, tmp_path / "html")
    assert out.returncode == 0, out.stderr
    html = {p.name: p.read_text() for p in (tmp_path / "html").glob("*.html")}
    # every numbered example is rendered, its docstring as text and its code
    for script in sorted(EXAMPLES.glob("[0-9][0-9]_*.py")):
        assert script.name in html["examples.html"]
    assert "FramePoseTask" in html["examples.html"] and "plan_ruckig" in html["examples.html"]
    # the public API is there, with its docstrings
    assert 'id="mbctl.control.ComputedTorque"' in html["control.html"]
    assert 'id="mbctl.robots.load_robot"' in html["robots.html"]
    assert 'id="mbctl.planners.plan_ruckig"' in html["planners.html"]
    assert 'id="mbctl.sim.Simulator"' in html["sim.html"]
    # every public package has its reference: the Unitree floor, the hardware plant, identification,
    # the tasks, IK, whole-body control and estimation
    assert 'id="mbctl.unitree.MotorTable"' in html["unitree.html"]
    assert 'id="mbctl.hardware.UnitreeHG"' in html["hardware.html"]
    assert 'id="mbctl.robots.identification.identify"' in html["robots.html"]
    for name in ("tasks.FramePoseTask", "ik.DiffIK", "wbc.WholeBodyController",
                 "estimation.LegKinematicsEstimator"):
        assert f'id="mbctl.control.{name}"' in html["control.html"], name
    # the guides (the README's reference, moved here) are pages of the site
    for guide in ("commands", "robots_guide", "ik", "whole_body", "dds", "identification", "measured",
                  "layout"):
        assert f"{guide}.html" in html, guide
    assert "On the real G1" in html["dds.html"] and "MotionSwitcherClient" in html["dds.html"]


FAKE = '''"""A module for the docs test."""


def documented():
    """Return nothing; see :class:`{ref}`."""


def helper():
{body}
'''


@pytest.mark.parametrize("fixed", [False, True])
def test_a_missing_docstring_or_a_broken_reference_fails_the_build(tmp_path, fixed):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "fake_api.py").write_text(FAKE.format(
        ref="fake_api.documented" if fixed else "fake_api.Nowhere",
        body='    """Help."""' if fixed else "    pass"))
    source = tmp_path / "src"
    source.mkdir()
    (source / "conf.py").write_text(  # our configuration and hooks, without the examples page
        f"import runpy\nglobals().update(runpy.run_path({str(DOCS / 'conf.py')!r}))\n"
        "mbctl_examples = False\n")
    (source / "index.rst").write_text("Fake\n====\n\n.. automodule:: fake_api\n")
    env = dict(os.environ, PYTHONPATH=str(package))
    out = _build(source, tmp_path / "html", env=env)
    if fixed:
        assert out.returncode == 0, out.stderr
    else:
        assert out.returncode != 0
        assert "public function fake_api.helper has no docstring" in out.stderr
        assert "fake_api.Nowhere" in out.stderr
