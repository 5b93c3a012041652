"""The G1 jobs over DDS against ``mbctl serve g1``, as a user runs them: processes on loopback, exit codes.

Each test uses its own DDS domain on ``lo``; every process it starts is stopped before it ends.
These tests do not test timing (bench/bench_dds.py does): their bridge runs in lock-step
(``--lockstep``: one physics period per command), so a loaded machine slows them and does not
change their result.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from mbctl.control.loop import RunLog
from mbctl.jobs.truth import TruthLogError, check_truth_header, read_truth, stance_slips, truth_checks
from mbctl.sim.dds_bridge import TRUTH_COLUMNS, wait_until_serving
from mbctl.unitree import ChannelError
from mbctl.unitree.domain_lock import reserve_domain
from tests.conftest import mbctl_command, run_mbctl
from tests.hardware.unitree_sim_harness import LOCKSTEP_WATCHDOG_PERIODS, stop

#: The end-to-end runs' watchdog (lock-step: the bridge waits for the client; see the constant)
WATCHDOG = ("--watchdog-periods", str(LOCKSTEP_WATCHDOG_PERIODS))


mbctl = partial(run_mbctl, timeout=120)  # the shared runner with this file's 2-minute bound


@contextmanager
def bridge(domain: int, folder: Path, *extra: str):
    """``mbctl serve g1 --lockstep`` on ``domain`` (lo) until the block ends (Ctrl-C); yields it serving."""
    serve = ("serve", "g1", "--lockstep", "--domain", str(domain), "--idle-timeout", "60", "--duration",
             "180")
    proc = subprocess.Popen(mbctl_command(*serve, "--output", str(folder), "-q", *extra),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        wait_until_serving(proc)  # the "serving" line, once DDS is up (killed after 120 s without)
        yield proc
    finally:
        stop(proc)  # Ctrl-C, then kill


def test_g1_stand_over_dds_stands_and_checks_against_the_truth(g1, dds_domain, tmp_path):
    serve_dir, run_dir = tmp_path / "serve", tmp_path / "stand"
    with bridge(dds_domain, serve_dir):
        out = mbctl("g1-stand", "--interface", "dds", "--domain", str(dds_domain), "--duration", "1.5",
                    *WATCHDOG, "--truth", str(serve_dir / "truth.csv"), "--output", str(run_dir), "-q")
        assert out.returncode == 0, out.stdout + out.stderr
    values = json.loads((run_dir / "report.json").read_text())["values"]
    assert values["interface"] == "dds" and values["cycles"] == 750 and values["state_rate_hz"] == 500.0
    assert values["state_order"] == "tick" and values["messages_lost"] == 0
    assert values["watchdog_events"] == 0 and values["bad_crc"] == 0
    assert values["truth_fell"] is False and values["truth_pelvis_max_deviation_m"] < 0.02
    assert values["estimator_position_error_max_m"] < 5e-3
    assert values["estimator_orientation_error_max_deg"] < 0.5
    served = json.loads((serve_dir / "report.json").read_text())
    assert served["status"] == "interrupted" and served["values"]["lockstep"] is True  # stopped by the test
    assert served["values"]["commands_applied"] > 750 and served["values"]["bad_crc"] == 0
    assert "dds: 750 cycles" in out.stdout and "truth: pelvis max deviation" in out.stdout
    assert values["controller_acted"] is True and values["truth_commands_applied"] >= 749  # bridge's count
    # a second bridge restarts the ticks: the first one's log is another run's, refused (exit 2)
    with bridge(dds_domain, tmp_path / "serve2"):
        out = mbctl("g1-stand", "--interface", "dds", "--domain", str(dds_domain), "--duration", "0.2",
                    *WATCHDOG, "--truth", str(serve_dir / "truth.csv"), "--output", str(tmp_path / "other"),
                    "-q")
    assert out.returncode == 2, out.stdout + out.stderr
    assert "give the truth.csv of the bridge this run talked to" in out.stderr  # its ticks, or when it ran
    assert json.loads((tmp_path / "other" / "report.json").read_text())["status"] == "failed"


def test_g1_wbc_over_dds_holds_the_com_checked_against_the_truth(g1, dds_domain, tmp_path):
    """The whole-body QP on the bridge's crouched G1: the CoM RMS comes from the plant's truth log.

    Started as the README pastes it: the client first, its truth log not there yet (the bridge
    writes it once it serves), waiting for the robot."""
    serve_dir, run_dir = tmp_path / "serve", tmp_path / "wbc"
    client = subprocess.Popen(mbctl_command(
        "g1-wbc", "stand", "--interface", "dds", "--domain", str(dds_domain), "--duration", "1.5", *WATCHDOG,
        "--wait-s", "120", "--truth", str(serve_dir / "truth.csv"), "--output", str(run_dir), "-q"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        with bridge(dds_domain, serve_dir, "--start", "crouched"):
            stdout, stderr = client.communicate(timeout=120)
    finally:
        stop(client)
    values = json.loads((run_dir / "report.json").read_text())["values"]
    assert client.returncode == 0, stdout + stderr + json.dumps(values)
    assert "waiting up to 120 s for the robot's state" in stderr
    assert values["com_error_source"] == "truth log" and values["cycles"] == 750
    # the truth CoM in the estimator's frame (x, y from its start): millimetres, not the start offset
    assert values["com_error_rms_m"] < 5e-3 and values["fell"] is False
    assert values["truth_max_foot_slip_m"] < 1e-3 and values["estimator_position_error_max_m"] < 5e-3
    assert values["contact_force_rel_error"] is None  # no MuJoCo contact forces over DDS


def test_lockstep_gives_the_same_run_twice(g1, tmp_path):
    """Two g1-wbc runs over DDS against lock-step bridges: the same CoM RMS (truth log), however loaded."""
    com_rms = []
    for k in range(2):
        serve_dir, run_dir = tmp_path / f"serve{k}", tmp_path / f"wbc{k}"
        with reserve_domain() as domain, bridge(domain, serve_dir, "--start", "crouched"):
            out = mbctl("g1-wbc", "stand", "--interface", "dds", "--domain", str(domain), "--duration", "1",
                        *WATCHDOG, "--truth", str(serve_dir / "truth.csv"), "--output", str(run_dir), "-q")
        assert out.returncode == 0, out.stdout + out.stderr
        values = json.loads((run_dir / "report.json").read_text())["values"]
        assert values["com_error_source"] == "truth log" and values["cycles"] == 500
        com_rms.append(values["com_error_rms_m"])
    assert com_rms[0] > 1e-4  # a real figure (it stood with an error)
    assert com_rms[1] == pytest.approx(com_rms[0], rel=0, abs=1e-6)


def _truth_log(path: Path, ticks: range, unix_s: float) -> Path:
    """A truth log of a robot standing still at the origin, its rows made from ``unix_s`` on, 2 ms apart."""
    rows = []
    for k, tick in enumerate(ticks):
        row = dict.fromkeys(TRUTH_COLUMNS, 0.0)
        row.update(tick=tick, unix_s=unix_s + 0.002 * k, base_z_m=0.79, base_qw=1.0, commands_applied=k)
        rows.append(",".join(repr(float(row[c])) for c in TRUTH_COLUMNS))
    path.write_text(",".join(TRUTH_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    return path


def test_a_truth_log_row_being_written_is_left_out_and_a_bad_whole_row_is_refused(tmp_path):
    """A running bridge's last row may be half written when the client reads (CI saw it once)."""
    path = _truth_log(tmp_path / "truth.csv", range(5), 1_800_000_000.0)
    whole = path.read_text()
    path.write_text(whole + "5,0.0")  # the sixth row, cut mid-write
    assert read_truth(path)["tick"].tolist() == [0, 1, 2, 3, 4]
    path.write_text(whole + "5,0.0\n")
    with pytest.raises(TruthLogError, match="got 2 columns instead of 26"):
        read_truth(path)


