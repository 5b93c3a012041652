"""Control-loop time through the mbctl API against a hand-written loop doing the same work.

Run: MENAGERIE_ROOT=/path/to/menagerie python bench/bench_control.py [--cpu-time] [--repeats 9]

``--cpu-time`` times each loop in this thread's CPU time (``time.thread_time``) instead of wall
time: on a machine other processes share, the waits for a core are left out of both sides.

Cases (both measured in this run, interleaved, medians of 9):

* G1 PD + gravity, floating base on the floor, torque motors: API = ``control.loop.run`` with
  ``PDGravity`` on a ``Simulator``; hand = read qpos/qvel, convert to Pinocchio's convention
  (quaternion reorder, base velocity to the base frame), ``computeGeneralizedGravity``, PD,
  clip to the torque limits, write ctrl, ``mj_step``, log q, v and torques.
* 2-link computed torque on the Cartesian square's joint trajectory: API = ``run`` with
  ``ComputedTorque``; hand = the same law with ``pin.rnea``, clip, ctrl, ``mj_step``, log.
  The hand loop indexes a reference sampled before timing; the API samples inside ``run``.

A third loop, "floor", runs the hand-written law through the robot API (``read_state``,
``Command``, ``send``, ``sync``): its ratio to the hand loop is what the robot API costs before
any mbctl controller code runs.

Goals: G1 PD + gravity <= 1.15x, 2-link computed torque <= 1.3x (issue 21; 1.5x before).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved  # noqa: E402

from mbctl.control.computed_torque import ComputedTorque  # noqa: E402
from mbctl.control.controller import joint_reference  # noqa: E402
from mbctl.control.gains import PDGains, gains_from_frequency  # noqa: E402
from mbctl.control.loop import presample, run  # noqa: E402
from mbctl.control.pd_gravity import PDGravity  # noqa: E402
from mbctl.jobs.demo import DemoConfig, square_reference  # noqa: E402
from mbctl.jobs.g1 import stance_inertia  # noqa: E402
from mbctl.robots import load_robot  # noqa: E402
from mbctl.robots.commands import Command, CommandKind  # noqa: E402
from mbctl.robots.edits import position_to_motor  # noqa: E402
from mbctl.robots.g1 import KEYFRAME  # noqa: E402
from mbctl.sim.simulator import Simulator  # noqa: E402

GOALS = {"G1 PD + gravity": 1.15, "2-link computed torque": 1.3}


TIMING = {"timer": time.perf_counter, "repeats": 9}


def g1_case(steps: int) -> tuple[float, float, float]:
    """Median seconds per step (api, hand, floor) for the G1 standing under PD + gravity."""
    robot = position_to_motor(load_robot("g1"))
    q0 = robot.keyframe_q(KEYFRAME)
    probe = PDGravity(robot, PDGains([1.0], [1.0]))
    gains = gains_from_frequency(10.0, 1.0, stance_inertia(robot, q0, probe.joints))
    controller = PDGravity(robot, gains)
    reference = joint_reference(q0[controller.joint_map.idx_q])
    sim = Simulator(robot)
    period = sim.control_period_s

    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    model = robot.pin_model
    data = model.createData()
    idx_q = np.asarray(controller.joint_map.idx_q)
    idx_v = np.asarray(controller.joint_map.idx_v)
    kp, kd = np.asarray(gains.kp), np.asarray(gains.kd)
    low, high = np.asarray(controller.joint_map.tau_low), np.asarray(controller.joint_map.tau_high)
    q_ref = np.asarray(reference.q)
    perm = np.r_[0:3, 4, 5, 6, 3, 7:robot.nq]  # MuJoCo (w, x, y, z) -> Pinocchio (x, y, z, w)
    log_q = np.empty((steps, robot.nq))
    log_v = np.empty((steps, robot.nv))
    log_tau = np.empty((steps, robot.nu))
    key = robot.keyframe_id(KEYFRAME)

    def api() -> None:
        sim.reset(KEYFRAME)
        run(sim, controller, reference, steps * period)

    def hand() -> None:
        mujoco.mj_resetDataKeyframe(m, d, key)
        for k in range(steps):
            q = d.qpos[perm]
            v = d.qvel.copy()
            x, y, z, w = q[3:7]
            R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                          [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                          [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            v[:3] = R.T @ v[:3]
            g = pin.computeGeneralizedGravity(model, data, q)
            tau = kp * (q_ref - q[idx_q]) + kd * (0.0 - v[idx_v]) + g[idx_v]
            np.clip(tau, low, high, out=tau)
            d.ctrl[:] = tau
            mujoco.mj_step(m, d)
            log_q[k], log_v[k], log_tau[k] = q, v, tau

    def hand_via_robot_api() -> None:
        """The hand-written law, but state, command and stepping through the robot API."""
        sim.reset(KEYFRAME)
        for k in range(steps):
            state = sim.read_state()
            q, v = state.q, state.v
            g = pin.computeGeneralizedGravity(model, data, q)
            tau = kp * (q_ref - q[idx_q]) + kd * (0.0 - v[idx_v]) + g[idx_v]
            np.clip(tau, low, high, out=tau)
            sim.send(Command(CommandKind.TORQUE, tau))
            sim.sync()
            log_q[k], log_v[k], log_tau[k] = q, v, tau

    t = interleaved({"api": api, "hand": hand, "floor": hand_via_robot_api}, **TIMING)  # type: ignore[arg-type]
    return t["api"] / steps, t["hand"] / steps, t["floor"] / steps


def two_link_case() -> tuple[float, float, float, int]:
    """Median seconds per step (api, hand, floor) and the steps, for computed torque on the square."""
    robot = load_robot("two_link_torque", gravity=True)
    sim = Simulator(robot)
    traj = square_reference(robot, DemoConfig(), robot.timestep_s).joints
    steps = len(traj.t_s)
    gains = gains_from_frequency(30.0, 1.0)
    controller = ComputedTorque(robot, gains)
    period = sim.control_period_s
    times = np.arange(steps) * period
    q_ref, v_ref, a_ref = presample(traj, times, controller.joints)

    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    model = robot.pin_model
    data = model.createData()
    kp, kd = float(gains.kp[0]), float(gains.kd[0])
    low, high = np.asarray(controller.joint_map.tau_low), np.asarray(controller.joint_map.tau_high)
    log_q = np.empty((steps, robot.nq))
    log_v = np.empty((steps, robot.nv))
    log_tau = np.empty((steps, robot.nu))

    def api() -> None:
        sim.reset(q=traj.q[0])
        run(sim, controller, traj, steps * period)

    def hand() -> None:
        mujoco.mj_resetData(m, d)
        d.qpos[:] = traj.q[0]
        mujoco.mj_forward(m, d)
        for k in range(steps):
            q = d.qpos.copy()
            v = d.qvel.copy()
            a = a_ref[k] + kp * (q_ref[k] - q) + kd * (v_ref[k] - v)
            tau = pin.rnea(model, data, q, v, a).copy()
            np.clip(tau, low, high, out=tau)
            d.ctrl[:] = tau
            mujoco.mj_step(m, d)
            log_q[k], log_v[k], log_tau[k] = q, v, tau

    def hand_via_robot_api() -> None:
        """The hand-written law, but state, command and stepping through the robot API."""
        sim.reset(q=traj.q[0])
        for k in range(steps):
            state = sim.read_state()
            q, v = state.q, state.v
            a = a_ref[k] + kp * (q_ref[k] - q) + kd * (v_ref[k] - v)
            tau = pin.rnea(model, data, q, v, a).copy()
            np.clip(tau, low, high, out=tau)
            sim.send(Command(CommandKind.TORQUE, tau))
            sim.sync()
            log_q[k], log_v[k], log_tau[k] = q, v, tau

    t = interleaved({"api": api, "hand": hand, "floor": hand_via_robot_api}, **TIMING)  # type: ignore[arg-type]
    return t["api"] / steps, t["hand"] / steps, t["floor"] / steps, steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cpu-time", action="store_true", help="Time in thread CPU time.")
    parser.add_argument("--repeats", type=int, default=9, help="Interleaved rounds (medians).")
    args = parser.parse_args()
    TIMING.update(timer=time.thread_time if args.cpu_time else time.perf_counter, repeats=args.repeats)
    rows = []
    api, hand, floor = g1_case(1000)
    rows.append(("G1 PD + gravity", api, hand, floor, 1000))
    api, hand, floor, steps = two_link_case()
    rows.append(("2-link computed torque", api, hand, floor, steps))
    print(f"{'case':<24} {'steps':>6} {'api [us]':>9} {'hand [us]':>10} {'ratio':>6} {'goal':>6}"
          f"        {'floor [us]':>10} {'floor ratio':>11}")
    for name, api, hand, floor, steps in rows:
        ratio = api / hand
        verdict = "ok    " if ratio <= GOALS[name] else "MISSED"
        print(f"{name:<24} {steps:>6d} {api * 1e6:>9.2f} {hand * 1e6:>10.2f} {ratio:>6.2f} "
              f"{GOALS[name]:>6.2f} {verdict} {floor * 1e6:>10.2f} {floor / hand:>11.2f}")
    load = os.getloadavg()
    print(f"{'thread CPU' if args.cpu_time else 'wall'} time, medians of {args.repeats} interleaved "
          f"rounds; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print("floor: the hand-written law with read_state / Command / send / sync of the robot API, "
          "i.e. the\nratio the robot API alone costs; api vs floor is what the controller and "
          "control.loop add.")


if __name__ == "__main__":
    main()
