"""The robot-agnostic whole-body IK (``mbctl.control.ik.backends``) on a tiny biped in code.

No G1 here: the task set is named by a ``WholeBodyIKConfig`` (feet held, a hand target, the torso's
orientation, CoM), and both backends ("qp" on Pinocchio, "mink" on MuJoCo) must build the same QP
and reach the same pose on a model with free, ball and hinge joints.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import mbctl
from mbctl.control import IKSetupError
from mbctl.control.ik import BACKENDS, WholeBodyIKConfig, make_whole_body_ik
from mbctl.control.tasks import Tolerance

#: Agreement of the two backends' velocity steps [rad/s, m/s] (inf-norm) without the posture
#: regulariser: the same strictly convex QP solved by daqp; the difference is round-off.
STEP_ATOL = 1e-10

#: With the posture regulariser: on a ball joint our posture Jacobian is the exact
#: ``pin.dDifference`` block, mink's the identity, so the Hessians differ by O(cost^2 |e|^2)
#: there (1e-7 here, with |e| ~ 0.1 rad) and the steps by about 1e-8.
STEP_ATOL_BALL_POSTURE = 1e-7

TINY_BIPED = """
<mujoco model="tiny_biped">
  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>
  <worldbody>
    <body name="torso" pos="0 0 0.55">
      <freejoint name="root"/>
      <inertial pos="0 0 0.1" mass="5" diaginertia="0.1 0.1 0.05"/>
      <body name="left_thigh" pos="0 0.1 0">
        <joint name="left_hip" axis="0 1 0" range="-1.5 1.5"/>
        <inertial pos="0 0 -0.15" mass="1" diaginertia="0.01 0.01 0.002"/>
        <body name="left_shin" pos="0 0 -0.3">
          <joint name="left_knee" axis="0 1 0" range="0 2.5"/>
          <inertial pos="0 0 -0.15" mass="0.8" diaginertia="0.01 0.01 0.002"/>
          <site name="left_foot" pos="0 0 -0.3"/>
        </body>
      </body>
      <body name="right_thigh" pos="0 -0.1 0">
        <joint name="right_hip" axis="0 1 0" range="-1.5 1.5"/>
        <inertial pos="0 0 -0.15" mass="1" diaginertia="0.01 0.01 0.002"/>
        <body name="right_shin" pos="0 0 -0.3">
          <joint name="right_knee" axis="0 1 0" range="0 2.5"/>
          <inertial pos="0 0 -0.15" mass="0.8" diaginertia="0.01 0.01 0.002"/>
          <site name="right_foot" pos="0 0 -0.3"/>
        </body>
      </body>
      <body name="upper_arm" pos="0 -0.15 0.3">
        <joint name="shoulder" type="ball"/>
        <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.002 0.002 0.002"/>
        <body name="forearm" pos="0.2 0 0">
          <joint name="elbow" axis="0 0 1" range="-2 2"/>
          <inertial pos="0.1 0 0" mass="0.3" diaginertia="0.001 0.001 0.001"/>
          <site name="hand" pos="0.2 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe>
    <key name="crouch" qpos="0 0 0.5 1 0 0 0  -0.4 0.8  -0.4 0.8  0.96 0 0 0.28  0.6"/>
  </keyframe>
