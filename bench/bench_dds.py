"""The G1's low-level IO in Python, part by part, and g1-stand over DDS against the in-process run.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_dds.py [--seconds 30] [--estimator 30,60]

1. Per message [us], medians, ours against Unitree's SDK path in the same run: LowCmd pack + CRC
   (numpy, zlib) vs the SDK's CRC helper (repacks in Python) + cyclonedds' serializer; LowState
   decode + CRC vs cyclonedds' deserializer + the SDK's CRC; one publish, raw bytes vs
   DataWriter.write; the estimator's update.
2. The estimator against the plant's truth, in-process: the whole-body controller standing 1 s
   then squatting (CoM 8 cm at 0.5 Hz), for each duration given (error max and drift at the end).
3. ``mbctl serve g1`` and ``mbctl g1-stand --interface dds`` as two processes on loopback for
   ``--seconds``: period p50/p99, deadline misses, messages lost, the truth checks, and the CoM
   (truth) against the in-process g1-stand of the same length.

Everything on loopback (``lo``), on a domain derived from the pid. The machine has 2 cores shared
with other work: the load average is printed before and after; absolute figures are noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved  # noqa: E402

from mbctl.robots.unitree import TOPIC_LOWCMD, Channel, low_cmd_codec, low_state_codec  # noqa: E402
from mbctl.robots.unitree.channel import message_types  # noqa: E402


def loadavg() -> str:
    return Path("/proc/loadavg").read_text().split(" ", 3)[:3].__str__()


def io_parts(domain: int) -> None:
    from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_
    from unitree_sdk2py.utils.crc import CRC

    lowcmd_t, _ = message_types()
    rng = np.random.default_rng(0)
    cmd = low_cmd_codec()
    tau = rng.normal(size=29)
    sdk_cmd = lowcmd_t.deserialize(cmd.encode())
    state = low_state_codec()
    state.message["motor_state"]["q"] = rng.normal(size=35)
    wire_state = state.encode()
    sdk_crc = CRC()

    def ours_cmd():
        cmd.message["motor_cmd"]["tau"][:29] = tau
        return cmd.encode()

    def sdk_cmd_path():
        for i in range(29):  # as the SDK's examples fill a message
            sdk_cmd.motor_cmd[i].tau = float(tau[i])
        sdk_cmd.crc = sdk_crc.Crc(sdk_cmd)
        return sdk_cmd.serialize()

    def sdk_state_path():
        msg = LowState_.deserialize(wire_state)
        return sdk_crc.Crc(msg) == msg.crc

    with Channel(domain) as channel:
        writer = channel.writer(TOPIC_LOWCMD, lowcmd_t)
        from cyclonedds.pub import DataWriter

        public = DataWriter(channel._participant, channel._topic(TOPIC_LOWCMD, lowcmd_t))
        payload = cmd.encode()
        t = interleaved({
            "LowCmd pack+CRC, ours": ours_cmd,
            "LowCmd pack+CRC, SDK": sdk_cmd_path,
            "LowState decode+CRC, ours": lambda: state.decode(wire_state),
            "LowState decode+CRC, SDK": sdk_state_path,
            "publish raw bytes": lambda: writer.write(payload),
            "publish DataWriter.write": lambda: public.write(sdk_cmd),
        }, repeats=2001)
    print("1. per message (median us)")
    for name, s in t.items():
        print(f"   {name:28s} {s * 1e6:8.1f}")
    print(f"   ratios SDK/ours: LowCmd {t['LowCmd pack+CRC, SDK'] / t['LowCmd pack+CRC, ours']:.0f}x, "
          f"LowState {t['LowState decode+CRC, SDK'] / t['LowState decode+CRC, ours']:.0f}x, publish "
          f"{t['publish DataWriter.write'] / t['publish raw bytes']:.0f}x")


def estimator_runs(durations: list[float]) -> None:
    from mbctl.jobs.estimator_check import squat_check
    from mbctl.robots.edits import position_to_motor
    from mbctl.robots.g1 import with_palm_sites
    from mbctl.robots.registry import load_robot

    robot = position_to_motor(with_palm_sites(load_robot("g1")))
    print("2. estimator vs plant truth, in-process (whole-body squat, CoM 8 cm at 0.5 Hz after 1 s standing)")
    for seconds in durations:
        c = squat_check(robot, seconds)
        print(f"   {seconds:4.0f} s: position error max {c.position_error_max_m * 1e3:.2f} mm, at the end "
              f"{c.position_error_final_m * 1e3:.2f} mm (drift "
              f"{c.position_error_final_m / seconds * 1e3:.3f} mm/s); the plant's foot slid "
              f"{c.foot_slip_m * 1e3:.2f} mm; orientation error max "
              f"{c.orientation_error_max_deg:.2e} deg; base moved {c.base_z_range_m * 1e3:.0f} mm; update "
              f"{c.update_median_us:.0f} us median")


def _mbctl(*args: str) -> list[str]:
    return [sys.executable, "-m", "mbctl.cli", *args]


def _com_rms_mm(com: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((com - com[0]) ** 2, axis=1))) * 1e3)


def end_to_end(domain: int, seconds: float, folder: Path, watchdog: int) -> None:
    serve_dir, dds_dir, sim_dir = folder / "serve", folder / "dds", folder / "sim"
    bridge = subprocess.Popen(_mbctl("serve", "g1", "--domain", str(domain), "--idle-timeout", "1",
                                     "--output", str(serve_dir), "-q"), stderr=subprocess.PIPE, text=True)
    try:
        assert "serving" in bridge.stderr.readline()
        client = subprocess.run(_mbctl("g1-stand", "--interface", "dds", "--domain", str(domain),
                                       "--duration", str(seconds), "--watchdog-periods", str(watchdog),
                                       "--truth", str(serve_dir / "truth.csv"), "--output", str(dds_dir),
                                       "-q"),
                                capture_output=True, text=True)
        bridge.wait(timeout=30)
    finally:
        if bridge.poll() is None:
            bridge.send_signal(signal.SIGINT)
            bridge.wait(timeout=10)
    subprocess.run(_mbctl("g1-stand", "--duration", str(seconds), "--output", str(sim_dir), "-q"),
                   check=True, capture_output=True)
    report = json.loads((dds_dir / "report.json").read_text())
    v = report["values"]
    b = json.loads((serve_dir / "report.json").read_text())["values"]
    print(f"3. g1-stand {seconds:g} s over DDS on loopback, watchdog {watchdog} periods "
          f"(exit {client.returncode}, "
          f"{report['status']}{': ' + report['message'] if report['message'] else ''}):")
    if "cycles" not in v:
        return
    print(f"   client: {v['cycles']} cycles, period p50 {v['period_p50_ms']:.3f} ms, p99 "
          f"{v['period_p99_ms']:.3f} ms, max {v['period_max_ms']:.2f} ms; "
          f"deadline misses {v['deadline_misses']} "
          f"({100 * v['deadline_misses'] / max(1, v['cycles']):.2f} %); messages lost {v['messages_lost']}; "
          f"watchdog events {v['watchdog_events']}")
    print(f"   bridge: period p50 {b['period_p50_ms']:.3f} ms, p99 {b['period_p99_ms']:.3f} ms, "
          "deadline misses "
          f"{b['deadline_misses']} of {b['cycles']}; commands applied {b['commands_applied']} of "
          f"{b['commands_received']} received")
    if "truth_fell" in v:
        print(f"   truth: fell {v['truth_fell']}, pelvis max deviation "
              f"{v['truth_pelvis_max_deviation_m'] * 1e3:.2f} mm, "
              f"foot slip {v['truth_max_foot_slip_m'] * 1e3:.3f} mm; "
              f"estimator error max {v['estimator_position_error_max_m'] * 1e3:.2f} mm, final "
              f"{v['estimator_position_error_final_m'] * 1e3:.2f} mm, orientation "
              f"{v['estimator_orientation_error_max_deg']:.3f} deg")
        truth = np.genfromtxt(serve_dir / "truth.csv", delimiter=",", names=True)
        ran = truth[truth["commands_applied"] > 0]
        com_dds = np.column_stack([ran["com_x_m"], ran["com_y_m"], ran["com_z_m"]])
        com_sim = _sim_com(sim_dir)
        print(f"   CoM RMS from its start: DDS {_com_rms_mm(com_dds):.3f} mm (truth), in-process "
              f"{_com_rms_mm(com_sim):.3f} mm; "
              f"difference {abs(_com_rms_mm(com_dds) - _com_rms_mm(com_sim)):.3f} mm")


def _sim_com(run: Path) -> np.ndarray:
    """The robot's CoM [m] along an in-process run, from its trajectory.npz (Pinocchio on each q)."""
    from mbctl.robots.registry import load_robot

    model = load_robot("g1").pin_model
    data = model.createData()
    q = np.load(run / "trajectory.npz")["q"]
    return np.array([pin.centerOfMass(model, data, qk) for qk in q])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="g1-stand over DDS duration (s); 0 skips")
    parser.add_argument("--estimator", default="30,60", help="estimator run lengths (s), comma-separated")
    parser.add_argument("--watchdog-periods", type=int, default=3, help="the DDS client's watchdog")
    args = parser.parse_args()
    domain = 1 + (os.getpid() * 37) % 232
    print(f"load average before: {loadavg()} (2 cores, shared)")
    io_parts(domain)
    estimator_runs([float(x) for x in args.estimator.split(",") if x])
    if args.seconds > 0:
        with tempfile.TemporaryDirectory() as tmp:
            end_to_end(domain, args.seconds, Path(tmp), args.watchdog_periods)
    print(f"load average after: {loadavg()}")


if __name__ == "__main__":
    main()
