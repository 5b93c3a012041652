"""The root of every error mbctl raises, so callers can catch the toolkit's errors in one place."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class ToolkitError(Exception):
    """Base class of all mbctl errors."""


def close_matches(name: str, known: Iterable[str], n: int = 3) -> list[str]:
    """The known names closest to `name`, best first (for "did you mean" hints)."""
    return difflib.get_close_matches(name, list(known), n=n, cutoff=0.5)


def unknown_name_message(kind: str, name: str, known: Iterable[str]) -> str:
    """A message for an unknown name that lists close matches, or all names when few."""
    known = list(known)
    matches = close_matches(name, known)
    if matches:
        hint = f" Did you mean {', '.join(repr(m) for m in matches)}?"
    else:
        hint = ""
    listing = ", ".join(known) if len(known) <= 40 else f"{len(known)} names, see `mbctl inspect`"
    return f"Unknown {kind} {name!r}.{hint} Available: {listing}."
