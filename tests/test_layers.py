"""The layer rule, read from the imports: robots <- unitree <- sim, hardware; planners <- control <- jobs.

Every ``import`` and ``from ... import`` in the package (including function-local ones) is
checked, so a lazy import cannot hide a dependency that points up the stack. Inside control/, the
task layer sits below differential IK and whole-body inverse dynamics, which are peers (neither
imports the other). Tests of control/ never import jobs/ or cli/, and the examples use the public
API only (no jobs/, cli/ or private names; from a package, only the names in its ``__all__``).
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
    # Unitree's low-level floor (wire format, DDS channel, clock, motor tables): below both of its plants
    "unitree": {"", "robots", "unitree"},
    "sim": {"", "robots", "unitree", "sim"},
    "planners": {"", "robots", "planners"},
    "control": {"", "robots", "planners", "control"},
    "jobs": {"", "robots", "unitree", "sim", "planners", "control", "jobs", "hardware"},
    "cli": {"", "robots", "unitree", "sim", "planners", "control", "jobs", "cli", "hardware"},
    # the real robots: a plant beside sim/, never importing it (nor control/: the estimator is given)
    "hardware": {"", "robots", "unitree", "hardware"},
}
#: Top-level names that belong to other projects and must never be imported bare.
FOREIGN = {"control", "robots", "sim", "planners", "jobs", "cli", "hardware", "unitree"}


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


#: Inside control/: what each subpackage may import from control/ ("" is control/'s own modules:
#: the controller protocol, the feedback laws, the loop, exceptions).
CONTROL_ALLOWED = {
    "tasks": {"tasks"},
    "ik": {"tasks", "ik"},
    "wbc": {"tasks", "wbc", ""},
    "estimation": {"estimation"},
}
#: control/'s own modules any subpackage may use.
#: control/qp is the one QP floor under ik/ and wbc/.
CONTROL_COMMON = {"mbctl.control.exceptions", "mbctl.control.qp"}


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


def _control_violations(root: Path = ROOT) -> list[str]:
    bad = []
    for sub, allowed in CONTROL_ALLOWED.items():
        for path in sorted((root / "control" / sub).rglob("*.py")):
            for name in _imports(path):
                parts = name.split(".")
                if parts[:2] != ["mbctl", "control"] or name in CONTROL_COMMON:
                    continue
                target = parts[2] if len(parts) > 2 and parts[2] in CONTROL_ALLOWED else ""
                if target not in allowed:
                    bad.append(f"{path.relative_to(root)}: imports {name}")
    return bad


def test_control_task_layer_is_below_ik_and_wbc_which_are_peers():
    assert _control_violations() == []


def test_the_control_check_sees_a_violation(tmp_path):
    (tmp_path / "control" / "ik").mkdir(parents=True)
    (tmp_path / "control" / "ik" / "bad.py").write_text("from mbctl.control.wbc import WBCConfig\n")
    for sub in ("tasks", "wbc", "estimation"):
        (tmp_path / "control" / sub).mkdir()
    assert _control_violations(tmp_path) == ["control/ik/bad.py: imports mbctl.control.wbc"]


def test_tests_of_control_import_no_jobs_or_cli():
    bad = [f"{path.relative_to(ROOT)}: {name}" for path in sorted((ROOT / "tests" / "control").rglob("*.py"))
           for name in _imports(path) if name.startswith(("mbctl.jobs", "mbctl.cli"))]
    assert bad == []


def _imported_names(path: Path) -> list[tuple[str, str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("mbctl"):
            out += [(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(a.name, "") for a in node.names if a.name.startswith("mbctl")]
    return out


def _example_violations(folder: Path) -> list[str]:
    import importlib

    bad = []
    for path in sorted(folder.glob("*.py")):
        for module, name in _imported_names(path):
            parts = module.split(".")
            where = f"{path.name}: {module}{' ' + name if name else ''}"
            if len(parts) > 1 and parts[1] in ("jobs", "cli"):
                bad.append(f"{where} (jobs/ and cli/ are the command line's, not the API)")
            elif any(p.startswith("_") for p in parts) or name.startswith("_"):
                bad.append(f"{where} (private)")
            elif name:
                mod = importlib.import_module(module)
                public = getattr(mod, "__all__", None)
                is_module = hasattr(mod, name) and type(getattr(mod, name)).__name__ == "module"
                if mod.__file__ and mod.__file__.endswith("__init__.py") and public is not None \
                        and name not in public and not is_module:
                    bad.append(f"{where} (not in {module}.__all__)")
    return bad


def test_examples_use_only_the_public_api():
    assert _example_violations(ROOT / "examples") == []


def test_the_example_check_sees_violations(tmp_path):
    lines = ["from mbctl.jobs.g1_wbc import prepare", "from mbctl.control import _x",
             "from mbctl.control import presample", "from mbctl.robots import fastmath",
             "from mbctl.control.tasks import stack", "from mbctl.control.ik import iterate",
             "from mbctl.control.ik import IKStep", "from mbctl.sim import Perturbation"]
    (tmp_path / "e.py").write_text("\n".join(lines) + "\n")
    assert _example_violations(tmp_path) == [
        "e.py: mbctl.jobs.g1_wbc prepare (jobs/ and cli/ are the command line's, not the API)",
        "e.py: mbctl.control _x (private)",
        "e.py: mbctl.sim Perturbation (not in mbctl.sim.__all__)",
    ]


#: MuJoCo's C API as Python calls: ``mj_*`` and ``mju_*``.
MJ_CALL_PREFIXES = ("mj_", "mju_")


def _raw_mujoco_calls(path: Path) -> list[str]:
    """``mujoco.mj_*`` / ``mujoco.mju_*`` used in ``path`` (under any alias, or imported by name)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    aliases = {a.asname or a.name for node in ast.walk(tree) if isinstance(node, ast.Import)
               for a in node.names if a.name == "mujoco"}
    bad = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                and node.attr.startswith(MJ_CALL_PREFIXES)):
            bad.append(f"{path.name}:{node.lineno}: mujoco.{node.attr}")
        elif isinstance(node, ast.ImportFrom) and node.module == "mujoco":
            bad += [f"{path.name}:{node.lineno}: from mujoco import {a.name}" for a in node.names
                    if a.name.startswith(MJ_CALL_PREFIXES)]
    return bad


def test_jobs_make_no_raw_mujoco_calls():
    """Jobs run the plant through sim/ and measure it through sim/ and robots/, never MuJoCo's C API."""
    bad = [b for path in sorted((ROOT / "jobs").rglob("*.py")) for b in _raw_mujoco_calls(path)]
    assert bad == [], "move these into sim/ (the plant) or robots/"


def test_the_raw_mujoco_check_sees_calls(tmp_path):
    (tmp_path / "bad.py").write_text("import mujoco as mj\nfrom mujoco import mju_zero, MjData\n"
                                     "mj.mj_forward(m, d)\nmj.mjtObj.mjOBJ_BODY\nx = mj.MjData(m)\n")
    assert _raw_mujoco_calls(tmp_path / "bad.py") == ["bad.py:2: from mujoco import mju_zero",
                                                       "bad.py:3: mujoco.mj_forward"]
