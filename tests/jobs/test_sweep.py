"""mbctl sweep on a small local Dask cluster: rows, failures, resume, single-run equality, plot."""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dask.distributed")

from mbctl.jobs import options  # noqa: E402
from mbctl.jobs.catalog import CATALOG, SweepInputError, parse_grid  # noqa: E402
from mbctl.jobs.demo import DEMO  # noqa: E402
from mbctl.jobs.runner import Progress, run_job  # noqa: E402
from mbctl.jobs.sweep import SweepConfig, run_sweep  # noqa: E402
from mbctl.jobs.sweep_cluster import SweepSetupError, open_client  # noqa: E402

DURATION = "0.1"


@pytest.fixture
def client(dask_client):
    return dask_client


def read_rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        return list(reader.fieldnames or []), list(reader)


def demo_sweep(tmp_path: Path, *params: str, resume: bool = False) -> SweepConfig:
    grid = parse_grid("demo", [f"duration={DURATION}", *params])
    return SweepConfig("demo", grid, tmp_path / "sweep", resume=resume)


def test_csv_columns_rows_json_and_plot(client, tmp_path):
    t0 = time.perf_counter()
    result = run_sweep(demo_sweep(tmp_path, "model_error=0,10", "controller=ct,pd"), client=client)
    elapsed_s = time.perf_counter() - t0
    assert result.status == "completed" and result.exit_code == 0
    header, rows = read_rows(result.files["csv"])
    assert header[:3] == ["duration", "model_error", "controller"]
    assert header[-4:] == ["status", "exit_code", "error", "run_dir"]
    assert "rms_error_m" in header and "max_error_m" in header
    assert [(r["model_error"], r["controller"]) for r in rows] == [
        ("0.0", "ct"), ("0.0", "pd"), ("10.0", "ct"), ("10.0", "pd")]
    assert all(r["status"] == "completed" and Path(r["run_dir"], "report.json").exists() for r in rows)
    assert Path(rows[0]["run_dir"]).name == "duration=0.1,model_error=0.0,controller=ct"
    meta = json.loads(result.files["json"].read_text())
    assert {"mbctl", "dask", "mujoco", "pin"} <= set(meta["versions"])
    assert meta["cluster"]["workers"] == 2 and meta["cluster"]["threads"] == 2
    assert meta["failures"] == []
    # the sweep's wall time spans its tasks: no shorter than the longest task, nor than the tasks'
    # total shared by the 2 one-thread workers, and no longer than the call that ran it
    task_s = [json.loads(Path(r["run_dir"], "report.json").read_text())["wall_time_s"] for r in rows]
    assert max(task_s) <= meta["wall_time_s"] <= elapsed_s
    assert sum(task_s) / 2 <= meta["wall_time_s"]
    assert result.files["plot"].stat().st_size > 1000


def test_row_equals_the_job_run_alone(client, tmp_path):
    config = demo_sweep(tmp_path, "model_error=0,15")
    result = run_sweep(SweepConfig("demo", config.grid, config.output_dir, metric="rms_eror"), client=client)
    assert "plot" not in result.files
    assert "its values: controller, model_error_pct, rms_error_m" in (result.note or "")
    for row in result.rows:
        alone = run_job(DEMO, options.demo(duration=float(DURATION), model_error=float(row["model_error"])),
                        tmp_path / f"alone{row['model_error']}")
        for key, value in alone.values.items():
            expected = json.dumps(value) if isinstance(value, dict) else str(value)
            assert row[key] == expected, key  # exact: the demo is deterministic


def test_failed_task_is_a_row_and_resume_reruns_only_it(client, tmp_path):
    # a 0.9 m square leaves the arm's workspace: the task fails in prepare, the sweep goes on
    result = run_sweep(demo_sweep(tmp_path, "side=0.2,0.9"), client=client)
    assert result.status == "completed" and result.exit_code == 1
    by_side = {r["side"]: r for r in result.rows}
    assert by_side["0.2"]["status"] == "completed"
    assert by_side["0.9"]["status"] == "failed" and "InvalidPlanningInput" in by_side["0.9"]["error"]
    assert json.loads(result.files["json"].read_text())["failures"][0]["side"] == "0.9"
    again = run_sweep(demo_sweep(tmp_path, "side=0.2,0.9", resume=True), client=client)
    assert (again.ran, again.skipped) == (1, 1)
    assert [r["side"] for r in read_rows(again.files["csv"])[1]] == ["0.2", "0.9"]


