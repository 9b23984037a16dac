"""Lint and type checks, part of the test suite so CI enforces them (ruff, mypy on the pure modules)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PURE_MODULES = ["gcs_swarm/guidance", "gcs_swarm/metrics.py", "gcs_swarm/frames.py"]


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


def test_mypy_pure_modules() -> None:
    pytest.importorskip("mypy")
    paths = [p for p in PURE_MODULES if (ROOT / p).exists()]
    result = _run([sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-error-summary", *paths])
    assert result.returncode == 0, result.stdout + result.stderr