def test_a_truth_log_made_outside_the_runs_loop_is_another_runs(tmp_path):
    """Ticks 10..19 are in both logs; only the one made while the loop ran is this run's."""
    q = np.zeros((10, 7))
    q[:, 2], q[:, 6] = 0.79, 1.0
    log = RunLog(np.arange(10) * 0.002, q, np.zeros((10, 6)), np.zeros((10, 1)), np.zeros((10, 1)),
                 np.zeros((10, 1)), 0.02, np.arange(10, 20))
    loop = (1_800_000_000.0, 1_800_000_000.02)  # 2027-01-15 08:00:00 UTC, for 20 ms
    ours = _truth_log(tmp_path / "ours.csv", range(100), loop[0] - 0.02)
    values = truth_checks(ours, log.tick, log, 0.5, loop)
    assert values["truth_pelvis_max_deviation_m"] == 0.0 and values["truth_commands_applied"] == 9
    earlier = _truth_log(tmp_path / "earlier.csv", range(100), loop[0] - 60.0)  # a minute before
    with pytest.raises(TruthLogError) as err:
        truth_checks(earlier, log.tick, log, 0.5, loop)
    assert str(err.value) == (
        f"{earlier} is another run's truth log: its rows for this run's LowState ticks 10..19 were made "
        "2027-01-15 07:59:00.020 to 2027-01-15 07:59:00.038 UTC, but this run's control loop ran "
        "2027-01-15 08:00:00.000 to 2027-01-15 08:00:00.020 UTC (ticks restart with every bridge); give the "
        "truth.csv of the bridge this run talked to (its clock within 1 s of this machine's)")
    (tmp_path / "old.csv").write_text("tick,time_s,wall_s,commands_applied\n1,0,0,0\n")  # no unix_s
    with pytest.raises(TruthLogError, match="is not a truth log of this mbctl"):
        check_truth_header(tmp_path / "old.csv")


