"""The cross-check's report, arguments, progress and CLI; its batched evaluation against Pinocchio.

Which robots agree is in test_crosscheck_robots.py; the modelling errors it catches, in
test_crosscheck_errors.py. Test models are in tests/robots/assets/.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import TOLERANCES, CrossCheckError, Tolerance, crosscheck
from mbctl.robots.crosscheck.sampling import sample_states
from mbctl.robots.registry import ASSETS

ALL_QUANTITIES = ("structure", *TOLERANCES)


# ---------------------------------------------------------------- report and errors


def test_report_json_and_text(two_link_torque):
    report = crosscheck(two_link_torque, n_states=5, seed=7)
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))
    assert data["passed"] is True and data["verdict"] == "PASS"
    assert [q["name"] for q in data["quantities"]] == list(ALL_QUANTITIES)
    assert data["quantities"][1]["tolerance"] == 1e-9
    text = report.to_text()
    assert text.splitlines()[-1] == "result: PASS"
    assert "mass_matrix" in text and "kg m^2" in text


def test_same_seed_same_states(two_link_torque):
    a = sample_states(two_link_torque, 10, seed=4)
    b = sample_states(two_link_torque, 10, seed=4)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.tau, b.tau)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_states": -1}, "n_states must be an integer >= 0; got -1"),
        ({"n_states": 2.5}, "n_states must be an integer >= 0; got 2.5"),
        ({"seed": "x"}, "seed must be an integer >= 0; got 'x'"),
        ({"chunk_size": 0}, "chunk_size must be an integer >= 1; got 0"),
        ({"tolerances": {}}, "tolerances has no entry for fk_position"),
        (
            {"progress": 3},
            r"progress must be a callable progress\(done_states, total_states\) or None; got 3",
        ),
    ],
)
def test_bad_arguments_raise(two_link, kwargs, match):
    with pytest.raises(CrossCheckError, match=match):
        crosscheck(two_link, **kwargs)


def test_bad_tolerance_raises():
    with pytest.raises(CrossCheckError, match="Tolerance.rtol must be a positive finite number; got 0.0"):
        Tolerance(0.0, 1.0, "m", "x")


def test_progress_counts_states_up_to_the_total(two_link_torque):
    calls: list[tuple[int, int]] = []
    report = crosscheck(
        two_link_torque,
        n_states=37,
        seed=0,
        chunk_size=8,
        progress=lambda done, total: calls.append((done, total)),
    )
    done = [d for d, _ in calls]
    assert done == [8, 16, 24, 32, 39]  # one call per chunk of 8, the last one partial
    assert all(a < b for a, b in zip(done, done[1:], strict=False))
    assert {total for _, total in calls} == {report.n_states} == {39}


def test_progress_is_not_called_without_states_to_evaluate(write_model, asset):
    chain = asset("chain.xml")
    lhs, rhs = asset("chain.xml").read_text().split('        <joint name="j2" axis="0 0 1"/>\n')
    robot = load_robot(chain, pin_model_file=write_model("two.xml", lhs + rhs), check=False)
    calls: list[tuple[int, int]] = []
    crosscheck(robot, n_states=5, progress=lambda done, total: calls.append((done, total)))
    assert calls == []


def test_chunking_does_not_change_results(g1):
    a = crosscheck(g1, n_states=20, seed=5, chunk_size=3)
    b = crosscheck(g1, n_states=20, seed=5, chunk_size=64)
    assert [q.max_abs_error for q in a.quantities] == [q.max_abs_error for q in b.quantities]


# ---------------------------------------------------------------- CLI


def _mbctl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "mbctl.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ),
    )


def test_cli_xcheck_passes_and_writes_json(tmp_path):
    out = _mbctl(
        "xcheck", "two_link_torque", "--states", "20", "--seed", "3", "--json", str(tmp_path / "r.json")
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "result: PASS"
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["n_states"] == 22 and data["seed"] == 3 and data["passed"] is True


def test_cli_xcheck_exits_1_on_a_different_pin_model(write_model):
    text = (ASSETS / "two_link_arm.xml").read_text().replace(' armature="0.002"', "")
    arm = write_model("arm.xml", text)
    out = _mbctl("xcheck", "two_link_torque", "--states", "10", "--pin-model", str(arm))
    assert out.returncode == 1, out.stderr
    assert "load-time agreement check found differences" in out.stdout
    assert out.stdout.splitlines()[-1] == "result: FAIL"


# ---------------------------------------------------------------- the batched evaluation


def _evaluator(robot, n_states=20, seed=0, chunk=8):
    from mbctl.robots.crosscheck.evaluator import Evaluator
    from mbctl.robots.crosscheck.frames import match_frames
    from mbctl.robots.crosscheck.plant import comparison_model

    m, _ = comparison_model(robot.mj_model, robot.scene_body_ids)
    states = sample_states(robot, n_states, seed)
    evaluator = Evaluator(robot, m, match_frames(robot), chunk)
    evaluator._evaluate(states, 0, chunk)
    return evaluator, states


@pytest.mark.parametrize("name", ["g1", "leg"])
def test_batched_frame_jacobians_equal_get_frame_jacobian(name, request, asset):
    import pinocchio as pin

    robot = (request.getfixturevalue("g1") if name == "g1"
             else load_robot(asset("ball_free_leg.xml"), check=False))
    evaluator, states = _evaluator(robot)
    P, _ = evaluator.aligned(evaluator.chunk, full=True)
    pm, pd = robot.pin_model, robot.pin_model.createData()
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for i in (0, 3, 7):  # slots of the chunk: states 0, 3, 7
        pin.computeAllTerms(pm, pd, states.q[i], states.v[i])
        pin.updateFramePlacements(pm, pd)
        for k, f in enumerate(evaluator.frames.pin_ids):
            np.testing.assert_allclose(P["jacobian"][i, k], pin.getFrameJacobian(pm, pd, f, lwa), atol=1e-14)
            np.testing.assert_allclose(P["frames"][i, k, :, 3], pd.oMf[f].translation, atol=1e-14)
            np.testing.assert_allclose(P["frames"][i, k, :, :3], pd.oMf[f].rotation, atol=1e-14)


def test_jacobians_compared_on_the_supports_give_the_full_maxima(g1):
    """Outside both engines' supports every entry is exactly zero: the packed maxima are the full ones."""
    for s in (0, 5, 9):  # one state at a time: MuJoCo's dense Jacobians are kept for one state
        evaluator, states = _evaluator(g1, chunk=1)
        evaluator._evaluate(states, s, s + 1)
        packed = evaluator._reduced(*evaluator.aligned(1), 1)
        evaluator._evaluate(states, s, s + 1)
        Pf, Qf = evaluator.aligned(1, full=True)
        outside = np.broadcast_to((evaluator._mask == 0)[None, :, None, :], Pf["jacobian"].shape)
        assert np.all(Pf["jacobian"][outside] == 0.0) and np.all(Qf["jacobian"][outside] == 0.0)
        full = np.abs(Pf["jacobian"] - Qf["jacobian"])
        assert packed["jacobian_linear"][0][0] == full[:, :, :3].max()
        assert packed["jacobian_angular"][0][0] == full[:, :, 3:].max()
        assert packed["jacobian_linear"][1] == np.abs(Qf["jacobian"][:, :, :3]).max()
