"""The Python the README and the guides print runs as pasted, and does what their text says.

The README's first block is the controller a new user writes; the G1 and cross-check snippets are
on the robots guide (docs/api/robots_guide.rst), the arm's IK snippet on the IK guide
(docs/api/ik.rst). Every block imports only the public API.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from tests.test_readme import DOCS, README, ROOT, md_blocks, rst_blocks

#: Largest final joint error [rad] the 2-link snippet may print after its 2 s hold.
MAX_FINAL_ERROR_RAD = 1e-3
PUBLIC = {"mbctl.robots", "mbctl.robots.crosscheck", "mbctl.sim", "mbctl.control", "mbctl.control.ik",
          "mbctl.control.tasks", "mbctl.control.wbc", "mbctl.planners"}


def _readme_blocks() -> list[str]:
    return md_blocks(README.read_text(), "python")


def _robots_blocks() -> list[str]:
    return rst_blocks(DOCS / "robots_guide.rst", "python")


def _ik_blocks() -> list[str]:
    return rst_blocks(DOCS / "ik.rst", "python")


def test_the_snippets_are_where_the_text_says():
    assert 'load_robot("two_link_torque"' in _readme_blocks()[0]
    robots = _robots_blocks()
    assert len(robots) == 2
    assert 'load_robot("g1")' in robots[0] and "crosscheck(" in robots[1]
    assert "FramePoseTask" in _ik_blocks()[0]


def test_two_link_controller_snippet_holds_the_pose(capsys):
    namespace: dict[str, object] = {}
    exec(_readme_blocks()[0], namespace)  # noqa: S102 (our own README)
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
    exec(_robots_blocks()[0], namespace)  # noqa: S102 (our own guide)
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


def test_crosscheck_snippet_passes_on_the_shipped_arm(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)  # the snippet names the example's arm by its path in the repo
    namespace: dict[str, object] = {}
    exec(_robots_blocks()[1], namespace)  # noqa: S102 (our own guide)
    assert namespace["report"].passed  # type: ignore[attr-defined]
    assert "result: PASS" in capsys.readouterr().out


def _all_blocks() -> list[tuple[str, str]]:
    blocks = [("README.md", b) for b in _readme_blocks()]
    pages = sorted(DOCS.glob("*.rst"))
    return blocks + [(page.name, b) for page in pages for b in rst_blocks(page, "python")]


def _block_id(value: str) -> str:
    return value if value.endswith((".md", ".rst")) else "code"


@pytest.mark.parametrize("where, block", _all_blocks(), ids=_block_id)
def test_snippets_import_only_the_public_api(where, block):
    imports = re.findall(r"^from (mbctl[\w.]*) import", block, flags=re.M)
    assert imports, f"a {where} snippet imports nothing from mbctl"
    assert set(imports) <= PUBLIC, f"{where}: {sorted(set(imports) - PUBLIC)}"


def test_arm_snippet_reaches_its_pose_targets(monkeypatch, capsys):
    """IK on the tool pose (checked in MuJoCo), the generic config's position target, ruckig to the
    solution, and computed torque bringing the plant's tool there."""
    import mujoco
    import pinocchio as pin

    monkeypatch.chdir(ROOT)  # the snippet names the example's arm by its path in the repo
    ns: dict[str, object] = {}
    exec(_ik_blocks()[0], ns)  # noqa: S102 (our own guide)
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
