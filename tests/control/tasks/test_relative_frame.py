"""RelativeFrameTask: ``e = log6(X_TF)`` (``X_TF = X_RT^-1 X_RF``), ``J_e = Jlog6(X_TF) J_rel``.

``J_rel = J_F - Ad(X_FR) J_R``: F and R may both move; R may be the world (``universe``).
No acceleration-level form.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import DynamicsState, FramePoseTask, KinematicState, RelativeFrameTask
from mbctl.robots import UnknownNameError
from tests.control.tasks.conftest import (
    ARM,
    FLOATING,
    acceleration_objective,
    expected_velocity_objective,
    fd_jacobian,
    inf_norm,
    kinematic_error,
    random_q,
    velocity_objective,
    velocity_rows,
)

# (model, F, R): both on the floating tree, one of them on the base, and R the world
CASES = [(ARM, "tip", "elbow"), (FLOATING, "hand", "chest"), (FLOATING, "foot", "hand"),
         (FLOATING, "hand", "universe")]
IDS = [f"{model.name}-{frame}-in-{reference}" for model, frame, reference in CASES]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _X_RF(state: KinematicState, frame: str, reference: str) -> pin.SE3:
    return state.frame_pose(state.frame_id(reference)).actInv(state.frame_pose(state.frame_id(frame)))


@pytest.mark.parametrize(("model", "frame", "reference"), CASES, ids=IDS)
def test_the_error_is_the_twist_from_the_target_to_the_frame_in_the_reference(model, frame, reference):
    state = KinematicState(model, random_q(model, np.random.default_rng(3)))
    task = RelativeFrameTask(frame, reference, model)
    with pytest.raises(TaskSetupError, match="no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_allclose(task.compute_error(state), np.zeros(6), atol=1e-14)
    # X_RT = X_RF exp6(xi): X_TF = exp6(-xi), so e = -xi (the opposite sign of FramePoseTask's)
    xi = np.array([0.1, -0.05, 0.2, 0.4, -0.3, 0.6])
    task.set_target(_X_RF(state, frame, reference) * pin.exp6(pin.Motion(xi)))
    np.testing.assert_allclose(task.compute_error(state), -xi, atol=1e-14)
    residual = task.residual(state)
    X_TF = pin.exp6(pin.Motion(-xi))
    assert residual.position_m == pytest.approx(np.linalg.norm(X_TF.translation), rel=1e-13)
    assert residual.orientation_rad == pytest.approx(np.linalg.norm(xi[3:]), rel=1e-13)


@pytest.mark.parametrize(("model", "frame", "reference"), CASES, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, frame, reference, seed):
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    task = RelativeFrameTask(frame, reference, model)
    # the target within 1 rad of F (log6 is singular at pi, where differences lose their digits)
    task.set_target(_X_RF(state, frame, reference) * pin.exp6(pin.Motion(rng.uniform(-0.5, 0.5, 6))))
    J = task.compute_jacobian(state)
    assert J.shape == (6, model.nv)
    err = inf_norm(J - fd_jacobian(kinematic_error(task, model), model, q))
    assert err < 1e-8, f"|J - J_fd|_inf = {err:.2e}"
    if model is FLOATING and reference != "universe":
        # F and R ride on the same base: moving the base alone leaves the error unchanged
        np.testing.assert_allclose(J[:, :6], 0.0, atol=1e-13)


def test_in_the_world_frame_it_is_the_pose_task_with_the_opposite_sign():
    rng = np.random.default_rng(8)
    state = KinematicState(FLOATING, random_q(FLOATING, rng))
    X_WT = pin.exp6(pin.Motion(0.5 * rng.standard_normal(6)))
    relative = RelativeFrameTask("hand", "universe", FLOATING)
    pose = FramePoseTask("hand", FLOATING)
    relative.set_target(X_WT)
    pose.set_target(X_WT)
    np.testing.assert_allclose(relative.compute_error(state), -pose.compute_error(state), atol=1e-14)
    np.testing.assert_allclose(relative.compute_jacobian(state), -pose.compute_jacobian(state), atol=1e-13)


@pytest.mark.parametrize(("model", "frame", "reference"), CASES, ids=IDS)
def test_the_rows_and_the_stacked_objective_follow_the_error_and_jacobian(model, frame, reference):
    rng = np.random.default_rng(9)
    q = random_q(model, rng)
    state = KinematicState(model, q)
    task = RelativeFrameTask(frame, reference, model, position_cost=[1.0, 0.0, 2.0],
                             orientation_cost=[0.5, 0.5, 0.0], gain=0.9, lm_damping=0.1)
    task.set_target(_X_RF(state, frame, reference) * pin.exp6(pin.Motion(0.2 * rng.standard_normal(6))))
    e, J = task.error_and_jacobian(state)
    # velocity level: the active rows, unweighted and not negated
    active = [0, 2, 3, 4]
    assert task.active_rows().tolist() == active
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, J[active], atol=1e-14)
    np.testing.assert_allclose(e_rows, e[active], atol=1e-15)
    H, c, mu = velocity_objective(task, state)
    H_ref, c_ref, mu_ref = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == pytest.approx(mu_ref, rel=1e-13)
    # no acceleration-level form: the task, and a stack holding it, say so
    dyn = DynamicsState(model, q)
    with pytest.raises(TaskSetupError, match="RelativeFrameTask has no acceleration-level form"):
        task.jacobian_and_drift(dyn)
    with pytest.raises(TaskSetupError, match="no acceleration-level form"):
        acceleration_objective(task, dyn)


def test_an_unknown_reference_is_named():
    with pytest.raises(UnknownNameError, match="elbw"):
        RelativeFrameTask("tip", "elbw", ARM)
