"""Test models of the robots tests (tests/robots/assets/, each commented on what it exercises)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

ASSETS = Path(__file__).resolve().parent / "assets"


@pytest.fixture(scope="session")
def asset() -> Callable[[str], Path]:
    """The path of a test model: ``asset("chain.xml")``."""
    return lambda name: ASSETS / name


@pytest.fixture()
def write_model(tmp_path: Path) -> Callable[[str, str], Path]:
    """Writes a model's text into the test's folder: ``write_model("leg.xml", text) -> Path``."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write
