"""One controller object on two plants: the G1 in-process, then over Unitree's DDS against a bridge.

The whole-body controller of example 07 (``standing_controller``: CoM, pelvis and torso
orientation, posture, angular momentum) squats the torque-mode G1. It runs first on the in-process
simulator, then, unchanged, on ``UnitreeG1``: the robot API over the G1's low-level DDS
(``rt/lowstate`` in, ``rt/lowcmd`` out, 500 Hz of wall-clock time), against ``mbctl serve g1``,
the MuJoCo plant speaking the robot's messages, which this script starts on the loopback
interface (``lo``) with its own DDS domain and stops at the end. Over DDS the base position and
velocity are not measured; the leg-kinematics estimator gives them, as on the real robot.

Checked on each plant, not in the controller's model: in-process MuJoCo's CoM (``PlantMonitor``);
over DDS the bridge's ground truth (``truth.csv``: the CoM at each LowState the controller used,
matched by its ``tick``).

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/10_g1_over_dds.py
    python examples/10_g1_over_dds.py --duration 2 --domain 42

Needs the ``hardware`` extra (``pip install 'mbctl[hardware]'``). Exits 2 without the G1 model or
DDS, and 1 if the robot fell on either plant, the CoM RMS error exceeds 5 mm, or the link was lost.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from mbctl.control import run
from mbctl.control.estimation import LegKinematicsEstimator
from mbctl.control.wbc import Scheduled, Standing, foot_contact_from_model, standing_controller
from mbctl.hardware import WATCHDOG_PERIODS, DdsOptions, HardwareError, UnitreeG1
from mbctl.robots import ModelFileError, ModelNotFoundError, Robot, load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, G1_FALL, G1_IMU, KEYFRAME, PELVIS, TORSO, crouched_start
from mbctl.robots.interface import RobotInterface, RobotState
from mbctl.sim import Simulator
from mbctl.sim.dds_bridge import BridgeStartError, wait_until_serving
from mbctl.sim.monitor import PlantMonitor
from mbctl.unitree import ChannelError
from mbctl.unitree.channel import check_domain
from mbctl.unitree.domain_lock import reserve_domain

SQUAT_M, SQUAT_HZ = 0.03, 0.5  # CoM height = start - SQUAT_M (1 - cos(2 pi f t))
MAX_COM_RMS_M = 5e-3


def squat(plant: RobotInterface, standing: Standing, controller: Scheduled, duration_s: float,
          monitor: PlantMonitor | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Hold the feet where they stand and squat for ``duration_s`` on ``plant``.

    Returns:
        The CoM target (N, 3) [m] of each cycle and, with a ``monitor``, MuJoCo's CoM (N, 3) [m].
    """
    standing.hold(plant.read_state())  # contacts and targets where this plant's robot stands
    c0 = standing.com.target.copy()
    w = 2 * np.pi * SQUAT_HZ

    def schedule(t: float, state: RobotState) -> None:
        """The CoM target at t [s]: position [m], velocity [m/s], acceleration [m/s^2]."""
        a = SQUAT_M
        standing.com.set_target(c0 - [0, 0, a * (1 - np.cos(w * t))], [0, 0, -a * w * np.sin(w * t)],
                                [0, 0, -a * w * w * np.cos(w * t)])

    controller.schedule = schedule
    targets, com = [], []

    def record(k, state, reference, command) -> bool:
        targets.append(standing.com.target.copy())
        if monitor is not None:
            com.append(monitor.com_W.copy())
            return monitor.fall_reason is not None
        return False

    run(plant, controller, None, duration_s, on_step=record)
    return np.array(targets), np.array(com)


def start_bridge(domain: int, folder: Path, duration_s: float,
                 model_dir: str | None) -> subprocess.Popen[str]:
    """``mbctl serve g1`` on ``domain`` and ``lo``, crouched as the in-process start; returns once it serves.

    Raises:
        BridgeStartError: The bridge did not start (its message).
    """
    cmd = [sys.executable, "-m", "mbctl.cli", "serve", "g1", "--start", "crouched", "--domain", str(domain),
           "--network-interface", "lo", "--idle-timeout", "30", "--duration", str(duration_s + 90),
           "--output", str(folder), "-q"]
    if model_dir is not None:
        cmd += ["--model-dir", model_dir]
    bridge = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        wait_until_serving(bridge)  # killed if it has not served within BRIDGE_START_S
    except BridgeStartError:
        stop(bridge)
        raise
    return bridge


def stop(bridge: subprocess.Popen[str]) -> None:
    """Ctrl-C the bridge (its truth log is complete; it would stop 30 s after the last command)."""
    bridge.send_signal(signal.SIGINT)
    try:
        bridge.wait(timeout=10)
    except subprocess.TimeoutExpired:
        bridge.kill()
        bridge.wait()
    if bridge.stderr:
        bridge.stderr.close()


