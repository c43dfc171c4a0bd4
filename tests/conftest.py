"""Shared test set-up: float64 JAX and the persistent compilation cache (via dynslip)."""

import os
from pathlib import Path

import pytest

import dynslip  # noqa: F401  (turns on x64 and the compilation cache)

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def scenarios_dir() -> Path:
    return SCENARIOS