</mujoco>
"""

#: The task set, in frame names only.
CONFIG = WholeBodyIKConfig(held_frames=("left_foot", "right_foot"), target_frames=("hand",),
                           base_frame="torso", com=True)


@pytest.fixture(scope="module")
def biped(tmp_path_factory):
    from mbctl.robots import load_robot

    path = tmp_path_factory.mktemp("biped") / "tiny_biped.xml"
    path.write_text(TINY_BIPED)
    return load_robot(path)


def _away(robot, q, seed, scale=0.05):
    """A configuration near ``q`` with every task off its target (no exactly-zero rotation)."""
    rng = np.random.default_rng(seed)
    return pin.integrate(robot.pin_model, q, scale * rng.standard_normal(robot.nv))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("posture_cost", "atol"), [(0.0, STEP_ATOL), (1e-2, STEP_ATOL_BALL_POSTURE)])
def test_both_backends_give_the_same_step(biped, seed, posture_cost, atol):
    q_ref = biped.keyframe_q("crouch")
    config = dataclasses.replace(CONFIG, posture_cost=posture_cost)
    iks = {b: make_whole_body_ik(b, biped, config, q_ref) for b in BACKENDS}
    for ik in iks.values():
        ik.set_target_position("hand", iks["qp"].frame_position("hand") + [0.05, 0.03, -0.04])
        ik.set_com_target(iks["qp"].com()[:2] + [0.01, -0.01])
    q = _away(biped, q_ref, seed)
    v = {b: ik.step(q) for b, ik in iks.items()}
    assert np.max(np.abs(v["qp"])) > 1e-2  # a real step
    assert np.max(np.abs(v["qp"] - v["mink"])) < atol
    # the same task set, residual by residual
    for ik in iks.values():
        ik.update(q)
    r_qp, r_mink = iks["qp"].task_residuals(), iks["mink"].task_residuals()
    assert r_qp.keys() == r_mink.keys() == {"left_foot", "right_foot", "hand", "torso", "com", "posture"}
    for task, residual in r_qp.items():
        for field, value in residual._asdict().items():
            other = getattr(r_mink[task], field)
            assert (value is None) == (other is None), (task, field)
            if value is not None:
                assert other == pytest.approx(value, abs=1e-12), (task, field)


@pytest.mark.parametrize("backend", BACKENDS)
def test_each_backend_reaches_a_hand_target_with_feet_and_torso_held(biped, backend):
    q0 = biped.keyframe_q("crouch")
    config = WholeBodyIKConfig(held_frames=("left_foot", "right_foot"), target_frames=("hand",),
                               base_frame="torso")
    ik = make_whole_body_ik(backend, biped, config, q0)
    start = {f: ik.frame_position(f) for f in ("left_foot", "right_foot")}
    target = ik.frame_position("hand") + [0.05, 0.05, 0.05]
    ik.set_target_position("hand", target)
    # tol 0.1 mm (1 mrad): the posture regulariser (cost 1e-2 vs 1 on the feet' orientation)
    # biases the optimum by about (1e-2)^2 x 0.8 rad of posture deviation, ~1e-4 rad
    res = ik.solve(q0, Tolerance(1e-4, 1e-3), max_iters=20)
    assert res.converged and res.iterations <= 6, res.residuals
    ik.update(res.q)
    np.testing.assert_allclose(ik.frame_position("hand"), target, atol=1e-4)
    for foot, p in start.items():
        np.testing.assert_allclose(ik.frame_position(foot), p, atol=1e-4)
    q_ball = res.q[biped.joint("shoulder").q_slice]  # ball quaternion stays unit (manifold steps)
    assert abs(np.linalg.norm(q_ball) - 1.0) < 1e-12
    assert res.iteration_times_s.shape == (res.iterations,)


def test_setup_errors_name_the_alternatives(biped):
    q0 = biped.keyframe_q("crouch")
    with pytest.raises(IKSetupError, match="IK backend 'pink' is unknown; choose one of qp, mink"):
        make_whole_body_ik("pink", biped, CONFIG, q0)
    bad = WholeBodyIKConfig(target_frames=("hnad",))
    with pytest.raises(IKSetupError, match="Did you mean 'hand'"):
        make_whole_body_ik("qp", biped, bad, q0)
    ik = make_whole_body_ik("qp", biped, WholeBodyIKConfig(target_frames=("hand",)), q0)
    with pytest.raises(IKSetupError, match="no CoM task"):
        ik.set_com_target([0.0, 0.0])
    with pytest.raises(IKSetupError, match="finite \\(3,\\) position"):
        ik.set_target_position("hand", [0.0, np.nan, 0.0])


def test_no_robot_names_in_control_ik():
    """control/ is robot-agnostic: the G1's names live in mbctl.robots.g1."""
    folder = Path(mbctl.__file__).resolve().parent / "control"
    pattern = re.compile(r"\bg1\b|unitree|palm|wrist_yaw|left_foot|right_foot|\"stand\"", re.IGNORECASE)
    for path in folder.rglob("*.py"):
        code = [line for line in path.read_text().splitlines() if not line.lstrip().startswith(("#", "*"))]
        hits = [line for line in code if pattern.search(line) and "e.g." not in line]
        assert not hits, f"{path.name}: {hits}"