def truth_at(truth_csv: Path, ticks: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The bridge's true CoM (N, 3) [m] and pelvis height (N,) [m] at the LowStates with ``ticks``."""
    truth = np.genfromtxt(truth_csv, delimiter=",", names=True)
    rows = truth[np.searchsorted(truth["tick"], ticks)]
    return np.column_stack([rows["com_x_m"], rows["com_y_m"], rows["com_z_m"]]), rows["base_z_m"]


def estimator(robot: Robot, start_q: np.ndarray) -> LegKinematicsEstimator:
    """The leg-kinematics estimator on the soles' centres and the pelvis IMU, its W at the true start.

    On flat ground: each foot in contact measured at the ground's height, within 2 mm.
    """
    feet = {foot: foot_contact_from_model(robot, foot).points_F.mean(axis=0) for foot in FEET}
    return LegKinematicsEstimator(robot, feet, G1_IMU.site, start_xy_m=(float(start_q[0]), float(start_q[1])),
                                  ground_noise_m=0.002)


def rms_mm(com: np.ndarray, target: np.ndarray) -> float:
    """RMS [mm] of the CoM's distance to its target, (N, 3) each [m]."""
    return float(np.sqrt(np.mean(np.sum((com - target) ** 2, axis=1))) * 1e3)


def main() -> int:
    """Squat in-process, then over DDS; print both side by side; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=4.0, help="time on each plant [s]")
    parser.add_argument("--domain", type=int, default=None,
                        help="DDS domain id (1..232); default: a free one, reserved while the script runs")
    parser.add_argument("--watchdog-periods", type=int, default=WATCHDOG_PERIODS,
                        help="periods without a state before the link counts as lost")
    parser.add_argument("--model-dir", default=None, help="Menagerie unitree_g1 directory")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    try:
        if args.domain is not None:
            check_domain(args.domain)
        robot = position_to_motor(load_robot("g1", model_dir=args.model_dir))
    except (ModelNotFoundError, ModelFileError, ChannelError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    start_q = crouched_start(robot)
    standing = standing_controller(robot, FEET, PELVIS, TORSO)
    controller = Scheduled(standing.controller, lambda t, state: None)  # the one controller object

    # 1. In-process: the simulator is the plant; MuJoCo measures the CoM.
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(start_q, np.zeros(robot.nv))
    foot_geoms = {name: cs.contact.geoms for name, cs in standing.controller.contacts.items()}
    monitor = PlantMonitor(sim, foot_geoms, fall_rule=G1_FALL.reason).attach()
    target_sim, com_sim = squat(sim, standing, controller, args.duration, monitor)
    fell_sim = monitor.fall_reason

    # 2. Over DDS: the same controller object, against the bridge on loopback.
    domain_held = reserve_domain() if args.domain is None else nullcontext(args.domain)
    with domain_held as domain, tempfile.TemporaryDirectory() as tmp:
        try:
            bridge = start_bridge(domain, Path(tmp), args.duration, args.model_dir)
        except BridgeStartError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        lost = None
        try:
            options = DdsOptions(domain=domain, watchdog_periods=args.watchdog_periods)
            with UnitreeG1(robot, estimator(robot, start_q), options) as g1:
                try:
                    target_dds, _ = squat(g1, standing, controller, args.duration)
                except HardwareError as exc:  # link lost: the interface sent the damping command
                    lost = str(exc)
                report, ticks = g1.report(), g1.state_ticks  # the LowState each cycle used
        except (HardwareError, ChannelError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        finally:
            stop(bridge)
        if lost is not None:
            print(f"over DDS: {lost}")
            return 1
        com_dds, pelvis_z = truth_at(Path(tmp) / "truth.csv", ticks)
    fell_dds = bool((pelvis_z < G1_FALL.base_min_z_m).any())

    rms_sim, rms_dds = rms_mm(com_sim, target_sim), rms_mm(com_dds, target_dds)
    print(f"G1 squat, {SQUAT_M * 200:.0f} cm deep at {SQUAT_HZ:g} Hz, {args.duration:g} s on each plant, "
          "one controller object:")
    print(f"  {'':28s} {'in-process':>14s} {'over DDS (lo)':>16s}")
    print(f"  {'cycles':28s} {len(target_sim):14d} {len(target_dds):16d}")
    print(f"  {'CoM RMS error [mm]':28s} {rms_sim:14.2f} {rms_dds:16.2f}   "
          "(MuJoCo's CoM / the bridge's truth)")
    print(f"  {'period p50 / p99 [ms]':28s} {'2.000 / 2.000':>14s} "
          f"{report.timing.period_p50_ms:8.3f} / {report.timing.period_p99_ms:.3f}"
          "   (simulated / wall clock)")
    print(f"  {'deadline misses':28s} {'-':>14s} {report.timing.deadline_misses:16d}")
    print(f"  {'messages lost':28s} {'-':>14s} {report.link.states_lost:16d}")
    print(f"  {'fell':28s} {fell_sim or 'no':>14s} {'yes' if fell_dds else 'no':>16s}")
    print(f"  CoM RMS difference, DDS - in-process: {rms_dds - rms_sim:+.2f} mm; DDS domain {domain}")
    ok = not fell_sim and not fell_dds and max(rms_sim, rms_dds) < MAX_COM_RMS_M * 1e3
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
