"""The layer rule, read from the imports: robots <- sim, control, planners <- jobs <- cli.

Every ``import`` and ``from ... import`` in the package (including function-local ones) is
checked, so a lazy import cannot hide a dependency that points up the stack.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import mbctl

ROOT = Path(mbctl.__file__).resolve().parent

#: Which mbctl layers each layer may import ("" is the package root: mbctl.exceptions).
ALLOWED = {
    "robots": {"", "robots"},
    "sim": {"", "robots", "sim"},
    "planners": {"", "robots", "planners"},
    "control": {"", "robots", "planners", "control"},
    "jobs": {"", "robots", "sim", "planners", "control", "jobs", "hardware"},
    "cli": {"", "robots", "sim", "planners", "control", "jobs", "cli", "hardware"},
    # the real robots: a plant beside sim/, never importing it (nor control/: the estimator is given)
    "hardware": {"", "robots", "hardware"},
}
#: Top-level names that belong to other projects and must never be imported bare.
FOREIGN = {"control", "robots", "sim", "planners", "jobs", "cli", "hardware"}


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                names.append("<relative>")
            elif node.module:
                names.append(node.module)
                if node.module == "mbctl":  # from mbctl import robots
                    names += [f"mbctl.{a.name}" for a in node.names]
    return names


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ALLOWED else ""


def _violations(layer: str) -> list[str]:
    bad = []
    for path in sorted((ROOT / layer).rglob("*.py")):
        for name in _imports(path):
            rel = path.relative_to(ROOT)
            if name == "<relative>":
                bad.append(f"{rel}: relative import (use mbctl.…)")
            elif name.split(".")[0] in FOREIGN:
                bad.append(f"{rel}: bare import {name!r} (the import name is mbctl)")
            elif name.startswith("mbctl.") and _layer(name) not in ALLOWED[layer]:
                bad.append(f"{rel}: imports {name} ({_layer(name)}/ is above {layer}/)")
    return bad


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_layer_imports_only_from_below(layer):
    assert (ROOT / layer).is_dir()
    assert _violations(layer) == []


def test_the_check_sees_a_violation(tmp_path, monkeypatch):
    # The rule must be able to fail: a sim module importing control is reported.
    fake = tmp_path / "sim"
    fake.mkdir()
    (fake / "bad.py").write_text("def f():\n    from mbctl.control.loop import run\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert _violations("sim") == ["sim/bad.py: imports mbctl.control.loop (control/ is above sim/)"]


def test_importing_control_and_planners_loads_no_sim_jobs_or_cli():
    code = ("import sys, mbctl.control, mbctl.control.ik, mbctl.planners; "
            "bad = sorted(m for m in sys.modules if m.startswith(('mbctl.sim', 'mbctl.jobs', 'mbctl.cli'))); "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)
