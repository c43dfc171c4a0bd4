"""Shared test set-up: the command line's JAX runtime (the CPU unless JAX_PLATFORMS says
otherwise, XLA's fusion emitters off, equinox's checks as NaN, the persistent compilation
cache: :func:`dynslip._jaxconfig.configure_runtime`), set before any test module runs."""

import os
from pathlib import Path

import pytest

from dynslip._jaxconfig import configure_runtime

configure_runtime()

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def scenarios_dir() -> Path:
    return SCENARIOS


#: load stepping's energy residual at the default increments (fraction of the work): implicit
#: Euler's own numerical dissipation, sum of 1/2 dx^T H dx >= 0 per increment, first order in
#: the increment (tests/test_loadstep.py measures the order, 0.99; tests/test_lab_frame.py 1.0
#: on the bottle's shoulder: 6.1e-3 -> 1.24e-3 -> 2.5e-4 at 5 -> 1 -> 0.2 drag times).
#: tests/test_numerical_dissipation.py accounts for it explicitly, D_num = sum of
#: 1/2 (grad E(x_1) - grad E(x_0)) . dx, on the N = 24 push-down in fixed increments of
#: 0.1 .. 0.0125 s: the plain residual 9.68e-3 .. 1.22e-3 (order 0.995) is D_num to 2.1e-3 ..
#: 2.8e-4 of itself, and the residual with D_num accounted is 2.0e-5 .. 3.4e-7 (order 1.96,
#: the trapezoid rule's error in the stored energy).
#: Measured on every run that asserts it (``pytest -m "slow or not slow" tests/test_evidence.py
#: tests/test_shipped.py tests/test_methods.py tests/test_forming.py``, the residual of each
#: call printed): 1.96e-2 on the let-go path at N = 20 (test_evidence), 1.80e-2 on the let-go
#: path at N = 50 (test_forming, test_methods), 4.8e-3 on method 1. Bound 3e-2: 1.5x the
#: largest; the sign (>= 0) catches an over-counted dissipation, as it caught -4.1 before the
#: accumulators were fixed. Runs that must detect a missing term of the balance use Kvaerno5.
LOAD_STEP_ENERGY_RESIDUAL = 3e-2

#: Kvaerno5's energy residual (fraction of the work) at the default rtol 1e-5: measured 1.5e-8
#: on the N = 40 push-down (``pytest -s tests/test_forming.py``), 8.1e-7 on the shipped let-go
#: path at N = 20 (``pytest -s tests/test_evidence.py -k let_go``); bound 1e-5 (12x)
KVAERNO5_ENERGY_RESIDUAL = 1e-5


def assert_energy_closes(summary):
    """The run's energy balance: Kvaerno5 closes it to :data:`KVAERNO5_ENERGY_RESIDUAL`; load
    stepping leaves its numerical dissipation, which removes energy (residual W - dE - D >= 0
    at the end) and stays below :data:`LOAD_STEP_ENERGY_RESIDUAL`."""
    e = summary["energy_balance"]
    if summary["solver"]["method"] in ("load_step", "load_step_full"):  # implicit Euler both
        assert e["residual_end"] >= 0.0, e
        assert e["relative_residual"] < LOAD_STEP_ENERGY_RESIDUAL, e
    else:
        assert e["relative_residual"] < KVAERNO5_ENERGY_RESIDUAL, e


#: threads distributed starts in the process of a dask Client or LocalCluster, which outlive it
DASK_THREADS = ("IO loop", "Dask-Offload")


@pytest.fixture(autouse=True)
def _no_dask_threads_in_the_test_process():
    """Every dask cluster and client of the suite lives in a child process (helpers.dask_cluster):
    with distributed's threads alive in the pytest process, a later XLA compile crashed the
    CI run (a segfault in tests/test_resolution.py, after tests/test_faults.py had hosted a
    LocalCluster). A test that starts one here fails by name instead."""
    import threading

    yield
    left = sorted({t.name for t in threading.enumerate() if t.name.startswith(DASK_THREADS)})
    assert not left, f"this test left dask threads in the pytest process: {left}"


#: the most memory maps the pytest process held at the end of a test module
_PEAK_MAPS = [0]


def _maps() -> int:
    try:
        with open("/proc/self/maps") as f:
            return sum(1 for _ in f)
    except OSError:  # not Linux
        return 0


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Every XLA CPU executable holds about 20 memory maps until it is released, and the kernel
    allows 65530 per process (vm.max_map_count): the whole suite in one process compiled past
    that, and XLA crashed (a segfault writing the compilation cache, an abort before). After
    each test module its executables are released (the driver's compiled segment solves and
    JAX's caches); the next module reads what it shares from the persistent cache."""
    yield
    import gc

    import jax

    from dynslip.physics.driver import simulate

    _PEAK_MAPS[0] = max(_PEAK_MAPS[0], _maps())
    simulate._COMPILED.clear()
    jax.clear_caches()
    gc.collect()


def pytest_sessionfinish(session):
    """Under pytest-xdist a worker hands its peak to the controller, which prints the summary."""
    out = getattr(session.config, "workeroutput", None)
    if out is not None:
        out["peak_maps"] = _PEAK_MAPS[0]


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    _PEAK_MAPS[0] = max(_PEAK_MAPS[0], getattr(node, "workeroutput", {}).get("peak_maps", 0))


def pytest_terminal_summary(terminalreporter):
    terminalreporter.write_line(
        f"memory maps: at most {_PEAK_MAPS[0]} at a module's end (the kernel's limit: "
        f"vm.max_map_count)"
    )