def test_each_stance_slip_is_the_foot_drifting_from_where_it_was_before_it_was_loaded():
    """Left: loaded rows 0-4 (from the first row's place), lifted 5-7 (moved 0.3 m), loaded 8-12 from
    row 7's place; right: loaded throughout. 100 N each at the start: 20 N supports."""
    w = np.zeros(13, dtype=[(c, float) for c in TRUTH_COLUMNS])
    w["right_foot_fz_N"] = 100.0
    w["left_foot_fz_N"] = [100.0] * 5 + [19.9] * 3 + [20.0] * 5
    w["left_foot_x_m"][:5] = np.arange(5) * 1e-3  # drifts 4 mm
    w["left_foot_x_m"][5:] = 0.3
    w["left_foot_y_m"][8:] = [0.0, 3e-3, 1e-3, -2e-3, 0.0]  # 3 mm from row 7's place
    w["right_foot_y_m"] = np.linspace(0.0, -1e-3, 13)  # 1 mm over the run
    np.testing.assert_allclose(stance_slips(w), [4e-3, 3e-3, 1e-3], rtol=0, atol=1e-15)
    w["left_foot_fz_N"], w["right_foot_fz_N"] = 0.0, 0.0  # no weight: every row supports (>= 0)
    np.testing.assert_allclose(stance_slips(w[5:8]), [0.0, 2e-3 / 12], rtol=0, atol=1e-15)
    w["right_foot_fz_N"][0] = 1.0
    assert stance_slips(w[:1]).tolist() == [0.0]  # the left foot never carries 10 %: no stance


def test_g1_walk_over_dds_walks_with_its_slips_from_the_truth_log(g1, dds_domain, tmp_path):
    """The walking controller over DDS, the estimator in the loop: the report's foot slips are each
    stance's from the bridge's truth log (the plant is not observed over DDS), the fall verdict and
    the distance the truth log's too."""
    serve_dir, run_dir = tmp_path / "serve", tmp_path / "walk"
    with bridge(dds_domain, serve_dir, "--start", "crouched"):
        out = mbctl("g1-walk", "forward", "--speed", "0.3", "--duration", "3", "--interface", "dds",
                    "--domain", str(dds_domain), *WATCHDOG, "--truth", str(serve_dir / "truth.csv"),
                    "--output", str(run_dir), "-q")
    report = json.loads((run_dir / "report.json").read_text())
    values = report["values"]
    # exit 1 by design: 3 s from standing cover 70 % of the command (the first step leaves at 0.8 s),
    # short of the 90 % a walk must; every other check passes (20 s walks: docs/api/walking.rst)
    assert out.returncode == 1 and report["passed"] is False, out.stdout + out.stderr + json.dumps(values)
    assert 0.6 < values["displacement_fraction"] < 0.9 and "median foot slip <= 5 mm" in report["bound"]
    assert values["fell"] is False and values["truth_fell"] is False and values["steps"] >= 3
    assert values["fall_source"] == "truth log" and values["fall_reason"] is None
    assert values["displacement_source"] == "truth log" and 0.4 < values["distance_m"] < 0.9
    assert values["foot_slip_source"] == "truth log"
    assert values["max_foot_slip_m"] == values["truth_max_foot_slip_m"] < 5e-3
    assert 0 < values["median_foot_slip_m"] == values["truth_median_foot_slip_m"] <= values["max_foot_slip_m"]
    assert "(truth log)" in out.stdout and values["estimator_drift_m_per_m"] < 0.02


