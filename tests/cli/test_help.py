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
    jobs = {"demo", "joint-step", "xcheck", "ik", "workspace", "g1-stand", "g1-track", "g1-arm-pd", "excite",
            "identify"}
    for command in jobs & set(COMMANDS):
        out = CliRunner().invoke(app, [command, "--help"], terminal_width=200, env={"COLUMNS": "200"})
        assert "--output" in out.output and "--quiet" in out.output, command
