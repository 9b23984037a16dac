"""End-to-end tests: every test here starts real processes (tests/e2e/flights.py flies them)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.e2e.flights import MISSIONS


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every test under tests/e2e starts real processes: mark it `e2e` (`pytest -m "not e2e"` skips them)."""
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.e2e)


@pytest.fixture
def quickstart() -> Path:
    return MISSIONS / "quickstart.yaml"