def test_a_bridge_nobody_commands_idles_out_from_its_start(g1, dds_domain, tmp_path):
    out = mbctl("serve", "g1", "--domain", str(dds_domain), "--idle-timeout", "0.5", "--output",
                str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert "stopped (idle)" in out.stdout and "0 commands applied of 0 received" in out.stdout


def test_no_robot_exits_2_naming_domain_and_interface(g1, dds_domain, tmp_path):
    out = mbctl("g1-stand", "--interface", "dds", "--domain", str(dds_domain), "--output", str(tmp_path))
    assert out.returncode == 2, out.stderr
    assert f"DDS domain {dds_domain}" in out.stderr and "network interface 'lo'" in out.stderr
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "report.json").exists()  # nothing written before the robot answered


def test_ctrl_c_damps_and_exits_130(g1, dds_domain, tmp_path):
    serve_dir, run_dir = tmp_path / "serve", tmp_path / "stand"
    with bridge(dds_domain, serve_dir):
        client = subprocess.Popen(mbctl_command("g1-stand", "--interface", "dds", "--domain", str(dds_domain),
                                                "--duration", "30", *WATCHDOG, "--output", str(run_dir),
                                                "-q"),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not _running(run_dir):
                time.sleep(0.1)
            time.sleep(0.5)
            client.send_signal(signal.SIGINT)
            _, err = client.communicate(timeout=20)
        finally:
            if client.poll() is None:
                client.kill()
                client.wait()
    assert client.returncode == 130, err
    report = json.loads((run_dir / "report.json").read_text())
    assert report["status"] == "interrupted" and report["rows"] > 0


def _running(folder: Path) -> bool:
    try:
        return json.loads((folder / "report.json").read_text())["status"] == "running"
    except (OSError, ValueError, KeyError):
        return False


@pytest.mark.parametrize(("args", "message"), [
    (("g1-stand", "--interface", "dds", "--latency-ms", "5"), "give --latency-ms"),
    (("g1-stand", "--truth", "x.csv"), "--truth is an option of --interface dds; this run is in-process "
                                       "(--interface sim), where it would be ignored"),
    # a forgotten --interface dds: the DDS options are refused, never ignored while the job stands in-process
    (("g1-stand", "--domain", "7"), "--domain is an option of --interface dds"),
    (("g1-arm-pd", "--network-interface", "enp3s0", "--watchdog-periods", "10"),
     "--network-interface, --watchdog-periods are options of --interface dds"),
    (("g1-wbc", "stand", "--watchdog-periods", "3"), "--watchdog-periods is an option of --interface dds"),
    (("g1-arm-pd", "--interface", "can"), "interface must be one of sim, dds"),
    (("serve", "h1"), "speaks the G1's low-level messages only"),
    (("serve", "g1", "--lockstep", "--latency-ms", "2"), "--lockstep advances one period per command"),
    (("g1-stand", "--state-crc", "off", "--wait-s", "3"),
     "--state-crc, --wait-s are options of --interface dds"),
    (("g1-stand", "--interface", "dds", "--state-crc", "maybe"), "state_crc must be one of on, off"),
    (("g1-arm-pd", "--motor-gains", "as-given"), "--motor-gains is an option of --interface dds"),
    (("g1-arm-pd", "--interface", "dds", "--motor-gains", "loose"),
     "motor_gains must be one of stable, as-given; got 'loose'"),
    (("g1-wbc", "push", "--interface", "dds"), "the push scenario needs the in-process plant "
                                               "(--interface sim): over DDS nothing can push the robot"),
    (("g1-stand", "--interface", "dds", "--payload", "1@pelvis"), "--payload and --plant-error change the "
                                                                   "in-process plant"),
])
def test_bad_plant_options_exit_2(args, message, tmp_path):
    out = mbctl(*args, "--output", str(tmp_path))
    assert out.returncode == 2 and message in out.stderr, out.stderr


def test_in_process_link_reports_its_losses(g1, tmp_path):
    out = mbctl("g1-stand", "--duration", "0.4", "--drop", "0.1", "--estimate", "--output", str(tmp_path),
                "-q")
    assert out.returncode == 0, out.stderr
    values = json.loads((tmp_path / "report.json").read_text())["values"]
    assert values["interface"] == "sim" and values["states_lost"] > 0 and values["commands_lost"] > 0
    assert values["controller_acted"] is True and 0.8 < values["commanded_fraction"] < 1.0  # ~0.9


def test_a_run_its_latency_leaves_uncommanded_exits_2_or_1(g1, tmp_path):
    """A latency as long as the run is refused up front; commands all dropped: exit 1, not 'stood'."""
    out = mbctl("g1-stand", "--latency-ms", "1e9", "--output", str(tmp_path / "late"))
    assert out.returncode == 2 and "--latency-ms 1e+09 is not shorter than the run (10 s)" in out.stderr
    assert not (tmp_path / "late").exists()
    out = mbctl("g1-stand", "--duration", "0.2", "--drop", "0.999", "--output", str(tmp_path / "lost"), "-q")
    assert out.returncode == 1, out.stdout + out.stderr
    assert "NOT A PASS (uncommanded): the controller never acted" in out.stderr and "stood" not in out.stderr
    assert json.loads((tmp_path / "lost" / "report.json").read_text())["status"] == "uncommanded"


def test_a_reserved_domain_is_skipped_by_every_process_until_released():
    """Domains come from mbctl.unitree.domain_lock: a lock file each, so two test runs (or a
    test run and bench/bench_dds.py) at once never share one."""
    with reserve_domain() as first:
        with reserve_domain(first) as second:  # another reservation in this process
            assert second != first
        code = ("from mbctl.unitree.domain_lock import reserve_domain\n"
                f"with reserve_domain({first}) as d: print(d)")
        other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
        assert other.returncode == 0, other.stderr
        assert int(other.stdout) != first  # another process
    with reserve_domain(first) as again:  # released at the end of the block
        assert again == first
    with pytest.raises(ChannelError, match="0 is DDS's default domain"):
        with reserve_domain(0):
            pass


def test_truth_checks_of_a_decimated_log_leave_the_largest_estimator_errors_unchecked(tmp_path):
    """A log that kept every 4th of 10 cycles (and the last): the truth window is every cycle's."""
    q = np.zeros((4, 7))
    q[:, 2], q[:, 6] = 0.79, 1.0
    q[-1, 2] = 0.80  # the last cycle's estimate 10 mm high
    log = RunLog(np.arange(10) * 0.002, q, np.zeros((4, 6)), np.zeros((4, 1)), np.zeros((4, 1)),
                 np.zeros((4, 1)), 0.02, np.arange(10, 20), np.array([0, 4, 8, 9]), 4)
    loop = (1_800_000_000.0, 1_800_000_000.02)
    truth = _truth_log(tmp_path / "ours.csv", range(100), loop[0] - 0.02)
    values = truth_checks(truth, log.tick, log, 0.5, loop)
    assert values["truth_commands_applied"] == 9 and values["truth_rows"] == 10  # ticks 10..19: every cycle
    assert values["estimator_position_error_final_m"] == pytest.approx(0.01, abs=1e-12)
    assert values["estimator_position_error_max_m"] is None
    assert values["estimator_orientation_error_max_deg"] is None
    assert values["estimator_errors_over"] == (
        "not checked: the loop's log kept every 4th of 10 cycles (control.loop.MAX_LOG_ROWS); run shorter "
        "pieces to check them")
