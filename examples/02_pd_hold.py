"""Write your own controller against the robot API: PD plus gravity, holding a pose.

A controller is any object with ``reset()`` and ``compute(state, reference) -> Command``. It
reads the measured state (q, v in Pinocchio's convention) and returns a typed command; it never
steps the plant. The control loop ``mbctl.control.run`` does that, on the simulator here (on the
G1 over DDS the same, unchanged). The law, per joint::

    tau = kp (q_ref - q) + kd (v_ref - v) + g(q)        [N m]

with ``g(q) = robot.gravity(q)`` the generalized gravity of the Pinocchio model and gains from
a natural frequency, a damping ratio and the joint inertia (the diagonal of
``robot.mass_matrix(q)``): ``kp = I omega^2``, ``kd = 2 zeta I omega``. The arm
starts at rest 0.2 rad away from the pose, under gravity (-y, in the arm's plane). The same law
ships as ``mbctl.control.PDGravity``; both are run and compared, and the library's plain
``JointPD`` shows the sag that the gravity term removes.

Run::

    python examples/02_pd_hold.py                  # 2 s
    python examples/02_pd_hold.py --duration 0.1

Exits 1 if the two implementations differ by more than 1e-9 rad, or (for runs long enough to
settle) if the steady-state error of PD + gravity exceeds 0.01 mrad.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from mbctl.control import (
    Controller,
    JointPD,
    JointReference,
    PDGravity,
    gains_from_frequency,
    joint_reference,
    run,
)
from mbctl.robots import Robot, load_robot
from mbctl.sim import Command, RobotState, Simulator, torque

#: Pose to hold [rad] (shoulder, elbow) and the offset [rad] the arm starts at.
HOLD_Q_RAD = np.array([0.4, 0.8])
START_OFFSET_RAD = -0.2
OMEGA_RAD_S = 20.0  # closed-loop natural frequency
ZETA = 1.0  # damping ratio (critical)
#: Time [s] after which the critically damped error is below 1e-6 of its start: (1 + w t) e^(-w t).
SETTLE_S = 1.0
MAX_STEADY_STATE_ERROR_RAD = 1e-5
MAX_IMPLEMENTATION_DIFFERENCE_RAD = 1e-9


class MyPDGravity:
    """``tau = kp (q_ref - q) + kd (v_ref - v) + g(q)`` on every actuated joint; torque output.

    Args:
        robot: A fixed-base robot whose actuators are torque motors, one per joint.
        kp: Stiffness per joint (nv,) [N m/rad].
        kd: Damping per joint (nv,) [N m s/rad].
    """

    def __init__(self, robot: Robot, kp: np.ndarray, kd: np.ndarray):
        self.robot = robot
        self.kp, self.kd = kp, kd
        # Actuator k drives the joint at v-index idx_v[k]: commands are in actuator order.
        self.idx_v = [robot.joint(a.joint).idx_v for a in robot.actuators.values()]

    def reset(self) -> None:
        """Nothing to clear: the law has no internal state."""

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Torque command (nu,) [N m] for ``state`` holding ``reference``."""
        g = self.robot.gravity(state.q)  # (nv,) [N m]
        tau = self.kp * (reference.q - state.q) + self.kd * (reference.v - state.v) + g
        return torque(tau[self.idx_v])


def hold(robot: Robot, controller: Controller[JointReference], duration_s: float) -> np.ndarray:
    """Run ``controller`` from rest at the start pose; the final joint error (nv,) [rad]."""
    sim = Simulator(robot)
    sim.reset(q=HOLD_Q_RAD + START_OFFSET_RAD)
    run(sim, controller, joint_reference(HOLD_Q_RAD), duration_s)
    return HOLD_Q_RAD - sim.q


def main() -> int:
    """Run both PD + gravity controllers and plain PD; print and check the errors."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")

    robot = load_robot("two_link_torque", gravity=True)
    inertia = np.diag(robot.mass_matrix(HOLD_Q_RAD))  # joint inertias [kg m^2]
    gains = gains_from_frequency(OMEGA_RAD_S, ZETA, inertia)
    print(f"{robot.name}, gravity {robot.mj_model.opt.gravity.tolist()} m/s^2; hold "
          f"{HOLD_Q_RAD.tolist()} rad from {START_OFFSET_RAD:+g} rad away, {args.duration:g} s")
    print(f"gains: kp {np.round(gains.kp, 3).tolist()} N m/rad, kd {np.round(gains.kd, 4).tolist()} "
          f"N m s/rad (omega {OMEGA_RAD_S:g} rad/s, zeta {ZETA:g}, inertia "
          f"{np.round(inertia, 4).tolist()} kg m^2)")

    mine = hold(robot, MyPDGravity(robot, gains.kp, gains.kd), args.duration)
    library = hold(robot, PDGravity(robot, gains), args.duration)
    sag = hold(robot, JointPD(robot, gains), args.duration)
    for label, err in (("my PD + gravity", mine), ("library PDGravity", library),
                       ("library JointPD (no g)", sag)):
        print(f"  {label:<24} final error {(np.round(1e3 * err, 4) + 0.0).tolist()} mrad, "
              f"max {1e3 * np.max(np.abs(err)):.4f} mrad")
    difference = float(np.max(np.abs(mine - library)))
    steady = float(np.max(np.abs(mine)))
    print(f"my controller vs the library: {difference:.2e} rad "
          f"(bound {MAX_IMPLEMENTATION_DIFFERENCE_RAD:g} rad)")
    ok = difference <= MAX_IMPLEMENTATION_DIFFERENCE_RAD
    if args.duration >= SETTLE_S:
        print(f"steady-state error: {1e3 * steady:.2e} mrad "
              f"(bound {1e3 * MAX_STEADY_STATE_ERROR_RAD:g} mrad)")
        ok = ok and steady <= MAX_STEADY_STATE_ERROR_RAD
    else:
        print(f"steady-state error: not checked (the run is shorter than the {SETTLE_S:g} s "
              "settling time)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
