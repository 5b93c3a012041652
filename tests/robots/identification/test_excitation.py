"""How the data determined each number: identified, weakly excited, or not identified (the prior's)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots.identification import IdentifyOptions, RecordedLog, identify
from mbctl.robots.identification.identifiability import WEAK_RTOL
from mbctl.robots.identification.summary import base_summaries, body_summary, joint_summaries
from mbctl.robots.registry import load_robot

#: A cart on a vertical slide (known) carrying an arm on a hinge about y: the slide's force weighs
#: the arm, so its mass is identifiable on its own, and with it the CoM.
LIFT = """<mujoco><option gravity="0 0 -9.81"/><worldbody><body name="cart"><joint name="lift" type="slide"
axis="0 0 1"/><inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/><body name="arm">
<joint name="swing" axis="0 1 0"/><inertial pos="0.1 0 0.02" mass="1" diaginertia="0.001 0.01 0.01"/>
</body></body></worldbody>
<actuator><motor joint="lift"/><motor joint="swing"/></actuator></mujoco>"""


def _one_joint_log(robot, amplitude_rad: float, duration_s: float = 8.0) -> RecordedLog:
    """The arm swings +-amplitude about hanging sideways (q = 0) at 0.5 Hz; the slide holds still.

    Exact inverse dynamics (v such that forward differences give a), no filter needed.
    """
    dt = robot.timestep_s
    t = np.arange(int(duration_s / dt)) * dt
    w = 2 * np.pi * 0.5
    zero = np.zeros_like(t)
    q = np.stack([zero, amplitude_rad * np.sin(w * t)], axis=1)
    a = np.stack([zero, -amplitude_rad * w**2 * np.sin(w * t)], axis=1)
    v0 = np.array([0.0, amplitude_rad * w])
    v = np.vstack([v0, v0 + np.cumsum(a[:-1] * dt, axis=0)])
    model, data = robot.pin_model, robot.pin_model.createData()
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k]) for k in range(len(t))])
    return RecordedLog(t, q, v, tau, tuple(robot.joints))


@pytest.fixture(scope="module")
def lift(tmp_path_factory):
    path = tmp_path_factory.mktemp("lift") / "lift.xml"
    path.write_text(LIFT)
    return load_robot(path)


def _identify(robot, amplitude_rad):
    return identify(robot, [_one_joint_log(robot, amplitude_rad)],
                    IdentifyOptions(bodies=("arm",), cutoff_hz=None, rate_hz=None, structural_samples=0))


def test_a_barely_excited_com_component_is_marked_weakly_excited(lift):
    """A 0.3 rad swing about hanging sideways barely moves the CoM's z lever: marked, not 'identified'."""
    ident = _identify(lift, 0.3)
    arm = body_summary(ident, "arm")
    assert arm.mass_status == "identified"
    assert arm.com_status == ("identified", "not identified", "weakly excited")  # y: along the hinge
    excitation = dict(zip(ident.params.names, ident.data.parameter_excitation(), strict=True))
    assert excitation["arm.m"] == pytest.approx(1.0)  # the best-determined direction
    assert excitation["arm.mcz"] < WEAK_RTOL < excitation["arm.mcx"]
    summary = ident.data.summary()
    assert "arm.mcz" in summary["weakly_excited"] and "arm.mcx" not in summary["weakly_excited"]
    assert summary["weak_excitation_below"] == WEAK_RTOL
    statuses = {s.expression: s.status for s in base_summaries(ident)}
    assert statuses["arm.mcz"] == "weakly excited" and statuses["arm.m"] == "identified"


def test_a_wide_swing_identifies_the_same_component(lift):
    arm = body_summary(_identify(lift, 1.0), "arm")
    assert arm.com_status == ("identified", "not identified", "identified")


def test_a_hinge_alone_never_identifies_a_com():
    """On one hinge the mass enters only through the first moments: c = h / m is the prior's."""
    robot = load_robot(Path(__file__).resolve().parents[1] / "assets" / "one_hinge.xml")
    ident = identify(robot, [_one_hinge_log(robot)], IdentifyOptions(cutoff_hz=None, rate_hz=None,
                                                                    structural_samples=0))
    link = body_summary(ident, "link")
    assert link.mass_status == "not identified"
    assert link.com_status == ("not identified",) * 3


def _one_hinge_log(robot) -> RecordedLog:
    dt = robot.timestep_s
    t = np.arange(int(8.0 / dt)) * dt
    w = 2 * np.pi * 0.5
    q = (0.3 + np.sin(w * t))[:, None]
    a = (-w**2 * np.sin(w * t))[:, None]
    v = np.vstack([[w], w + np.cumsum(a[:-1, 0] * dt)[:, None]])
    model, data = robot.pin_model, robot.pin_model.createData()
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k]) for k in range(len(t))]).reshape(-1, 1)
    return RecordedLog(t, q, v, tau, tuple(robot.joints))


def test_joint_parameters_carry_their_status(two_link_torque_gravity):
    """Friction of a joint the log never moves is not identified; of a moving one, identified."""
    robot = two_link_torque_gravity
    dt = robot.timestep_s
    t = np.arange(int(6.0 / dt)) * dt
    w = 2 * np.pi * np.array([0.4, 0.9])
    zero = np.zeros_like(t)
    q = np.stack([zero, 0.8 * np.sin(w[1] * t)], axis=1)
    a = np.stack([zero, -0.8 * w[1] ** 2 * np.sin(w[1] * t)], axis=1)
    v0 = np.array([0.0, 0.8 * w[1]])
    v = np.vstack([v0, v0 + np.cumsum(a[:-1] * dt, axis=0)])
    model, data = robot.pin_model, robot.pin_model.createData()
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k]) for k in range(len(t))])
    ident = identify(robot, [RecordedLog(t, q, v, tau, tuple(robot.joints))],
                     IdentifyOptions(friction=True, cutoff_hz=None, rate_hz=None, structural_samples=0))
    joints = joint_summaries(ident)
    assert joints["shoulder"]["viscous"].status == "not identified"
    assert joints["elbow"]["viscous"].status == "identified"
    assert joints["elbow"]["viscous"]._asdict()["status"] == "identified"  # what the report writes
