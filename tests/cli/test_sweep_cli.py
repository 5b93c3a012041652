"""mbctl sweep from the command line, and the option names it shares with every job's command."""

from __future__ import annotations

import csv
import inspect
import typing
from functools import partial

import pytest

from mbctl.cli import _register_commands, app
from mbctl.jobs.catalog import CATALOG, _unwrap
from tests.conftest import run_mbctl

_register_commands()
COMMANDS = {c.name: c.callback for c in app.registered_commands}


mbctl = partial(run_mbctl, timeout=120)  # the shared runner with this file's 2-minute bound


@pytest.mark.parametrize("job", sorted(CATALOG))
def test_sweep_options_are_the_commands_options(job):
    """Names, order, defaults and types of the command equal those of jobs/options (no drift)."""
    command = inspect.signature(COMMANDS[job], eval_str=True).parameters
    cli = {n: p for n, p in command.items() if n not in ("output", "quiet", "video", "video_size")}
    build = CATALOG[job].build
    hints = typing.get_type_hints(build)
    built = inspect.signature(build).parameters
    assert list(cli) == list(built)
    for name, param in cli.items():
        assert param.default == built[name].default, name
        assert _unwrap(param.annotation.__origin__) == _unwrap(hints[name]), name


def test_unknown_option_exits_2_naming_the_allowed_names(tmp_path):
    out = mbctl("sweep", "demo", "--param", "model_eror=1,2", "--output", str(tmp_path / "s"))
    assert out.returncode == 2
    assert "demo has no option 'model_eror'; its options are: controller, compare, model_error" in out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "s").exists()


def test_sweep_on_an_existing_scheduler(dask_client, tmp_path):
    out = mbctl("sweep", "demo", "--param", "duration=0.1", "--param", "model_error=0,5",
                "--scheduler", dask_client.scheduler.address, "--output", str(tmp_path / "s"), "--quiet")
    assert out.returncode == 0, out.stderr
    assert "2 rows (2 run, 0 kept)" in out.stdout
    with (tmp_path / "s" / "sweep.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["model_error"] for r in rows] == ["0.0", "5.0"]
    assert (tmp_path / "s" / "sweep.png").exists()


def test_a_sweep_that_exits_1_says_which_rows_and_why_with_the_metric_table(dask_client, tmp_path):
    """Every row of this IK sweep completes outside its bound (the CoM of the arm cannot reach
    (0.3, 0.3)): the sweep exits 1, and used to say only "0 not completed"."""
    out = mbctl("sweep", "ik", "--param", "robot=two_link", "--param", "com=0.3,0.3;0.05,0", "--param",
                "tol=1e-3", "--scheduler", dask_client.scheduler.address, "--output", str(tmp_path / "s"),
                "--quiet")
    assert out.returncode == 1, out.stdout + out.stderr
    text = out.stdout + out.stderr
    assert "exit 1: 2 of 2 rows did not pass: 2 completed outside their bound, 0 not completed" in text
    assert "max_plant_residual_m by row:" in text
    table = text[text.index("max_plant_residual_m by row:"):].splitlines()
    assert table[1].split() == ["robot", "com", "tol", "max_plant_residual_m", "status", "exit", "why",
                                "(not", "passed)"]
    bound = "outside its bound: every IK and plant (MuJoCo) residual within 0.001 m and 0.01 rad"
    assert table[2].startswith("  two_link  0.3,0.3") and table[2].endswith(bound)
    assert table[2].split()[3:6] == ["0.213", "completed", "1"]  # the CoM 0.213 m from its target
    with (tmp_path / "s" / "sweep.csv").open() as f:
        assert [r["error"] for r in csv.DictReader(f)] == [bound, bound]


def test_a_symlink_under_runs_exits_2(tmp_path):
    (tmp_path / "s" / "runs").mkdir(parents=True)
    (tmp_path / "s" / "runs" / "duration=0.1").symlink_to(tmp_path)
    out = mbctl("sweep", "demo", "--param", "duration=0.1", "--output", str(tmp_path / "s"))
    assert out.returncode == 2 and "runs/duration=0.1 is a symbolic link" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr


@pytest.fixture
def http_server():
    """A tiny HTTP server on a free loopback port: it accepts connections but speaks no Dask."""
    import http.server
    import threading

    server = http.server.HTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_a_scheduler_that_is_an_http_server_exits_2_without_hanging(http_server, tmp_path):
    out = run_mbctl("sweep", "demo", "--param", "duration=0.1", "--scheduler", http_server,
                    "--connect-timeout", "1", "--output", str(tmp_path / "s"), timeout=60)
    assert out.returncode == 2, out.stderr
    assert f"no Dask scheduler answered at {http_server} within 1 s" in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize(("address", "message"), [
    ("notaurl", "--scheduler 'notaurl' is not a scheduler address (missing port number"),
    ("http://127.0.0.1:8787", "Dask reaches a scheduler by tcp, tls, ws, wss, ucx, not http://"),
    ("tcp://127.0.0.1:70000", "needs a host and a port in 1-65535"),
])
def test_a_malformed_scheduler_address_exits_2_before_anything_is_written(tmp_path, address, message):
    out = mbctl("sweep", "demo", "--param", "duration=0.1", "--scheduler", address, "--output",
                str(tmp_path / "s"))
    assert out.returncode == 2 and message in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "s").exists()


def test_a_worker_address_is_not_taken_for_a_scheduler(dask_client):
    from mbctl.jobs.sweep_cluster import SweepSetupError, check_scheduler

    worker = next(iter(dask_client.scheduler_info()["workers"]))
    with pytest.raises(SweepSetupError, match="answers, but as a Dask Worker, not a scheduler"):
        check_scheduler(worker, 5.0)
    check_scheduler(dask_client.scheduler.address, 5.0)  # the scheduler itself passes


def test_a_sweep_over_the_dds_interface_exits_2_before_any_task(tmp_path):
    out = mbctl("sweep", "g1-stand", "--param", "interface=sim,dds", "--output", str(tmp_path / "s"))
    assert out.returncode == 2 and "interface=dds" in out.stderr and "sweep the link in process" in out.stderr
    assert not (tmp_path / "s" / "runs").exists()
