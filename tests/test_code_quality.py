"""Lint and type checks, part of the test suite so CI enforces them (ruff, mypy on both packages)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ["gcs_swarm", "sitl_sim"]


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=300)


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff not installed (pip install -e '.[test]')")
def test_ruff_lint_clean() -> None:
    result = _run(["ruff", "check", "."])
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff not installed (pip install -e '.[test]')")
def test_ruff_format_clean() -> None:
    result = _run(["ruff", "format", "--check", "."])
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_packages() -> None:
    pytest.importorskip("mypy")
    result = _run([sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-error-summary", *PACKAGES])
    assert result.returncode == 0, result.stdout + result.stderr
