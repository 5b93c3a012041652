"""The G1's low-level IO in Python, part by part, and g1-stand over DDS against the in-process run.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_dds.py [--seconds 30] [--estimator 30,60]
     python bench/bench_dds.py --wbc [stand,squat] [--wbc-seconds 10] [--runs 3]
     python bench/bench_dds.py --stalls 20 --default 60 [--runs 3]

1. Per message [us], medians, ours against Unitree's SDK path in the same run: LowCmd pack + CRC
   (numpy, zlib) vs the SDK's CRC helper (repacks in Python) + cyclonedds' serializer; LowState
   decode + CRC vs cyclonedds' deserializer + the SDK's CRC; one publish, raw bytes vs
   DataWriter.write; the estimator's update.
2. The estimator against the plant's truth, in-process: the whole-body controller standing 1 s
   then squatting (CoM 8 cm at 0.5 Hz), for each duration given (error max and drift at the end).
3. ``mbctl serve g1`` and ``mbctl g1-stand --interface dds`` as two processes on loopback for
   ``--seconds``: period p50/p99, deadline misses, messages lost, the truth checks, and the CoM
   (truth) against the in-process g1-stand of the same length.

``--stalls SECONDS`` instead measures where the client's waits for a state come from (issue 29):
g1-wbc stand in this process against a free-running bridge, ``--runs`` times with the quiet loop
off (collector on, normal priority) and on (no collection in the loop, real-time priority where
permitted): the waits between new states (p99, max: what the watchdog is compared with), the
cycle's CPU time, the collections inside the loop and their longest pause, the estimator's update,
the bridge's own longest period and misses. ``--default SECONDS`` runs ``mbctl g1-wbc stand
--interface dds --duration SECONDS`` with no other flag, ``--runs`` times: does it finish, and the
longest wait for a state.

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

from mbctl.hardware import WATCHDOG_PERIODS  # noqa: E402
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


def over_dds(domain: int, folder: Path, client: list[str], *serve: str,
             cpus: tuple[str, str] | None = None) -> subprocess.CompletedProcess:
    """``mbctl serve g1`` on ``domain`` (lo) into ``folder/serve`` while ``client`` (a job's arguments
    after ``--interface dds --domain D``, with ``--truth`` to its log) runs into ``folder/dds``;
    both processes end before this returns. ``cpus``: the bridge's and the client's ``mbctl --cpus``."""
    serve_dir = folder / "serve"
    pin_serve, pin_client = (["--cpus", cpus[0]], ["--cpus", cpus[1]]) if cpus else ([], [])
    bridge = subprocess.Popen(_mbctl(*pin_serve, "serve", "g1", "--domain", str(domain), "--idle-timeout",
                                     "60", "--output", str(serve_dir), "-q", *serve),
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        wait_until_serving(bridge)
        out = subprocess.run(_mbctl(*pin_client, *client, "--interface", "dds", "--domain", str(domain),
                                    "--truth", str(serve_dir / "truth.csv"), "--output",
                                    str(folder / "dds"), "-q"),
                             capture_output=True, text=True)
    finally:  # the client is done: stop the bridge (its idle timeout counts from its start)
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


#: What a stall measurement gives per run (the client's, then the bridge's).
_STALL_FIGURES = ("gap_p99_ms", "gap_max_ms", "period_max_ms", "work_cpu_p99_ms", "cpu_overruns",
                  "gc_in_loop", "gc_max_ms", "estimator_p99_us", "estimator_max_us",
                  "bridge_period_max_ms", "bridge_misses_pct")


def _client_in_process(domain: int, folder: Path, seconds: float, quiet: bool) -> dict[str, float]:
    """g1-wbc stand over DDS in this process, watchdog wide open, instrumented: gc pauses, estimator."""
    import gc
    import time
    from functools import partial

    from mbctl.control.estimation import LegKinematicsEstimator
    from mbctl.hardware import DdsOptions
    from mbctl.jobs import plant as plant_module
    from mbctl.jobs.g1_wbc import G1_WBC, WBCParams
    from mbctl.jobs.plant import PlantOptions
    from mbctl.jobs.runner import run_job

    pauses: list[tuple[float, float]] = []  # (when, how long) [s]
    started: dict[str, float] = {}

    def on_gc(phase: str, info: dict) -> None:
        if phase == "start":
            started["t"] = time.perf_counter()
        elif "t" in started:
            t = started.pop("t")
            pauses.append((t, time.perf_counter() - t))

    from mbctl.hardware.unitree_hg import UnitreeHG

    sync = UnitreeHG.sync
    window: list[float] = []

    def timed_sync(self):  # the loop's first and last cycle ends
        sync(self)
        window[len(window) > 0:] = [time.perf_counter()]

    update = LegKinematicsEstimator.update
    updates: list[float] = []

    def timed_update(self, reading):  # the estimator's cost, inside read_state
        t = time.perf_counter()
        out = update(self, reading)
        updates.append(time.perf_counter() - t)
        return out

    gc.callbacks.append(on_gc)
    LegKinematicsEstimator.update = timed_update
    UnitreeHG.sync = timed_sync
    plant_module.DdsOptions = partial(DdsOptions, quiet_loop=quiet)  # type: ignore[assignment]
    try:
        params = WBCParams("stand", seconds, plant=PlantOptions("dds", domain, watchdog_periods=10_000))
        record = run_job(G1_WBC, params, folder)
    finally:
        gc.callbacks.remove(on_gc)
        LegKinematicsEstimator.update = update
        UnitreeHG.sync = sync
        plant_module.DdsOptions = DdsOptions
    in_loop = [d for t, d in pauses if window and window[0] <= t <= window[-1]]
    v = record.values
    est = np.array(updates[-int(seconds * 500):]) * 1e6
    return {"status": record.status, "gap_p99_ms": v["state_gap_p99_ms"], "gap_max_ms": v["state_gap_max_ms"],
            "period_max_ms": v["period_max_ms"], "work_cpu_p99_ms": v["work_cpu_p99_ms"],
            "cpu_overruns": v["cpu_overruns"], "realtime": v["realtime"], "gc_in_loop": len(in_loop),
            "gc_max_ms": max(in_loop, default=0.0) * 1e3, "estimator_p99_us": float(np.percentile(est, 99)),
            "estimator_max_us": float(est.max())}


def stall_runs(seconds: float, runs: int, folder: Path) -> None:
    """Where the client's waits for a state come from: quiet loop off and on, a free-running bridge."""
    print(f"5. stalls: g1-wbc stand {seconds:g} s over DDS against `mbctl serve g1` (free-running), the "
          f"client in this process (watchdog open), {runs} runs each, quiet loop off (gc on, normal "
          "priority) and on (no gc in the loop, real-time priority where permitted)")
    for quiet in (False, True):
        got = []
        for run in range(runs):
            load = loadavg()
            with reserve_domain() as domain:
                serve_dir = folder / f"serve-{quiet}-{run}"
                serve = ("serve", "g1", "--start", "crouched", "--domain", str(domain), "--idle-timeout",
                         "60")
                bridge = subprocess.Popen(_mbctl(*serve, "--output", str(serve_dir), "-q"),
                                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                try:
                    wait_until_serving(bridge)
                    row = _client_in_process(domain, folder / f"wbc-{quiet}-{run}", seconds, quiet)
                finally:
                    bridge.send_signal(signal.SIGINT)
                    bridge.wait(timeout=30)
                    bridge.stderr.close()
            b = json.loads((serve_dir / "report.json").read_text())["values"]
            row.update(bridge_period_max_ms=b["period_max_ms"],
                       bridge_misses_pct=100 * b["deadline_misses"] / max(1, b["cycles"]))
            got.append(row)
            print(f"   quiet {'on ' if quiet else 'off'} run {run + 1} ({row['status']}, realtime "
                  f"{row['realtime']}, bridge realtime {b.get('realtime')}, load {load}): "
                  + ", ".join(f"{k} {row[k]:.3f}" for k in _STALL_FIGURES))
        print(f"   quiet {'on' if quiet else 'off'}: median [min, max] over {runs} runs")
        for key in _STALL_FIGURES:
            x = np.array([r[key] for r in got], dtype=float)
            print(f"     {key:22s} {np.median(x):9.3f}  [{x.min():.3f}, {x.max():.3f}]")


def default_runs(seconds: float, runs: int, folder: Path) -> None:
    """Issue 29's target: ``mbctl g1-wbc stand --interface dds --duration 60`` with no flags finishes."""
    print(f"6. the default: `mbctl g1-wbc stand --interface dds --duration {seconds:g}` with no other flag "
          f"against `mbctl serve g1 --start crouched`, {runs} runs")
    gaps = []
    for run in range(runs):
        load = loadavg()
        with reserve_domain() as domain:
            out = over_dds(domain, folder / f"default-{run}", ["g1-wbc", "stand", "--duration", str(seconds)],
                           "--start", "crouched")
        path = folder / f"default-{run}" / "dds" / "report.json"
        if not path.exists():
            print(f"   run {run + 1} (load {load}): exit {out.returncode}, no report: "
                  f"{out.stderr.strip()[-900:]}")
            continue
        report = json.loads(path.read_text())
        v = report["values"]
        gaps.append(v.get("state_gap_max_ms", float("nan")))
        print(f"   run {run + 1} (load {load}): exit {out.returncode}, {report['status']}"
              f"{': ' + report['message'][:160] if report['message'] else ''}; cycles {v.get('cycles')}, "
              f"watchdog {v.get('watchdog_events')}, state gap p99 "
              f"{v.get('state_gap_p99_ms', float('nan')):.2f} ms, max {gaps[-1]:.2f} ms, period max "
              f"{v.get('period_max_ms', float('nan')):.2f} ms, "
              f"realtime {v.get('realtime')}")
    x = np.array(gaps)
    print(f"   longest wait for a state: median {np.median(x):.2f} ms [{x.min():.2f}, {x.max():.2f}]")


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
    parser.add_argument("--watchdog-periods", type=int, default=WATCHDOG_PERIODS,
                        help="the DDS client's watchdog")
    parser.add_argument("--wbc", nargs="?", const="stand,squat", default=None,
                        help="only issue 20's targets: g1-wbc SCENARIOS (default stand,squat) over DDS")
    parser.add_argument("--wbc-seconds", type=float, default=10.0, help="g1-wbc run length (s)")
    parser.add_argument("--runs", type=int, default=3, help="g1-wbc runs over DDS per scenario")
    parser.add_argument("--stalls", type=float, default=None, metavar="SECONDS",
                        help="only: where the client's stalls come from, runs this long (quiet loop off/on)")
    parser.add_argument("--default", type=float, default=None, metavar="SECONDS",
                        help="only: g1-wbc stand over DDS with no flags, runs of this length (issue 29: 60)")
    args = parser.parse_args()
    print(f"load average before: {loadavg()} (2 cores, shared)")
    if args.stalls is not None or args.default is not None:
        with tempfile.TemporaryDirectory() as tmp:
            if args.stalls is not None:
                stall_runs(args.stalls, args.runs, Path(tmp))
            if args.default is not None:
                default_runs(args.default, args.runs, Path(tmp))
        print(f"load average after: {loadavg()}")
        return
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
