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
             for p in ROOT.rglob("__init__.py") if not skip & set(p.relative_to(ROOT).parts)
             and not p.relative_to(ROOT).parts[0].startswith(".")}  # hidden: .venv, a TSID build in .tsid
    assert found - listed == set(), "add these to [tool.setuptools] packages"
    assert listed - found == set(), "these packages do not exist"


#: The longest a source file may be [lines] (the brief: small modules, one idea each).
MAX_LINES = 500


def _python_files(root: Path) -> list[Path]:
    """The repository's tracked .py files (package, tests, bench, examples), or every .py outside
    virtual environments and build folders when the tree is not a git checkout."""
    out = subprocess.run(["git", "ls-files", "-z", "--", "*.py"], capture_output=True, cwd=root)
    if out.returncode == 0 and out.stdout:
        return [root / p for p in out.stdout.decode().split("\0") if p]
    skip = {".venv", "venv", "build", ".git", "node_modules"}
    return [p for p in root.rglob("*.py") if not skip & set(p.relative_to(root).parts)]


def _too_long(root: Path, limit: int = MAX_LINES) -> list[str]:
    lengths = ((p, len(p.read_text().splitlines())) for p in _python_files(root) if p.is_file())
    return sorted(f"{p.relative_to(root)}: {n} lines" for p, n in lengths if n > limit)


def test_no_source_file_is_over_500_lines():
    assert _python_files(ROOT), "no Python files found"
    long = _too_long(ROOT)
    assert not long, f"split these by idea (at most {MAX_LINES} lines each): " + "; ".join(long)


def test_the_length_check_sees_a_long_file(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "long.py").write_text("x = 1\n" * (MAX_LINES + 1))
    (tmp_path / "pkg" / "short.py").write_text("x = 1\n" * MAX_LINES)
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / "dep.py").write_text("x = 1\n" * 1000)
    assert _too_long(tmp_path) == [f"pkg/long.py: {MAX_LINES + 1} lines"]
