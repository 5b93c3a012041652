"""The whole-body controller's joint-friction feed-forward: the model's friction at the planned velocity.

On the biped of conftest.py with MuJoCo's dry friction on every joint (0.3 N m, as the Menagerie
G1): the added torque is ``f_c tanh(v_plan / speed) + d v_plan`` with ``v_plan = v + vdot dt``, and
a released foot carried by a pose task follows it with the feed-forward, and lags without.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control import run
from mbctl.control.tasks import AccelerationGains, FramePoseTask
from mbctl.control.wbc import Scheduled, WBCConfig, standing_controller
from mbctl.planners import minimum_jerk_at
from mbctl.robots import load_robot
from mbctl.robots.interface import RobotState
from mbctl.sim import Simulator

from .conftest import JOINTS, biped_xml

FEET = ("l_sole", "r_sole")
FRICTION_N_M = 0.3


@pytest.fixture(scope="module")
def sticky_biped(tmp_path_factory):
    """The biped with 0.3 N m of dry friction on every joint (MuJoCo's frictionloss; Pinocchio's friction)."""
    path = tmp_path_factory.mktemp("sticky") / "biped.xml"
    friction = f'damping="0.05" frictionloss="{FRICTION_N_M}"'
    path.write_text(biped_xml(JOINTS).replace('damping="0.05"', friction))
    return load_robot(path)


def test_the_added_torque_is_the_models_friction_at_the_planned_velocity(sticky_biped, crouch):
    robot = sticky_biped
    act = [robot.joint(j).idx_v for j in JOINTS]
    assert np.all(robot.pin_model.friction[act] == FRICTION_N_M)
    v = np.zeros(robot.nv)
    v[act] = np.linspace(-0.02, 0.02, len(act))
    taus, vdot = {}, None
    for on in (False, True):
        wb = standing_controller(robot, FEET, "pelvis", "torso",
                                 config=WBCConfig(friction_feedforward=on, friction_speed_rad_s=0.01))
        wb.hold(RobotState(crouch(robot), np.zeros(robot.nv), 0.0))
        first = wb.controller.compute(RobotState(crouch(robot), v, 0.0)).values  # no dt yet: v_plan = v
        second = wb.controller.compute(RobotState(crouch(robot), v, 0.004)).values
        taus[on] = (first, second)
        vdot = wb.controller.solution.vdot  # the QP is the same with and without: friction comes after it
    expected_first = FRICTION_N_M * np.tanh(v[act] / 0.01) + 0.05 * v[act]
    np.testing.assert_allclose(taus[True][0] - taus[False][0], expected_first, atol=1e-9)
    v_plan = v[act] + vdot[act] * 0.004
    expected_second = FRICTION_N_M * np.tanh(v_plan / 0.01) + 0.05 * v_plan
    np.testing.assert_allclose(taus[True][1] - taus[False][1], expected_second, atol=1e-9)
    assert np.abs(expected_second).max() > 0.2  # the check is not on zeros


def _lift_right_foot(robot, crouch, friction_feedforward: bool) -> float:
    """Shift over the left foot, release the right one and lift it 3 cm; the largest foot error [m]."""
    sim = Simulator(robot)
    sim.reset(q=crouch(robot))
    wb = standing_controller(robot, FEET, "pelvis", "torso",
                             config=WBCConfig(friction_feedforward=friction_feedforward))
    wb.hold(sim.read_state())
    ctrl = wb.controller
    c0 = ctrl.state.com().copy()
    left = ctrl.state.frame_pose(ctrl.contacts["l_sole"].fid).translation
    over_left = np.array([left[0], left[1], c0[2]])
    swing = FramePoseTask("r_sole", ctrl.model, 10.0, 10.0, servo=AccelerationGains(20.0, 1.0))
    down: list[pin.SE3] = []
    errors: list[float] = []

    def schedule(t: float, state: RobotState) -> None:
        wb.com.set_target(*minimum_jerk_at(c0, over_left, t, 0.0, 1.0))
        if t >= 1.0 and not down and ctrl.contacts["r_sole"].target_weight > 0:
            ctrl.release("r_sole")
        if ctrl.contact_released("r_sole") and not down:
            down.append(pin.SE3(ctrl.state.frame_pose(ctrl.contacts["r_sole"].fid)))
            swing.set_target(down[0])
            ctrl.add_task(swing)
        if down:
            p0 = down[0].translation
            p, v, a = minimum_jerk_at(p0, p0 + [0.0, 0.0, 0.03], t, 1.5, 0.6)
            swing.set_target(pin.SE3(down[0].rotation, p), v, a)
            X = ctrl.state.frame_pose(ctrl.contacts["r_sole"].fid)
            errors.append(float(np.linalg.norm(pin.log6(X.actInv(swing.transform_target_to_world)).vector)))

    run(sim, Scheduled(ctrl, schedule), None, 2.5)
    return max(errors)


def test_a_free_foot_follows_its_task_with_the_feed_forward_and_lags_without(sticky_biped, crouch):
    with_ff = _lift_right_foot(sticky_biped, crouch, True)
    without = _lift_right_foot(sticky_biped, crouch, False)
    # measured: 9.6 mm (or mrad) with the feed-forward, 46 without
    assert with_ff < 0.015
    assert without > 3.0 * with_ff
