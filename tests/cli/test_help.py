"""Every command's --help as a user reads it: units survive the formatter, options documented."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from mbctl.cli import _register_commands, app

_register_commands()
COMMANDS = sorted(c.name for c in app.registered_commands if c.name)


@pytest.mark.parametrize("command", COMMANDS)
def test_help_keeps_units_and_documents_every_option(command):
    out = CliRunner().invoke(app, [command, "--help"], terminal_width=200, env={"COLUMNS": "200"})
    assert out.exit_code == 0, out.output
    # rich markup eats "[rad]": units are written "(rad)"; a bracketed unit would vanish silently
    callback = next(c.callback for c in app.registered_commands if c.name == command)
    import inspect

    checked = 0
    for name, param in inspect.signature(callback, eval_str=True).parameters.items():
        meta = getattr(param.annotation, "__metadata__", ())
        for info in meta:
            checked += 1
            help_text = getattr(info, "help", None)
            assert help_text, f"{command}: option {name} has no help"
            assert not re.search(r"\[[a-zA-Z/^0-9 ]+\]", help_text), f"{command} {name}: {help_text!r}"
    assert checked == len(inspect.signature(callback).parameters)


def test_every_job_has_output_and_quiet():
    jobs = {"demo", "joint-step", "xcheck", "ik", "workspace", "g1-stand", "g1-track", "g1-arm-pd", "g1-wbc",
            "excite", "identify", "serve"}
    assert jobs <= set(COMMANDS), sorted(jobs - set(COMMANDS))  # every job is a registered command
    for command in sorted(jobs):
        out = CliRunner().invoke(app, [command, "--help"], terminal_width=200, env={"COLUMNS": "200"})
        assert "--output" in out.output and "--quiet" in out.output, command


def test_help_loads_no_engine():
    """``mbctl --help`` and every command's help import no engine, plotting or cluster library.

    Each command imports its job when it runs: the help is shown at typer's speed (bench/bench_cli.py).
    """
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from typer.testing import CliRunner\n"
        "from mbctl.cli import _register_commands, app\n"
        "_register_commands()\n"
        "for args in [['--help']] + [[c.name, '--help'] for c in app.registered_commands]:\n"
        "    assert CliRunner().invoke(app, args).exit_code == 0, args\n"
        "heavy = ('mujoco', 'pinocchio', 'numpy', 'matplotlib', 'dask', 'imageio', 'qpsolvers', 'mink')\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"--help imported {out.stdout.strip()}"


def test_the_help_s_choices_are_the_jobs():
    """The names the help lists (jobs/choices.py, light to import) are the ones the jobs accept."""
    from mbctl.jobs import choices
    from mbctl.jobs.catalog import CATALOG
    from mbctl.jobs.g1_wbc import DEFAULT_DURATION_S, SCENARIOS

    assert SCENARIOS == choices.WBC_SCENARIOS
    assert DEFAULT_DURATION_S == choices.WBC_DEFAULT_DURATION_S
    assert tuple(CATALOG) == choices.SWEEP_JOBS
    from mbctl.jobs.serve import STARTS

    assert STARTS == choices.SERVE_STARTS


@pytest.mark.parametrize("command", ["g1-walk", "g1-wbc", "serve", "sweep", "excite"])
def test_a_description_s_paragraphs_wrap_to_the_terminal_not_to_the_source(command):
    # Typer keeps a later paragraph's source line breaks; at 80 columns the terminal wrapped those
    # lines again: a line of 70 characters, then one of 10 ("`course`, a" alone)
    out = CliRunner().invoke(app, [command, "--help"], terminal_width=80, env={"COLUMNS": "80"})
    assert out.exit_code == 0, out.output
    description = out.output.split("Usage:")[1].split("╭")[0].splitlines()[2:]
    paragraphs = "\n".join(line.strip() for line in description).strip().split("\n\n")
    assert len(paragraphs) >= 2, description
    for paragraph in paragraphs:
        lines = paragraph.splitlines()
        short = [line for line in lines[:-1] if len(line) < 60]  # (rich wraps at 78: a word short of it)
        assert not short, (command, lines)
