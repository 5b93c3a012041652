"""The G1's low-level IO in Python, part by part, and g1-stand over DDS against the in-process run.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_dds.py [--seconds 30] [--estimator 30,60]
     python bench/bench_dds.py --wbc [stand,squat] [--wbc-seconds 10] [--runs 3]

1. Per message [us], medians, ours against Unitree's SDK path in the same run: LowCmd pack + CRC
   (numpy, zlib) vs the SDK's CRC helper (repacks in Python) + cyclonedds' serializer; LowState
   decode + CRC vs cyclonedds' deserializer + the SDK's CRC; one publish, raw bytes vs
   DataWriter.write; the estimator's update.
2. The estimator against the plant's truth, in-process: the whole-body controller standing 1 s
   then squatting (CoM 8 cm at 0.5 Hz), for each duration given (error max and drift at the end).
3. ``mbctl serve g1`` and ``mbctl g1-stand --interface dds`` as two processes on loopback for
   ``--seconds``: period p50/p99, deadline misses, messages lost, the truth checks, and the CoM
   (truth) against the in-process g1-stand of the same length.

``--wbc [stand,squat]`` instead measures issue 20's targets: for each scenario ``--wbc-seconds``
(10 s) of ``mbctl g1-wbc SCENARIO --interface dds --truth ...`` against ``mbctl serve g1 --start
crouched`` (a fresh bridge and domain per run), ``--runs`` times, and the same scenario in-process
(deterministic: run once). Per scenario: deadline misses [% of cycles] and the cycles whose CPU
time alone overran (the rest of the misses waited for a core), the client's period p50 and p99,
its compute and IO p99 in wall and in CPU time, the bridge's own p99, misses and CPU time per
period, the CoM RMS over DDS (the bridge's truth log) and in-process, and their difference;
medians and [min, max] over the runs, with the load average at each run's start. Targets: misses
< 1 %, p99 < 2.5 ms, |CoM RMS difference| < 1 mm.

Everything on loopback (``lo``), on DDS domains reserved machine-wide while in use
(``mbctl.unitree.domain_lock``: a test run or another bench at the same time never shares
one). The machine has 2 cores shared with other work: the load average is printed before and
after; absolute figures are noisy.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved  # noqa: E402

from mbctl.sim.dds_bridge import wait_until_serving  # noqa: E402
from mbctl.unitree import TOPIC_LOWCMD, Channel, low_cmd_codec, low_state_codec  # noqa: E402
from mbctl.unitree.channel import message_types  # noqa: E402
from mbctl.unitree.domain_lock import reserve_domain  # noqa: E402


def loadavg() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split(" ", 3)[:3])


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


def over_dds(domain: int, folder: Path, client: list[str], *serve: str) -> subprocess.CompletedProcess:
    """``mbctl serve g1`` on ``domain`` (lo) into ``folder/serve`` while ``client`` (a job's arguments
    after ``--interface dds --domain D``, with ``--truth`` to its log) runs into ``folder/dds``;
    both processes end before this returns."""
    serve_dir = folder / "serve"
    bridge = subprocess.Popen(_mbctl("serve", "g1", "--domain", str(domain), "--idle-timeout", "1",
                                     "--output", str(serve_dir), "-q", *serve),
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        wait_until_serving(bridge)
        out = subprocess.run(_mbctl(*client, "--interface", "dds", "--domain", str(domain),
                                    "--truth", str(serve_dir / "truth.csv"), "--output",
                                    str(folder / "dds"), "-q"),
                             capture_output=True, text=True)
        bridge.wait(timeout=30)
    finally:
        if bridge.poll() is None:
            bridge.send_signal(signal.SIGINT)
            bridge.wait(timeout=10)
        bridge.stderr.close()
    return out


def end_to_end(domain: int, seconds: float, folder: Path, watchdog: int) -> None:
    serve_dir, dds_dir, sim_dir = folder / "serve", folder / "dds", folder / "sim"
    client = over_dds(domain, folder, ["g1-stand", "--duration", str(seconds), "--watchdog-periods",
                                       str(watchdog)])
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


#: What a g1-wbc run over DDS gives the table, from its report and the bridge's.
_WBC_FIGURES = ("misses_pct", "cpu_overruns_pct", "p50_ms", "p99_ms", "work_p99_ms", "work_cpu_p99_ms",
                "bridge_p99_ms", "bridge_misses_pct", "bridge_work_cpu_p99_ms", "com_dds_mm", "com_sim_mm",
                "com_diff_mm", "ctrl_sim_us", "ctrl_dds_us")


def wbc_runs(scenarios: list[str], seconds: float, runs: int, folder: Path, watchdog: int) -> None:
    """Issue 20's targets: g1-wbc over DDS against the bridge, ``runs`` times, and in-process once."""
    print(f"4. g1-wbc over DDS against `mbctl serve g1 --start crouched` on lo, {seconds:g} s, {runs} runs "
          f"each, watchdog {watchdog} periods (targets: misses < 1 %, p99 < 2.5 ms, CoM within 1 mm)")
    com_sim, ctrl_sim = {}, {}
    for scenario in scenarios:  # deterministic: once, before the timed runs
        out = folder / f"sim-{scenario}"
        subprocess.run(_mbctl("g1-wbc", scenario, "--duration", str(seconds), "--output", str(out), "-q"),
                       capture_output=True, check=False)
        values = json.loads((out / "report.json").read_text())["values"]
        com_sim[scenario] = values["com_error_rms_m"] * 1e3
        ctrl_sim[scenario] = values["controller_time_median_us"]
    rows: dict[str, list[dict[str, float]]] = {s: [] for s in scenarios}
    for run in range(runs):
        for scenario in scenarios:
            run_dir = folder / f"{scenario}-{run}"
            load = loadavg()
            job = ["g1-wbc", scenario, "--duration", str(seconds), "--watchdog-periods", str(watchdog)]
            with reserve_domain() as domain:  # a fresh domain for each bridge
                client = over_dds(domain, run_dir, job, "--start", "crouched")
            report = json.loads((run_dir / "dds" / "report.json").read_text())
            v = report["values"]
            b = json.loads((run_dir / "serve" / "report.json").read_text())["values"]
            if "cycles" not in v or v.get("com_error_source") != "truth log":
                print(f"   {scenario} run {run + 1}: exit {client.returncode}, {report['status']}: "
                      f"{report['message']} (load {load})")
                continue
            com_dds = v["com_error_rms_m"] * 1e3
            row = {"misses_pct": 100 * v["deadline_misses"] / v["cycles"],
                   "cpu_overruns_pct": 100 * v["cpu_overruns"] / v["cycles"], "p50_ms": v["period_p50_ms"],
                   "p99_ms": v["period_p99_ms"], "work_p99_ms": v["work_p99_ms"],
                   "work_cpu_p99_ms": v["work_cpu_p99_ms"], "bridge_p99_ms": b["period_p99_ms"],
                   "bridge_misses_pct": 100 * b["deadline_misses"] / max(1, b["cycles"]),
                   "bridge_work_cpu_p99_ms": b["work_cpu_p99_ms"],
                   "com_dds_mm": com_dds, "com_sim_mm": com_sim[scenario],
                   "com_diff_mm": com_dds - com_sim[scenario],
                   # the controller beside its plant in one process, and with the plant in another
                   "ctrl_sim_us": ctrl_sim[scenario], "ctrl_dds_us": v["controller_time_median_us"]}
            rows[scenario].append(row)
            print(f"   {scenario} run {run + 1} (exit {client.returncode}, load {load}): "
                  + ", ".join(f"{k} {row[k]:.3f}" for k in _WBC_FIGURES)
                  + f"; lost {v['messages_lost']}, watchdog {v['watchdog_events']}, fell {v['fell']}")
    for scenario, got in rows.items():
        if not got:
            continue
        print(f"   {scenario}: median [min, max] over {len(got)} runs")
        for key in _WBC_FIGURES:
            x = np.array([r[key] for r in got])
            print(f"     {key:18s} {np.median(x):8.3f}  [{x.min():.3f}, {x.max():.3f}]")


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
    parser.add_argument("--wbc", nargs="?", const="stand,squat", default=None,
                        help="only issue 20's targets: g1-wbc SCENARIOS (default stand,squat) over DDS")
    parser.add_argument("--wbc-seconds", type=float, default=10.0, help="g1-wbc run length (s)")
    parser.add_argument("--runs", type=int, default=3, help="g1-wbc runs over DDS per scenario")
    args = parser.parse_args()
    print(f"load average before: {loadavg()} (2 cores, shared)")
    if args.wbc is not None:
        with tempfile.TemporaryDirectory() as tmp:
            wbc_runs([s for s in args.wbc.split(",") if s], args.wbc_seconds, args.runs, Path(tmp),
                     args.watchdog_periods)
        print(f"load average after: {loadavg()}")
        return
    with reserve_domain() as domain:
        io_parts(domain)
    estimator_runs([float(x) for x in args.estimator.split(",") if x])
    if args.seconds > 0:
        with reserve_domain() as domain, tempfile.TemporaryDirectory() as tmp:
            end_to_end(domain, args.seconds, Path(tmp), args.watchdog_periods)
    print(f"load average after: {loadavg()}")


if __name__ == "__main__":
    main()