@pytest.mark.parametrize("cut", ["in run_dir", "in the values", "status edited"])
def test_resume_runs_a_torn_row_again(client, tmp_path, cut):
    config = demo_sweep(tmp_path, "model_error=0,5")
    run_sweep(config, client=client)
    path = config.output_dir / "sweep.csv"
    text = path.read_text()
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    torn = {"in run_dir": last[:-12], "in the values": last[:len(last) // 3],
            "status edited": last.replace(",completed,", ",diverged,")}[cut]
    path.write_text(text.replace(last, torn))
    again = run_sweep(SweepConfig("demo", config.grid, config.output_dir, resume=True), client=client)
    assert (again.ran, again.skipped, again.unsound) == (1, 1, 1)
    rows = read_rows(again.files["csv"])[1]
    assert [r["model_error"] for r in rows] == ["0.0", "5.0"]
    assert all(r["status"] == "completed" and Path(r["run_dir"], "report.json").exists() for r in rows)
    assert rows[1]["run_dir"] == str(config.output_dir / "runs" / "duration=0.1,model_error=5.0")


def test_resume_with_a_changed_grid_keeps_the_earlier_rows(client, tmp_path):
    run_sweep(demo_sweep(tmp_path, "model_error=0,5"), client=client)
    again = run_sweep(demo_sweep(tmp_path, "model_error=5,10", resume=True), client=client)
    assert (again.ran, again.skipped, len(again.earlier)) == (1, 1, 1)
    assert [r["model_error"] for r in again.rows] == ["5.0", "10.0"]
    rows = read_rows(again.files["csv"])[1]
    assert [r["model_error"] for r in rows] == ["5.0", "10.0", "0.0"]  # the earlier grid's row last
    assert json.loads(again.files["json"].read_text())["earlier_grid_rows"] == 1


def test_resume_with_other_parameters_is_refused(client, tmp_path):
    run_sweep(demo_sweep(tmp_path, "model_error=0"), client=client)
    with pytest.raises(SweepInputError, match="drop --resume"):
        run_sweep(demo_sweep(tmp_path, "omega=20", resume=True), client=client)


class InterruptAfterFirst(Progress):
    def advance(self, n: int = 1) -> None:
        raise KeyboardInterrupt


def test_ctrl_c_keeps_the_finished_rows(client, tmp_path):
    config = demo_sweep(tmp_path, "model_error=0,5,10")
    result = run_sweep(config, InterruptAfterFirst(), client=client)
    assert result.status == "interrupted" and result.exit_code == 130
    rows = read_rows(result.files["csv"])[1]
    assert len(rows) == 1 and rows[0]["status"] == "completed"
    assert json.loads(result.files["json"].read_text())["status"] == "interrupted"
    resumed = run_sweep(SweepConfig("demo", config.grid, config.output_dir, resume=True), client=client)
    assert (resumed.skipped, resumed.ran, len(resumed.rows)) == (1, 2, 3)


@pytest.mark.parametrize(("job", "params", "seeds", "message"), [
    ("dmeo", [], None, "unknown job 'dmeo'; a sweep runs one of: demo, joint-step"),
    ("demo", ["model_eror=1"], None, "demo has no option 'model_eror'; its options are: controller"),
    ("demo", ["model_error=five"], None, "model_error='five' is not a number"),
    ("demo", ["gravity=maybe"], None, "gravity='maybe' is not a boolean"),
    ("demo", [], 3, "demo has no randomness"),
    ("xcheck", ["states=3"], None, "xcheck needs robot: give --param robot=VALUE"),
    ("ik", ["robot=g1", "target=a"], None, "repeatable"),
    ("demo", ["model_error"], None, "NAME=V1,V2"),
])
def test_bad_input_names_the_value_and_the_allowed(job, params, seeds, message):
    with pytest.raises(SweepInputError, match=message.replace("(", r"\(")):
        parse_grid(job, params, seeds)


def test_a_value_the_job_rejects_fails_before_any_task(tmp_path):
    config = SweepConfig("demo", parse_grid("demo", ["controller=ct,nope"]), tmp_path / "s")
    with pytest.raises(SweepInputError, match="controller=nope"):
        run_sweep(config, client=object())  # never used: the check comes first
    assert not (tmp_path / "s").exists()


def test_seeds_add_a_seed_column_for_jobs_with_randomness():
    assert parse_grid("xcheck", ["robot=two_link", "states=2"], seeds=3)["seed"] == [0, 1, 2]
    assert [e for e in CATALOG if CATALOG[e].seeded] == ["xcheck"]


def test_missing_dask_says_how_to_install(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(SweepSetupError, match=r"pip install 'mbctl\[sweep\]'"):
        with open_client(SweepConfig("demo", {}, tmp_path)):
            pass


def test_plot_line_over_one_option_with_seeds_and_heat_map_over_two(tmp_path):
    from mbctl.jobs.sweep_plots import plot_sweep

    rows = [{"states": s, "seed": str(k), "err": str(0.1 * k + s)} for s in (1, 2, 3) for k in range(3)]
    assert plot_sweep(rows, ["states", "seed"], "err", "t", tmp_path / "line.png").stat().st_size > 1000
    heat = [{"impulse": i, "direction": d, "slip": str(i * d)} for i in (5, 10) for d in (0, 90)]
    assert plot_sweep(heat, ["impulse", "direction"], "slip", "t", tmp_path / "heat.png").exists()
    assert plot_sweep(rows[:1], ["states", "seed"], "err", "t", tmp_path / "none.png") is None
    assert plot_sweep(rows, ["states", "seed"], "missing", "t", tmp_path / "none.png") is None


def test_the_summary_says_which_rows_did_not_pass_and_why():
    from mbctl.jobs.sweep_table import TABLE_ROWS, metric_table, summary_lines

    rows = [{"model_error": "0.0", "rms_error_m": "0.000115", "status": "completed", "exit_code": "0",
             "error": ""},
            {"model_error": "10.0", "rms_error_m": "0.0242", "status": "completed", "exit_code": "1",
             "error": "outside its bound: RMS error <= 1 mm"},
            {"model_error": "50.0", "rms_error_m": "", "status": "diverged", "exit_code": "1",
             "error": "the plant diverged at t = 0.3 s (BADQACC)"}]
    assert summary_lines(rows[:1]) == []
    assert summary_lines(rows) == ["exit 1: 2 of 3 rows did not pass: 1 completed outside their bound, 1 "
                                   "not completed (failed, diverged or interrupted); the table says which "
                                   "and why"]
    assert metric_table(rows, ["model_error"], "rms_error_m") == [
        "rms_error_m by row:",
        "  model_error  rms_error_m  status     exit  why (not passed)",
        "  0            0.000115     completed  0",
        "  10           0.0242       completed  1     outside its bound: RMS error <= 1 mm",
        "  50           -            diverged   1     the plant diverged at t = 0.3 s (BADQACC)"]
    many = metric_table(rows * TABLE_ROWS, ["model_error"], "rms_error_m")
    assert len(many) == 2 + TABLE_ROWS + 1 and many[-1] == f"  ... {2 * TABLE_ROWS} more rows in sweep.csv"


def test_run_folder_names_are_safe_and_distinct():
    from mbctl.jobs.sweep import run_name

    assert run_name({"model_error": 5.0, "controller": "ct"}) == "model_error=5.0,controller=ct"
    a, b = run_name({"robot": "a/b.xml"}), run_name({"robot": "a_b.xml"})
    assert "/" not in a and a != b


@pytest.mark.parametrize("resume", [False, True])
def test_a_symlink_under_runs_is_refused_before_any_task(tmp_path, resume):
    from mbctl.jobs.runner import OutputError

    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "report.json").write_text("{}")
    (victim / "thesis.tex").write_text("years of work")
    config = demo_sweep(tmp_path, "model_error=0", resume=resume)
    (config.output_dir / "runs").mkdir(parents=True)
    (config.output_dir / "runs" / "duration=0.1,model_error=0.0").symlink_to(victim)
    with pytest.raises(OutputError, match="runs/duration=0.1,model_error=0.0 is a symbolic link; mbctl "
                                          "never writes through one"):
        run_sweep(config, client=object())  # never used: the check comes first
    assert sorted(p.name for p in victim.iterdir()) == ["report.json", "thesis.tex"]


def test_a_new_sweep_removes_only_what_its_runs_made(client, tmp_path):
    config = demo_sweep(tmp_path, "model_error=0")
    run_sweep(config, client=client)
    runs = config.output_dir / "runs"
    (runs / "mine").mkdir()
    (runs / "mine" / "report.json").write_text('{"outputs": {"a": "thesis.tex"}}')  # forged
    (runs / "mine" / "thesis.tex").write_text("years of work")
    (runs / "duration=0.1,model_error=0.0" / "notes.txt").write_text("the user's notes")
    run_sweep(demo_sweep(tmp_path, "model_error=5"), client=client)
    assert (runs / "mine" / "thesis.tex").read_text() == "years of work"
    assert sorted(p.name for p in (runs / "duration=0.1,model_error=0.0").iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in runs.iterdir()) == ["duration=0.1,model_error=0.0",
                                                      "duration=0.1,model_error=5.0", "mine"]


def test_plot_axes_read_in_the_users_units():
    """Options in the units the command line takes them in, report values in mm and %."""
    from mbctl.jobs.sweep_plots import sweep_figure

    rows = [{"model_error": str(m), "controller": c, "rms_error_m": str(e)}
            for m, c, e in [(0.0, "ct", 1e-4), (40.0, "ct", 4e-3), (0.0, "pd", 0.025), (40.0, "pd", 0.018)]]
    ax = sweep_figure(rows, ["model_error", "controller"], ["model_error", "controller"], "rms_error_m",
                      "t").axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("model error (%)", "controller")
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "40"]
    assert sorted(float(t.get_text()) for t in ax.texts) == [0.1, 4.0, 18.0, 25.0]  # mm in the cells
    assert ax.figure.axes[1].get_ylabel() == "rms error (mm)"  # the colour bar
    line = sweep_figure(rows[:2], ["model_error"], ["model_error"], "rms_error_m", "t").axes[0]
    assert line.get_ylabel() == "rms error (mm)"
    np.testing.assert_allclose(line.lines[0].get_ydata(), [0.1, 4.0])
    fell = [{"impulse": "5", "fell": "false"}, {"impulse": "5", "fell": "true"},
            {"impulse": "15", "fell": "true"}]
    ax = sweep_figure(fell, ["impulse"], ["impulse"], "fell", "t").axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("impulse (N s)", "fell (% of runs)")
    np.testing.assert_allclose(ax.lines[0].get_ydata(), [50.0, 100.0])
