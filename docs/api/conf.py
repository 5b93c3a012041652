"""Sphinx configuration of mbctl's API reference (built by tests/test_docs.py with -W -n).

Sphinx with autodoc and napoleon, not MkDocs with mkdocstrings: napoleon reads our Google
docstrings as they are, autodoc's nitpicky mode (-n) turns every cross-reference that does not
resolve into a warning and -W makes warnings errors, and it needs no theme or plugin beyond
Sphinx itself (mink and pink publish their references with Sphinx too). The reference covers the
public API: each package's ``__all__``. A public name without a docstring fails the build
(:func:`_require_docstring`), as does a broken cross-reference. The numbered examples are
rendered from ``examples/`` at build time (:func:`_write_examples`).
"""

from __future__ import annotations

import ast
import os
import re
import sys
from pathlib import Path
from typing import Any

from sphinx.application import Sphinx
from sphinx.util import logging

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"

project = "mbctl"
author = "the mbctl developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
exclude_patterns = ["_build"]
html_theme = "alabaster"
nitpicky = True
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
# undoc-members: an undocumented public name reaches _require_docstring (and fails) instead of
# being left out silently.
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes:" as fields: NamedTuple fields are not described twice
# Third-party types in signatures have no target here (no network for intersphinx): not ours to check.
_FOREIGN = r"(np|numpy|npt|pin|pinocchio|mujoco|qpsolvers|ruckig|mink|typer|rich|matplotlib|viser|dask|" \
           r"distributed|threading|collections|typing|pathlib|os|enum|dataclasses|abc|types)"
nitpick_ignore_regex = [
    (r"py:.*", _FOREIGN + r"(\..*)?"),
    (r"py:.*", r"(ArrayLike|NDArray|Path|Any|Callable|Sequence|Mapping|Iterable|Iterator|Enum|"
               r"Generic|TypeVar|NamedTuple|Protocol|ClassVar|Literal|P|T|optional)"),
    (r"py:.*", r"(dict|list|tuple|set)\[.*"),  # a generic in an attribute's annotation
    (r"py:.*", r"mbctl\..*\._\w+"),  # private helpers (bases of public classes)
    (r"py:.*", r"mbctl\..*\.RefT\w*"),  # the controllers' reference TypeVar
]

_log = logging.getLogger(__name__)


def _write_examples(app: Sphinx) -> None:
    """``examples.rst``: every numbered example, its docstring as text and its code."""
    if not app.config.mbctl_examples:
        return
    lines = ["Examples", "========", "",
             "The numbered scripts in ``examples/``, simplest first; each runs on the public API",
             "and takes ``--duration`` (the tests run every one short).", ""]
    scripts = sorted(EXAMPLES.glob("[0-9][0-9]_*.py"))
    for script in scripts:
        doc = ast.get_docstring(ast.parse(script.read_text())) or ""
        title = script.name
        lines += [title, "-" * len(title), "", doc, "",
                  f".. literalinclude:: {os.path.relpath(script, app.srcdir)}",
                  "   :language: python", f"   :lines: {_body_start(script)}-", ""]
    target = Path(app.srcdir) / "examples.rst"
    text = "\n".join(lines)
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


def _body_start(script: Path) -> int:
    """The first line after the module docstring (rendered as text above the code)."""
    tree = ast.parse(script.read_text())
    first = tree.body[0]
    return (first.end_lineno or 0) + 1 if isinstance(first, ast.Expr) else 1


def _resolve_short_names(app: Sphinx, env: object, node: Any, contnode: Any) -> Any:
    """Resolve a short or defining-module name to the one documented object of that name.

    ``CommandError`` (a ``Raises:`` entry) or ``mbctl.control.loop.run`` (where a re-exported
    name is defined) point at the documented ``mbctl.robots.CommandError``, ``mbctl.control.run``.
    A name documented nowhere, or twice under that last component, stays unresolved (a warning:
    an error under -W).
    """
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    last = target.rsplit(".", 1)[-1]
    domain = app.env.get_domain("py")
    names = [name for name, obj in domain.objects.items() if not obj.aliased]  # type: ignore[attr-defined]
    matches = {n for n in names if n.endswith("." + target)}  # Task.method: the one class's
    if len(matches) != 1:
        matches = {n for n in names if n.rsplit(".", 1)[-1] == last}
    if len(matches) != 1:
        return None
    node["reftarget"] = matches.pop()
    return domain.resolve_xref(app.env, node["refdoc"], app.builder, node["reftype"], node["reftarget"],
                               node, contnode)


#: Property and attribute docstrings that begin "Some words: more words" (prose, not a type):
#: napoleon would read "Some words" as the type. Colons of such a first line become dashes.
_PROSE_COLON = re.compile(r"^[^:`]*\s[^:`]*: ")


def _prose_first_line(app: Sphinx, what: str, name: str, obj: object, options: object,
                      lines: list[str]) -> None:
    if what in ("attribute", "property", "data") and lines and _PROSE_COLON.match(lines[0]):
        lines[0] = lines[0].replace(": ", " \u2014 ")


def _require_docstring(app: Sphinx, what: str, name: str, obj: object, options: object,
                       lines: list[str]) -> None:
    """Warn (an error under -W) for a documented public object without a docstring."""
    undocumented = not any(x.strip() for x in lines)
    if what in ("module", "class", "function", "method", "exception") and undocumented:
        if not name.rsplit(".", 1)[-1].startswith("_"):
            _log.warning("public %s %s has no docstring", what, name, location=name)


def _skip_stdlib(app: Sphinx, what: str, name: str, obj: object, skip: bool,
                 options: object) -> bool | None:
    """Leave out names a module imported from the standard library.

    (``Iterable`` in a module without ``__all__``): they are not ours to document.
    """
    module = getattr(obj, "__module__", None)
    if isinstance(module, str) and module.split(".")[0] in sys.stdlib_module_names:
        return True
    return None


def setup(app: Sphinx) -> None:
    """Hook the examples page and the docstring check into the build."""
    app.add_config_value("mbctl_examples", True, "env")  # False: no examples page (the docs' own tests)
    app.connect("builder-inited", _write_examples)
    app.connect("autodoc-process-docstring", _prose_first_line, priority=400)  # before napoleon
    app.connect("autodoc-process-docstring", _require_docstring)
    app.connect("missing-reference", _resolve_short_names)
    app.connect("autodoc-skip-member", _skip_stdlib)
