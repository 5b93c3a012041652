"""The README as a new user meets it: pasteable command blocks, commands that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import mbctl

README = Path(mbctl.__file__).resolve().parent / "README.md"


def _bash_lines() -> list[str]:
    lines: list[str] = []
    for block in re.findall(r"```bash\n(.*?)```", README.read_text(), flags=re.S):
        lines += [ln.split("#")[0].strip() for ln in block.splitlines()]
    return [ln for ln in lines if ln]


def test_quickstart_has_exactly_the_two_commands():
    quick = README.read_text().split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    block = re.findall(r"```bash\n(.*?)```", quick, flags=re.S)
    assert len(block) == 1
    commands = [ln for ln in block[0].splitlines() if ln.strip()]
    assert commands == [
        "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/mbctl demo",
        "python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && .venv/bin/python -m pytest -q",
    ]


def test_bash_blocks_are_pasteable_line_by_line():
    for line in _bash_lines():
        assert not re.search(r"\[--?\w", line), f"optional-argument synopsis in a bash block: {line}"
        assert " | " not in line.replace("||", ""), f"an alternatives bar in a bash block: {line}"
        assert "..." not in line and "<" not in line, f"a placeholder in a bash block: {line}"


@pytest.fixture(scope="module")
def commands() -> set[str]:
    from mbctl.cli import _register_commands, app

    _register_commands()
    return {c.name for c in app.registered_commands if c.name}


def test_every_mbctl_line_names_a_command(commands):
    used = {ln.split()[1] for ln in _bash_lines() if ln.startswith("mbctl ") and len(ln.split()) > 1}
    used.discard("--version")
    assert used, "the README shows no mbctl command"
    assert used <= commands, sorted(used - commands)


def _layout_rows() -> dict[str, str]:
    layout = README.read_text().split("## Layout", 1)[1]
    rows = {}
    for line in layout.splitlines():
        if line.startswith("| `"):
            rows[line.split("`")[1]] = line
    return rows


def test_the_layout_section_names_every_package_and_module():
    """The README's Layout and the house agree: each package a row, each public module named in it."""
    root = README.parent
    rows = _layout_rows()
    packages = sorted(str(p.parent.relative_to(root)) + "/" for p in root.glob("*/**/__init__.py")
                      if ".venv" not in p.parts and "tests" not in p.parts and "docs" not in p.parts
                      and "bench" not in p.parts and "examples" not in p.parts)
    missing_rows = [p for p in packages if p not in rows]
    assert not missing_rows, f"packages without a Layout row: {missing_rows}"
    unnamed = [f"{pkg}{m.stem}" for pkg in packages for m in sorted((root / pkg).glob("*.py"))
               if not m.stem.startswith("_") and m.stem != "exceptions" and f"`{m.stem}`" not in rows[pkg]]
    assert not unnamed, f"modules the Layout row of their package does not name: {unnamed}"
