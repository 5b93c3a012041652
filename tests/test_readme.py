"""The README and the guides as a new user meets them: a short guide first, pasteable command
blocks, commands that exist, links that lead somewhere, and a layout table that matches the house.

The README is the guide (what mbctl is, the Quickstart, a controller early, the G1, where next);
the reference moved to the pages of ``docs/api/`` (reStructuredText, built by tests/test_docs.py),
and their command blocks are held to the README's standard.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

import mbctl

ROOT = Path(mbctl.__file__).resolve().parent
README = ROOT / "README.md"
DOCS = ROOT / "docs" / "api"
#: The pages written by hand: the ones the docs build generates (``docs/api/.gitignore``: examples.rst,
#: from the examples' docstrings) exist only after a build, and a fresh clone's run must check the same.
GENERATED = set((DOCS / ".gitignore").read_text().split())
PAGES = sorted(p for p in DOCS.glob("*.rst") if p.name not in GENERATED)
#: The README stays a guide: at most this many lines, its first Python (a controller) before this line.
MAX_README_LINES = 250
MAX_FIRST_PYTHON_LINE = 80


def rst_blocks(path: Path, language: str) -> list[str]:
    """The ``.. code-block:: LANGUAGE`` blocks of a reStructuredText page, dedented."""
    pattern = rf"^\.\. code-block:: {language}\n((?:[ \t]*\n|   .*\n)+)"
    blocks = re.findall(pattern, path.read_text(), flags=re.M)
    return [textwrap.dedent(b).strip("\n") + "\n" for b in blocks]


def md_blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def _documents() -> list[Path]:
    return [README, *PAGES]


def _bash_blocks(path: Path) -> list[str]:
    return md_blocks(path.read_text(), "bash") if path.suffix == ".md" else rst_blocks(path, "bash")


def _bash_lines(path: Path) -> list[str]:
    lines = [ln.split("#")[0].strip() for block in _bash_blocks(path) for ln in block.splitlines()]
    return [ln for ln in lines if ln]


def test_quickstart_has_exactly_the_two_commands():
    quick = README.read_text().split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    block = re.findall(r"```bash\n(.*?)```", quick, flags=re.S)
    assert len(block) == 2  # the two commands, then the activation said once
    commands = [ln for ln in block[0].splitlines() if ln.strip()]
    assert commands == [
        "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/mbctl demo",
        "python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && .venv/bin/python -m pytest -q -n 2 "
        "--dist loadfile",
    ]
    assert block[1].strip() == "source .venv/bin/activate"


def test_the_readme_is_a_short_guide_with_a_controller_early():
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines (at most {MAX_README_LINES})"
    first_python = next(i for i, ln in enumerate(lines, 1) if ln.startswith("```python"))
    assert first_python < MAX_FIRST_PYTHON_LINE, f"the README's first Python starts at line {first_python}"
    quickstart = next(i for i, ln in enumerate(lines, 1) if ln == "## Quickstart")
    assert quickstart < first_python


def test_the_environment_is_activated_once_before_any_bare_command():
    text = README.read_text()
    assert text.count("source .venv/bin/activate") == 1
    before = text.split("source .venv/bin/activate", 1)[0]
    bare = [ln for ln in _bash_lines_of(before) if re.match(r"(mbctl|python|pip) ", ln)]
    assert not bare, f"a bare command before the environment is activated: {bare}"


def _bash_lines_of(text: str) -> list[str]:
    lines = [ln.split("#")[0].strip() for block in md_blocks(text, "bash") for ln in block.splitlines()]
    return [ln for ln in lines if ln]


@pytest.mark.parametrize("document", _documents(), ids=lambda p: p.name)
def test_bash_blocks_are_pasteable_line_by_line(document):
    for line in _bash_lines(document):
        where = f"{document.name}, a bash block"
        assert not re.search(r"\[--?\w", line), f"{where}: optional-argument synopsis: {line}"
        assert " | " not in line.replace("||", ""), f"{where}: an alternatives bar: {line}"
        assert "..." not in line and "<" not in line, f"{where}: a placeholder: {line}"


def test_the_guides_have_their_command_blocks():
    """The commands that moved out of the README are on their pages, in blocks the tests read."""
    for page in ("commands", "robots_guide", "ik", "whole_body", "dds", "identification"):
        assert _bash_lines(DOCS / f"{page}.rst"), f"{page}.rst shows no command block"


@pytest.fixture(scope="module")
def commands() -> set[str]:
    from mbctl.cli import _register_commands, app

    _register_commands()
    return {c.name for c in app.registered_commands if c.name}


def _inline_mbctl_commands(path: Path) -> set[str]:
    """Second words of ``mbctl X`` written inline (``literal`` in reST, `code` in Markdown)."""
    tick = "``" if path.suffix == ".rst" else "`"
    found = re.findall(rf"{tick}mbctl (?:--cpus [\w,-]+ )?([\w-]+)", path.read_text())
    return set(found)


@pytest.mark.parametrize("document", _documents(), ids=lambda p: p.name)
def test_every_mbctl_line_names_a_command(document, commands):
    # the root's options come before the command (``mbctl --cpus 0 serve g1``)
    lines = [re.sub(r"^mbctl --cpus \S+ ", "mbctl ", ln) for ln in _bash_lines(document)]
    used = {ln.split()[1] for ln in lines if ln.startswith("mbctl ") and len(ln.split()) > 1}
    used |= _inline_mbctl_commands(document)
    used -= {"--version", "--help", "--cpus", "COMMAND"}
    assert used <= commands, f"{document.name}: {sorted(used - commands)}"


def test_the_readme_and_the_command_page_show_commands(commands):
    readme = {ln.split()[1] for ln in _bash_lines(README) if ln.startswith("mbctl ")}
    assert {"g1-wbc", "serve", "xcheck"} <= readme
    page = _inline_mbctl_commands(DOCS / "commands.rst")
    assert commands <= page, f"commands the command-line page does not name: {sorted(commands - page)}"


def _scripts(text: str) -> set[str]:
    """The files a document runs: ``python PATH.py``, ``python -m bench.MODULE``, ``tests/...py``."""
    paths = set(re.findall(r"python ((?:bench|docs|examples)/[\w/]+\.py)", text))
    paths |= {m.replace(".", "/") + ".py" for m in re.findall(r"python -m (bench\.[\w.]+)", text)}
    return paths | set(re.findall(r"(tests/[\w/]+\.py)", text))


@pytest.mark.parametrize("document", _documents(), ids=lambda p: p.name)
def test_every_script_a_document_runs_exists(document):
    missing = sorted(s for s in _scripts(document.read_text()) if not (ROOT / s).is_file())
    assert not missing, f"{document.name}: files that do not exist: {missing}"


def test_every_measured_figure_names_its_command():
    table_rows = re.split(r"\n   \* - ", (DOCS / "measured.rst").read_text())[1:]
    figures = [row for row in table_rows if not row.startswith("what")]
    assert len(figures) > 30
    for row in figures:
        command = row.split("\n     - ")[-1]
        assert re.search(r"``(mbctl |python )", command), f"a figure without its command: {row[:80]!r}"
    history = re.search(r"\bwas \d|\(was\b|; was\b|\bearlier (runs?|figures?)\b|before issue",
                        "".join(figures))
    assert not history, f"history in a measured cell (it belongs in git): {history.group(0)!r}"


def test_the_readme_links_every_guide_and_every_link_resolves():
    text = README.read_text()
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text) + re.findall(r'src="([^"]+)"', text)
    local = [t for t in targets if not re.match(r"https?://", t)]
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"
    toctree = re.findall(r"^   (\w+)$", (DOCS / "index.rst").read_text(), flags=re.M)
    unlinked = [p for p in toctree if p != "examples" and f"docs/api/{p}.rst" not in local]
    assert not unlinked, f"pages the README's 'Where next' does not link: {unlinked}"


def _layout_rows() -> dict[str, str]:
    """The layout page's list-table: each row's first cell (a ``package/``) and its whole text."""
    table = (DOCS / "layout.rst").read_text().split(".. list-table::", 1)[1]
    rows: dict[str, str] = {}
    for row in re.split(r"\n   \* - ", table)[1:]:
        if row.startswith("``"):
            rows[row.split("``")[1]] = row
    return rows


def test_the_layout_page_names_every_package_and_module():
    """The layout page and the house agree: each package a row, each public module named in it."""
    rows = _layout_rows()
    # (hidden folders are not the house's: .venv, a TSID build in .tsid, caches)
    packages = sorted(str(p.parent.relative_to(ROOT)) + "/" for p in ROOT.glob("*/**/__init__.py")
                      if not p.relative_to(ROOT).parts[0].startswith(".") and "tests" not in p.parts
                      and "docs" not in p.parts and "bench" not in p.parts and "examples" not in p.parts)
    missing_rows = [p for p in packages if p not in rows]
    assert not missing_rows, f"packages without a layout row: {missing_rows}"
    unnamed = [f"{pkg}{m.stem}" for pkg in packages for m in sorted((ROOT / pkg).glob("*.py"))
               if not m.stem.startswith("_") and m.stem != "exceptions" and f"``{m.stem}``" not in rows[pkg]]
    assert not unnamed, f"modules the layout row of their package does not name: {unnamed}"
    top = [m.name for m in sorted(ROOT.glob("*.py")) if not m.stem.startswith("_")]
    assert [m for m in top if m not in rows] == [], "top-level modules without a layout row"
