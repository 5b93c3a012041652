"""Size guards: inputs that would exhaust memory or run for hours are refused up front, naming the limit."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from mbctl import limits
from mbctl.jobs import options
from mbctl.jobs.catalog import parse_grid
from mbctl.jobs.demo import DemoConfig
from mbctl.jobs.joint_step import JointStepParams
from mbctl.jobs.workspace import WorkspaceParams
from mbctl.jobs.xcheck import XcheckParams
from mbctl.limits import SizeLimitError
from mbctl.robots import load_robot
from mbctl.robots.model_size import count_bodies
from tests.conftest import require


def _flat(n: int, joints: bool = True) -> str:
    joint = '<joint axis="0 0 1"/>' if joints else ""
    bodies = "".join(f'<body pos="{0.01 * i} 0 0">{joint}<geom size="0.01" mass="0.1"/></body>'
                     for i in range(n))
    return f'<mujoco model="flat"><worldbody>{bodies}</worldbody></mujoco>'


def test_a_model_over_the_body_limit_is_refused_before_mujoco_parses_it(tmp_path, monkeypatch):
    robot = tmp_path / "robot.xml"
    robot.write_text(_flat(limits.MAX_BODIES + 1, joints=False))
    scene = tmp_path / "scene.xml"
    scene.write_text('<mujoco><include file="robot.xml"/><worldbody><body><geom size="1"/></body>'
                     '</worldbody></mujoco>')
    assert count_bodies(scene) == limits.MAX_BODIES + 2  # the include is followed
    import mujoco

    def never(*args, **kwargs):
        raise AssertionError("MuJoCo parsed the file")

    monkeypatch.setattr(mujoco.MjSpec, "from_file", never)
    with pytest.raises(SizeLimitError, match=f"scene.xml with 2,002 bodies exceeds mbctl's limit of "
                                             f"{limits.MAX_BODIES:,} bodies"):
        load_robot(robot, scene=scene)


def _chain(n: int) -> str:
    """n hinged links in one tree (Pinocchio's parser reads only the first tree)."""
    links = "".join(f'<body name="b{i}" pos="0.01 0 0"><joint name="j{i}" axis="0 0 1"/>'
                    '<geom size="0.01" mass="0.1"/>' for i in range(n))
    return f'<mujoco model="chain"><worldbody>{links}{"</body>" * n}</worldbody></mujoco>'


@pytest.mark.parametrize("analytic", ["mujoco", "parser"])
def test_a_robot_over_the_dof_limit_is_refused_before_pinocchio_data(tmp_path, analytic):
    path = tmp_path / "many.xml"
    path.write_text(_chain(limits.MAX_ROBOT_DOF + 1))
    with pytest.raises(SizeLimitError, match="robot '.*' with 151 degrees of freedom exceeds mbctl's limit "
                                             "of 150"):
        load_robot(path, analytic=analytic)
    path.write_text(_chain(20))
    assert load_robot(path, analytic=analytic).nv == 20


@pytest.mark.parametrize(("make", "message"), [
    (lambda: DemoConfig(duration_s=1e12), "--duration 1e+12 s exceeds mbctl's limit of 600 s"),
    # the plant jobs: an hour
    (lambda: options.g1_stand(duration=3601.0), "--duration 3,601 s exceeds mbctl's limit of 3,600 s"),
    (lambda: options.g1_wbc(duration=1e12), "--duration 1e+12 s exceeds"),
    (lambda: XcheckParams("two_link", states=100_000_000), "--states 100,000,000 exceeds mbctl's limit of "
                                                             "100,000"),
    (lambda: JointStepParams("two_link", "elbow", 0.1, steps=10**9), "--steps 1,000,000,000 exceeds"),
    (lambda: WorkspaceParams(samples=100_000), "--samples 100,000 exceeds mbctl's limit of 1,001"),
])
def test_job_inputs_over_a_limit_are_refused(make, message):
    with pytest.raises(SizeLimitError, match=message.replace("+", r"\+")):
        make()


def test_limits_themselves_pass():
    DemoConfig(duration_s=limits.MAX_DURATION_S)
    XcheckParams("two_link", states=limits.MAX_XCHECK_STATES)
    JointStepParams("two_link", "elbow", 0.1, steps=limits.MAX_STEPS)


def test_a_sweep_grid_over_the_task_limit_needs_force(tmp_path):
    require("dask.distributed")
    from mbctl.jobs.sweep import SweepConfig, prepare_sweep, run_sweep

    grid = parse_grid("demo", ["model_error=" + ",".join(str(i) for i in range(1000)),
                               "omega=" + ",".join(str(10 + i) for i in range(1000))])
    message = ("the grid 1,000,000 tasks exceeds mbctl's limit of 10,000 tasks; 1000 model_error x 1000 "
               "omega; split the grid, or give --force")
    with pytest.raises(SizeLimitError, match=message):
        run_sweep(SweepConfig("demo", grid, tmp_path / "s"), client=object())
    assert not (tmp_path / "s").exists()
    small = parse_grid("demo", ["model_error=" + ",".join(str(i) for i in range(101)),
                                "omega=" + ",".join(str(10 + i) for i in range(100))])
    _, combos = prepare_sweep(SweepConfig("demo", small, tmp_path / "s", force=True))
    assert len(combos) == 10_100


def test_the_cli_exits_2_naming_the_limit():
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "demo", "--duration", "1e12"],
                         capture_output=True, text=True, timeout=120, env=os.environ)
    assert out.returncode == 2 and "--duration 1e+12 s exceeds mbctl's limit of 600 s" in out.stderr
    assert "Traceback" not in out.stderr
