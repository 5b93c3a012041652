"""Static checks as tests, so the README's one test command covers them: ruff and mypy."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import mbctl

ROOT = Path(mbctl.__file__).resolve().parent


def test_ruff_is_clean():
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent))
    out = subprocess.run([ruff or "ruff", "check", str(ROOT)], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


def test_mypy_is_clean(tmp_path):
    # The repo root is the package, so mypy sees it through a link named after the import name.
    (tmp_path / "mbctl").symlink_to(ROOT, target_is_directory=True)
    out = subprocess.run(
        [sys.executable, "-m", "mypy", "-p", "mbctl", "--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(tmp_path / ".mypy_cache")],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Success: no issues found" in out.stdout


def test_every_package_is_in_pyprojects_list():
    """A subpackage missing from the list works in an editable install and is absent from a wheel."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    skip = {"tests", "bench", "examples", "docs", ".venv", "build"}
    found = {"mbctl." + ".".join(p.parent.relative_to(ROOT).parts) if p.parent != ROOT else "mbctl"
             for p in ROOT.rglob("__init__.py") if not skip & set(p.relative_to(ROOT).parts)}
    assert found - listed == set(), "add these to [tool.setuptools] packages"
    assert listed - found == set(), "these packages do not exist"
