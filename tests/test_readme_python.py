"""The README's "Python API" snippets run as printed, and do what their text says."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import mbctl

README = Path(mbctl.__file__).resolve().parent / "README.md"
#: Largest final joint error [rad] the 2-link snippet may print after its 2 s hold.
MAX_FINAL_ERROR_RAD = 1e-3


def _python_blocks() -> list[str]:
    section = README.read_text().split("## Python API", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_the_section_has_the_four_snippets():
    blocks = _python_blocks()
    assert len(blocks) == 4
    assert 'load_robot("two_link_torque"' in blocks[0]
    assert 'load_robot("g1")' in blocks[1]


def test_two_link_controller_snippet_holds_the_pose(capsys):
    namespace: dict[str, object] = {}
    exec(_python_blocks()[0], namespace)  # noqa: S102 (our own README)
    printed = capsys.readouterr().out
    match = re.search(r"final error \(rad\): \[([^\]]*)\]", printed)
    assert match, f"the snippet did not print its final error: {printed!r}"
    error_rad = np.array(match.group(1).split(), dtype=float)
    assert error_rad.shape == (2,)
    assert np.max(np.abs(error_rad)) < MAX_FINAL_ERROR_RAD, printed
    # the printed numbers are the log's, not a constant
    log = namespace["log"]
    np.testing.assert_allclose(error_rad, np.array([0.4, 0.8]) - log.q[-1], rtol=1e-5)  # type: ignore[attr-defined]

    # "the same law, shipped": the library controller holds the same pose
    from mbctl.control import joint_reference, run
    from mbctl.sim import Simulator

    robot = namespace["robot"]
    library_log = run(Simulator(robot), namespace["library"], joint_reference([0.4, 0.8]), duration_s=2.0)  # type: ignore[arg-type]
    assert np.max(np.abs(np.array([0.4, 0.8]) - library_log.q[-1])) < MAX_FINAL_ERROR_RAD


def test_g1_snippet_gives_the_documented_shapes(g1, capsys):
    namespace: dict[str, object] = {}
    exec(_python_blocks()[1], namespace)  # noqa: S102 (our own README)
    assert capsys.readouterr().out.strip(), "the snippet prints the sensor, base height, warnings"
    robot, sim = namespace["g1"], namespace["sim"]
    nv = g1.nv
    assert namespace["M"].shape == (nv, nv)  # type: ignore[attr-defined]
    assert namespace["g"].shape == (nv,)  # type: ignore[attr-defined]
    assert namespace["J"].shape == (6, nv)  # type: ignore[attr-defined]
    assert sim.warnings == {}  # type: ignore[attr-defined]
    # standing on the stand keyframe's targets: the pelvis stays up
    assert sim.base_z_m > 0.6  # type: ignore[attr-defined]
    # the pose is the simulator's (MuJoCo) body pose at that state
    p_mj, R_mj = sim.body_pose("left_ankle_roll_link")  # type: ignore[attr-defined]
    np.testing.assert_allclose(namespace["p"], p_mj, atol=1e-9)
    np.testing.assert_allclose(namespace["R"], R_mj, atol=1e-9)
    assert robot.name == "g1"  # type: ignore[attr-defined]


@pytest.mark.parametrize("index", [0, 1, 3])
def test_snippets_import_only_the_public_api(index):
    imports = re.findall(r"^from (mbctl[\w.]*) import", _python_blocks()[index], flags=re.M)
    assert imports and set(imports) <= {"mbctl.robots", "mbctl.sim", "mbctl.control", "mbctl.control.ik",
                                        "mbctl.control.tasks", "mbctl.planners"}


def test_arm_snippet_reaches_its_pose_targets(monkeypatch, capsys):
    """IK on the tool pose (checked in MuJoCo), the generic config's position target, ruckig to the
    solution, and computed torque bringing the plant's tool there."""
    import mujoco
    import pinocchio as pin

    monkeypatch.chdir(README.parent)  # the snippet names the example's arm by its path in the repo
    ns: dict[str, object] = {}
    exec(_python_blocks()[3], ns)  # noqa: S102 (our own README)
    assert capsys.readouterr().out.startswith("True ")
    arm, result, target = ns["arm"], ns["result"], ns["target"]
    data = mujoco.MjData(arm.mj_model)  # type: ignore[attr-defined]
    data.qpos[:] = arm.plant_qpos(result.q)  # type: ignore[attr-defined]
    mujoco.mj_kinematics(arm.mj_model, data)  # type: ignore[attr-defined]
    site = arm.site_id("tool")  # type: ignore[attr-defined]
    assert np.linalg.norm(data.site_xpos[site] - target.translation) < 1e-4  # type: ignore[attr-defined]
    rotation = data.site_xmat[site].reshape(3, 3).T @ target.rotation  # type: ignore[attr-defined]
    assert np.linalg.norm(pin.log3(rotation)) < 1e-3
    moved, p = ns["moved"], ns["p"]
    assert moved.converged  # type: ignore[attr-defined]
    np.testing.assert_allclose(arm.frame_pose("tool", moved.q)[0], p + [0.05, 0.1, 0.0], atol=1e-4)  # type: ignore
    trajectory, sim = ns["trajectory"], ns["sim"]
    np.testing.assert_allclose(trajectory.q[-1], result.q, atol=1e-9)  # type: ignore[attr-defined]
    assert np.linalg.norm(sim.site_pose("tool")[0] - target.translation) < 1e-3  # type: ignore
