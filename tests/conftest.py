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


#: load stepping's energy residual at the default increments (fraction of the work): implicit
#: Euler's own numerical dissipation, sum of 1/2 dx^T H dx >= 0 per increment, first order in
#: the increment (tests/test_loadstep.py measures the order, 0.99); 2-4% on the shipped paths
LOAD_STEP_ENERGY_RESIDUAL = 5e-2


def assert_energy_closes(summary):
    """The run's energy balance: Kvaerno5 closes it to its tolerance (1e-2 of the work); load
    stepping leaves its numerical dissipation, which removes energy (residual W - dE - D >= 0
    at the end) and stays below :data:`LOAD_STEP_ENERGY_RESIDUAL`."""
    e = summary["energy_balance"]
    if summary["solver"]["method"] == "load_step":
        assert e["residual_end"] >= 0.0, e
        assert e["relative_residual"] < LOAD_STEP_ENERGY_RESIDUAL, e
    else:
        assert e["relative_residual"] < 1e-2, e
