"""The job runner: run folder, lock, streamed rows, report status in every case, exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np
import pytest

from mbctl.exceptions import ToolkitError
from mbctl.jobs.runner import (
    LOCK_NAME,
    Job,
    Outcome,
    OutputError,
    RunContext,
    check_output_dir,
    run_job,
)
from mbctl.robots.commands import Command, CommandKind
from mbctl.sim.exceptions import SimulationDiverged
from mbctl.sim.recorder import MAX_REPLAY_SAMPLES, BoundedTrajectoryRecorder, read_csv
from mbctl.sim.simulator import Simulator
from mbctl.sim.trajectory import load_trajectory


@dataclass(frozen=True)
class Params:
    rows: int = 5
    fail_at: int | None = None
    error: str = "toolkit"
    plot: bool = False


def _prepare(params: Params):
    def work(ctx: RunContext) -> Outcome:
        csv = ctx.open_csv(["time_s", "x_m"])
        for k in range(params.rows):
            if k == params.fail_at:
                raise {
                    "toolkit": lambda: ToolkitError("the QP is infeasible at k=3"),
                    "diverged": lambda: SimulationDiverged({"BADQACC": 1}, 0.006),
                    "interrupt": KeyboardInterrupt,
                    "bug": lambda: ZeroDivisionError("division by zero"),
                }[params.error]()
            csv.write([0.002 * k, float(k)])
            ctx.values["last_k"] = k
        if params.plot:
            from mbctl.jobs.plots import new_figure

            fig, _ = new_figure()
            ctx.save_figure(fig, "toy.png")
        return Outcome(passed=params.rows < 10, summary=(f"{params.rows} rows",), bound="rows < 10")

    return work


TOY = Job("toy", _prepare)


def _report(folder):
    return json.loads((folder / "report.json").read_text())


def test_completed_run_writes_rows_report_and_exit_0(tmp_path):
    record = run_job(TOY, Params(rows=5, plot=True), tmp_path)
    assert (record.status, record.exit_code, record.rows) == ("completed", 0, 5)
    assert sorted(os.listdir(tmp_path)) == ["report.json", "toy.csv", "toy.png"]
    report = _report(tmp_path)
    assert report["status"] == "completed" and report["passed"] is True
    assert report["rows"] == 5 and report["last_time_s"] == pytest.approx(0.008)
    assert report["outputs"] == {"csv": "toy.csv", "plot": "toy.png"}
    assert report["parameters"]["rows"] == 5
    for name in os.listdir(tmp_path):
        assert os.stat(tmp_path / name).st_mode & 0o777 == 0o644, name


def test_result_outside_its_bound_exits_1(tmp_path):
    record = run_job(TOY, Params(rows=12), tmp_path)
    assert (record.status, record.exit_code) == ("completed", 1)
    assert _report(tmp_path)["passed"] is False


def test_a_run_refused_a_pass_is_uncommanded_whatever_its_outcome(tmp_path):
    """The work ran to its end and "passed", but said its controller never acted: status says so, exit 1."""
    def prepare(params: Params):
        def work(ctx: RunContext) -> Outcome:
            ctx.open_csv(["time_s"]).write([0.0])
            ctx.refuse_pass("no command reached the plant")
            return Outcome(passed=True, summary=("stood",), bound="did not fall")
        return work

    record = run_job(Job("toy", prepare), Params(), tmp_path)
    assert (record.status, record.exit_code, record.rows) == ("uncommanded", 1, 1)
    report = _report(tmp_path)
    assert (report["status"], report["passed"], report["message"]) == (
        "uncommanded", False, "no command reached the plant")
    assert record.summary().startswith("NOT A PASS (uncommanded): no command reached the plant\nwrote 1 rows")


def test_a_long_run_keeps_a_bounded_replay_and_every_csv_row(tmp_path, two_link_torque):
    """2.2x MAX_REPLAY_SAMPLES steps: the replay keeps at most the cap, evenly spaced; the CSV every row."""
    steps = 220_000

    def prepare(params: Params):
        def work(ctx: RunContext) -> Outcome:
            sim = ctx.attach(Simulator(two_link_torque))
            csv = ctx.open_csv(["time_s"])
            for _ in range(steps):
                sim.step()
                csv.write([sim.time_s])
            return Outcome()
        return work

    record = run_job(Job("toy", prepare), Params(), tmp_path)
    assert record.rows == steps
    model, t, qpos, _ = load_trajectory(tmp_path)
    dt = model.opt.timestep
    assert len(t) == len(qpos) == 55_001 <= MAX_REPLAY_SAMPLES == 100_000  # every 4th step and the start
    assert t[0] == 0.0 and t[-1] == pytest.approx(steps * dt)
    np.testing.assert_allclose(np.diff(t), 4 * dt, rtol=1e-6)
    assert _report(tmp_path)["replay"] == {"samples": 55_001, "every_nth_update": 4, "updates": steps}


@pytest.mark.parametrize("block_rows", [3, 4096])
def test_the_replay_keeps_the_last_state_between_kept_steps(tmp_path, two_link_torque, monkeypatch,
                                                            block_rows):
    monkeypatch.setattr("mbctl.sim.trajectory.BLOCK_ROWS", block_rows)  # 3: samples across blocks
    sim = Simulator(two_link_torque)
    rec = BoundedTrajectoryRecorder(sim, tmp_path, max_samples=8).attach()
    sim.send(Command(CommandKind.TORQUE, np.array([0.3, -0.2])))
    seen = [sim.data.qpos.copy()]
    for _ in range(21):  # 8 samples reached at step 7 (stride 2), at step 14 (stride 4): 0, 4, 8, ... 20
        sim.step()
        seen.append(sim.data.qpos.copy())
    rec.close()
    t, qpos = load_trajectory(tmp_path)[1:3]
    np.testing.assert_allclose(t / sim.model.opt.timestep, [0, 4, 8, 12, 16, 20, 21], atol=1e-9)  # 21: end
    np.testing.assert_array_equal(qpos, np.array(seen)[[0, 4, 8, 12, 16, 20, 21]])  # each step's own state
    assert len(np.unique(qpos[:, 0])) == 7  # the arm moved: the rows are not one state repeated
    with pytest.raises(ValueError, match="max_samples must be >= 2"):
        BoundedTrajectoryRecorder(sim, tmp_path, max_samples=1)


@pytest.mark.parametrize(
    "error, status, code, message",
    [
        ("toolkit", "failed", 1, "the QP is infeasible at k=3"),
        ("diverged", "diverged", 1, "diverged near t=0.0060 s: MuJoCo raised BADQACC (x1)"),
        ("interrupt", "interrupted", 130, "interrupted"),
    ],
)
def test_a_run_that_stops_keeps_every_row_and_says_why(tmp_path, error, status, code, message):
    record = run_job(TOY, Params(rows=10, fail_at=3, error=error), tmp_path)
    assert (record.status, record.exit_code, record.rows) == (status, code, 3)
    report = _report(tmp_path)
    assert report["status"] == status and message in report["message"]
    assert report["values"] == {"last_k": 2}  # what was known before the stop
    data = read_csv(tmp_path / "toy.csv")
    assert list(data["x_m"]) == [0.0, 1.0, 2.0]
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".")]  # no temp or lock files
    if error == "interrupt":
        assert record.summary() == f"interrupted at t=0.004 s; wrote 3 rows to {tmp_path / 'toy.csv'}"


@dataclass(frozen=True)
class SumParams:
    rows: int = 6
    fail_at: int | None = None
    fill_fails: bool = False


def _summing(params: SumParams):
    """A job whose figure (the sum of every cycle's x) is computed from its log, not during the loop."""
    def work(ctx: RunContext) -> Outcome:
        xs: list[float] = []

        def fill() -> None:
            if params.fill_fails:
                raise ValueError("no cycles to sum")
            ctx.values["x_sum"] = sum(xs)
            ctx.values["fills"] = ctx.values.get("fills", 0) + 1

        ctx.values_at_end(fill)
        for k in range(params.rows):
            if k == params.fail_at:
                raise KeyboardInterrupt
            xs.append(float(k))
        fill()
        return Outcome(passed=True, summary=("summed",), bound="")

    return work


def test_an_interrupted_run_reports_the_figures_of_every_cycle_it_ran(tmp_path):
    record = run_job(Job("sums", _summing), SumParams(fail_at=4), tmp_path / "stopped")
    assert record.status == "interrupted" and record.values == {"x_sum": 0 + 1 + 2 + 3, "fills": 1}
    assert _report(tmp_path / "stopped")["values"] == {"x_sum": 6.0, "fills": 1}
    done = run_job(Job("sums", _summing), SumParams(), tmp_path / "done")
    assert done.values == {"x_sum": 15.0, "fills": 1}  # completed: the job's own fill, not once more
    failing = run_job(Job("sums", _summing), SumParams(fail_at=2, fill_fails=True), tmp_path / "bad")
    assert failing.status == "interrupted"
    assert failing.values == {"values_at_end_error": "ValueError: no cycles to sum"}  # named, report written


def test_a_bug_is_reported_then_raised(tmp_path):
    with pytest.raises(ZeroDivisionError):
        run_job(TOY, Params(rows=10, fail_at=2, error="bug"), tmp_path)
    report = _report(tmp_path)
    assert report["status"] == "failed" and "ZeroDivisionError" in report["message"]
    assert report["rows"] == 2


def test_no_file_of_an_earlier_run_survives(tmp_path):
    run_job(TOY, Params(rows=3, plot=True), tmp_path)
    (tmp_path / ".toy.csv.123.tmp").write_text("a dead process's temp file")
    run_job(TOY, Params(rows=2, plot=False), tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["report.json", "toy.csv"]  # the old plot is gone
    assert read_csv(tmp_path / "toy.csv")["x_m"].size == 2


def test_a_folder_that_holds_another_jobs_run_is_refused(tmp_path):
    """``mbctl identify RUN --output RUN`` deleted the excitation it read: a run replaces a run of
    its own job only; another job's run is refused before prepare, naming the folder and the job."""
    run_job(TOY, Params(rows=3, plot=True), tmp_path)
    before = {name: (tmp_path / name).read_bytes() for name in os.listdir(tmp_path)}
    calls = []
    other = Job("other", lambda p: calls.append(p))
    with pytest.raises(OutputError, match=f"output folder {tmp_path} holds a run of `mbctl toy` "
                                          r".*\(toy.csv, toy.png\); `mbctl other` would replace"):
        run_job(other, Params(), tmp_path)
    assert calls == [] and {name: (tmp_path / name).read_bytes() for name in os.listdir(tmp_path)} == before
    assert run_job(TOY, Params(rows=2), tmp_path).status == "completed"  # its own job replaces it


def test_cli_identify_into_its_excitation_folder_exits_2_and_keeps_the_log(tmp_path):
    run = tmp_path / "excite"
    run.mkdir()
    (run / "excite.csv").write_text("time_s\n0.0\n")
    (run / "report.json").write_text(json.dumps({"job": "excite", "status": "completed",
                                                 "output_sha256": {"excite.csv": "0" * 64}}))
    out = _cli("identify", str(run), "--output", str(run))
    assert out.returncode == 2, out.stdout + out.stderr
    assert f"output folder {run} holds a run of `mbctl excite`" in out.stderr
    assert "Traceback" not in out.stderr
    assert sorted(os.listdir(run)) == ["excite.csv", "report.json"]
    assert (run / "excite.csv").read_text() == "time_s\n0.0\n"


def test_a_second_run_into_a_held_folder_refuses(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (tmp_path / LOCK_NAME).write_text(str(holder.pid))
        with pytest.raises(OutputError, match=f"another mbctl run \\(pid {holder.pid}\\) is writing to"):
            run_job(TOY, Params(), tmp_path)
        assert sorted(os.listdir(tmp_path)) == [LOCK_NAME]  # nothing touched
    finally:
        holder.kill()
        holder.wait()
    # the holder is gone: its lock is stale and the next run takes it over
    assert run_job(TOY, Params(), tmp_path).status == "completed"
    assert not (tmp_path / LOCK_NAME).exists()


def test_unusable_output_is_refused_before_prepare(tmp_path):
    calls = []
    job = Job("toy", lambda p: calls.append(p))
    (tmp_path / "file").write_text("")
    with pytest.raises(OutputError, match="exists and is not a directory"):
        run_job(job, Params(), tmp_path / "file")
    with pytest.raises(OutputError, match="cannot write to output folder /proc/nonexistent"):
        run_job(job, Params(), "/proc/nonexistent/out")
    assert calls == []
    assert check_output_dir(tmp_path / "a" / "b").is_dir()


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mbctl.cli", *args], capture_output=True, text=True,
                          timeout=120)


def test_cli_bad_output_exits_2_with_one_line_before_any_work():
    out = _cli("xcheck", "two_link", "--json", "/proc/nonexistent/x.json")
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "/proc/nonexistent" in out.stderr
    assert "Traceback" not in out.stderr and out.stdout == ""


def test_cli_version():
    out = _cli("--version")
    assert out.returncode == 0 and out.stdout.startswith("mbctl 0.")


def test_rows_are_on_disk_while_the_run_goes_on(tmp_path):
    seen = {}

    def prepare(params):
        def work(ctx: RunContext) -> Outcome:
            csv = ctx.open_csv(["time_s", "x_m"])
            for k in range(3):
                csv.write([0.002 * k, float(k)])
            path, t0 = tmp_path / "toy.csv", time.monotonic()
            while path.read_text().count("\n") < 4 and time.monotonic() - t0 < 5.0:
                time.sleep(0.005)  # the work is still running: the flush thread writes the rows
            seen["lines"], seen["waited_s"] = path.read_text().splitlines(), time.monotonic() - t0
            return Outcome()

        return work

    assert run_job(Job("toy", prepare), None, tmp_path).status == "completed"
    assert seen["lines"] == ["time_s,x_m", "0.0,0.0", "0.002,1.0", "0.004,2.0"]
    assert seen["waited_s"] < 1.0  # flushed every 50 ms; 1 s of slack for a busy machine


def test_a_symlink_at_the_csv_path_exits_2_and_its_target_is_untouched(tmp_path):
    """The streamed CSV never follows a link planted at its path (issue 22)."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    folder = tmp_path / "D"
    folder.mkdir()
    (folder / "joint_step.csv").symlink_to("../victim.txt")
    out = _cli("joint-step", "two_link", "--joint", "shoulder", "--delta", "0.1", "--output", str(folder))
    assert out.returncode == 2, out.stderr
    assert victim.read_text() == "precious"
    assert "joint_step.csv is a symbolic link" in out.stderr and "Traceback" not in out.stderr
    assert sorted(os.listdir(folder)) == ["joint_step.csv"]  # refused before anything was written


def test_a_symlink_at_another_csv_the_work_opens_fails_the_run_with_exit_2(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "extra.csv").symlink_to(victim)

    def prepare(params):
        def work(ctx: RunContext) -> Outcome:
            ctx.open_csv(["time_s"]).write([0.0])
            ctx.open_csv(["time_s"], "extra.csv")
            return Outcome()

        return work

    record = run_job(Job("toy", prepare), None, folder)
    assert (record.status, record.exit_code, record.rows) == ("failed", 2, 1)
    assert "extra.csv is a symbolic link" in (record.message or "")
    assert victim.read_text() == "precious"


def _filmed(params: None):
    def work(ctx: RunContext) -> Outcome:
        from mbctl.jobs.plots import new_figure
        from mbctl.robots import load_robot, torque
        from mbctl.sim import Simulator

        sim = ctx.attach(Simulator(load_robot("two_link_torque")))
        for _ in range(30):
            sim.step(torque([1.0, 0.0]))
        fig, _ = new_figure()
        ctx.save_figure(fig, "toy.png")
        return Outcome()

    return work


def test_no_output_follows_a_symlink(tmp_path):
    from mbctl.sim.video import VideoSpec

    run, victims = tmp_path / "run", tmp_path / "victims"
    run.mkdir()
    victims.mkdir()
    names = ["report.json", "trajectory.npz", "model.xml", "video.mp4", "toy.png"]
    for name in names:
        (victims / name).write_text(f"the user's {name}")
        (run / name).symlink_to(victims / name)
    record = run_job(Job("toy", _filmed), None, run, video=VideoSpec(64, 48))
    assert record.status == "completed"
    for name in names:
        assert (victims / name).read_text() == f"the user's {name}", name
        assert not (run / name).is_symlink() and (run / name).stat().st_size > 0, name
    assert (run / "video.mp4").read_bytes()[4:8] == b"ftyp"  # the run's own MP4 replaced the link


def test_a_directory_in_place_of_an_output_is_refused_before_the_run(tmp_path):
    from mbctl.sim.video import VideoSpec

    calls = []
    job = Job("toy", lambda p: calls.append(p))
    (tmp_path / "video.mp4").mkdir()
    with pytest.raises(OutputError, match="video.mp4 is a directory where this run writes a file"):
        run_job(job, Params(), tmp_path, video=VideoSpec(64, 48))
    assert calls == [] and sorted(os.listdir(tmp_path)) == ["video.mp4"]
    out = _cli("demo", "--duration", "0.1", "--video", "--output", str(tmp_path), "--quiet")
    assert out.returncode == 2 and "video.mp4 is a directory" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and sorted(os.listdir(tmp_path)) == ["video.mp4"]


def test_a_forged_or_stale_report_removes_no_user_file(tmp_path):
    from mbctl.robots.menagerie import sha256_file

    run_job(TOY, Params(rows=3, plot=True), tmp_path)
    report = _report(tmp_path)
    assert set(report["output_sha256"]) == {"toy.csv", "toy.png"}
    assert report["output_sha256"]["toy.csv"] == sha256_file(tmp_path / "toy.csv")
    outside, victim = tmp_path.parent / f"{tmp_path.name}-outside.txt", tmp_path / "victim.txt"
    outside.write_text("outside")
    victim.write_text("the user's notes")
    (tmp_path / "notes.txt").write_text("the user's notes")
    (tmp_path / "link.txt").symlink_to(victim)
    (tmp_path / "toy.png").write_text("edited by the user since the run")  # stale entry
    digest = sha256_file(victim)
    report["outputs"].update(notes="notes.txt", link="link.txt", out=f"../{outside.name}",
                             victim="victim.txt")
    report["output_sha256"].update({"notes.txt": "0" * 64, "link.txt": digest,
                                    f"../{outside.name}": sha256_file(outside), "/etc/passwd": "0" * 64})
    (tmp_path / "report.json").write_text(json.dumps(report))
    run_job(TOY, Params(rows=2), tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["link.txt", "notes.txt", "report.json", "toy.csv", "toy.png",
                                           "victim.txt"]
    assert victim.read_text() == "the user's notes" and outside.read_text() == "outside"
    assert (tmp_path / "toy.png").read_text() == "edited by the user since the run"


def test_a_report_that_is_a_symlink_is_not_read(tmp_path):
    from mbctl.robots.menagerie import sha256_file

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "data.txt").write_text("the user's data")
    digest = sha256_file(tmp_path / "run" / "data.txt")
    (elsewhere / "report.json").write_text(json.dumps(
        {"outputs": {"csv": "data.txt"}, "output_sha256": {"data.txt": digest}}))
    (tmp_path / "run" / "report.json").symlink_to(elsewhere / "report.json")
    run_job(TOY, Params(rows=2), tmp_path / "run")
    assert (tmp_path / "run" / "data.txt").read_text() == "the user's data"
    assert (elsewhere / "report.json").exists() and not (tmp_path / "run" / "report.json").is_symlink()
