"""End-to-end tests: every test here starts real processes (tests/e2e/flights.py flies them) and is marked
`e2e` by tests/conftest.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.e2e.flights import MISSIONS


@pytest.fixture
def quickstart() -> Path:
    return MISSIONS / "quickstart.yaml"
