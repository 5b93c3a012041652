"""The ``mbctl workspace`` job: the 2-link annulus, the sampled plot, other robots refused."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from mbctl.control import IKSetupError
from mbctl.control.ik import TwoLinkArm
from mbctl.jobs.runner import run_job
from mbctl.jobs.workspace import SUPPORTED_ROBOTS, WORKSPACE, WorkspaceParams, sample_workspace


def _mbctl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mbctl.cli", *args], capture_output=True, text=True,
                          timeout=300, env=dict(os.environ))


def test_samples_stay_in_the_annulus(two_link):
    arm = TwoLinkArm.from_robot(two_link)
    r = np.hypot(*(sample_workspace(arm, two_link, n=41) - arm.base).T)
    assert r.min() >= arm.r_min - 1e-12 and r.max() <= arm.r_max + 1e-12
    assert r.max() > arm.r_max - 1e-3  # the grid reaches the outer circle
    with pytest.raises(IKSetupError, match="n must be >= 2"):
        sample_workspace(arm, n=1)


def test_job_writes_png_and_annulus(tmp_path):
    record = run_job(WORKSPACE, WorkspaceParams("two_link", samples=41), tmp_path)
    assert record.exit_code == 0
    assert (tmp_path / "workspace.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    values = json.loads((tmp_path / "report.json").read_text())["values"]
    assert values["r_min_m"] == pytest.approx(0.015) and values["r_max_m"] == pytest.approx(0.615)


@pytest.mark.parametrize("robot", ["g1", "two_link.xml", "/tmp/arm.xml"])
def test_other_robots_refused_naming_the_supported(robot):
    with pytest.raises(IKSetupError, match="supports only the planar 2-link arm") as exc:
        WorkspaceParams(robot)
    assert all(name in str(exc.value) for name in SUPPORTED_ROBOTS)


def test_cli_annulus_plot_and_refusal(tmp_path):
    out = _mbctl("workspace", "two_link", "--output", str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert "r_min = 0.0150 m, r_max = 0.6150 m" in out.stdout
    assert (tmp_path / "workspace.png").stat().st_size > 10_000
    out = _mbctl("workspace", "g1", "--output", str(tmp_path / "g1"))
    assert out.returncode == 2
    assert "two_link, two_link_torque" in out.stderr and "Traceback" not in out.stderr
    help_text = " ".join(_mbctl("workspace", "--help").stdout.replace("│", " ").split())
    assert "other robots are refused" in help_text and "two_link_torque" in help_text


def test_plot_is_a_density_with_the_inner_circle_in_an_inset(two_link):
    """No dots (a regular joint grid drawn dot by dot makes moire), r_min visible in a zoom."""
    from matplotlib.collections import PathCollection, PolyCollection

    from mbctl.jobs.workspace import plot_workspace

    arm = TwoLinkArm.from_robot(two_link)
    fig = plot_workspace(arm, sample_workspace(arm, two_link, n=41))
    ax = fig.axes[0]
    assert any(isinstance(c, PolyCollection) for c in ax.collections)  # hexagonal bins
    assert not any(isinstance(c, PathCollection) for c in ax.collections)  # no scatter
    (inset,) = ax.child_axes
    assert inset.get_xlim() == pytest.approx((-45.0, 45.0))  # 3 r_min either side, in mm
    (disc,) = inset.patches  # the unreachable disc, r_min = 15 mm
    assert np.ptp(disc.get_path().vertices[:, 0]) == pytest.approx(30.0, rel=1e-3)
    assert "r_min = 15 mm" in [t.get_text() for t in ax.get_legend().get_texts()]
