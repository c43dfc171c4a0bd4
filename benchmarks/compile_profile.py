"""Where the test suite's time goes in JAX: a pytest plugin that sums, per test module, the
compile events JAX reports (``jax.monitoring``): tracing to a jaxpr, lowering to MLIR, and
XLA's backend compile, each with its count. It works under pytest-xdist (each worker hands its
sums to the controller). Run from the repository root::

    DYNSLIP_CACHE_DIR=$(mktemp -d) PYTHONPATH=benchmarks pytest -q -m "not slow" \\
        -p compile_profile --junitxml=/tmp/quick.xml

The table at the end lists the modules by backend compile time; a module with thousands of
compiles spends them on eager operations (each new shape of each ``jnp`` call outside ``jit``
is one small program, 10-40 ms on this machine), one with a few long ones on its runs' steps.
With an empty cache (``DYNSLIP_CACHE_DIR``) it measures the cold loop.
"""

from __future__ import annotations

import collections

import jax.monitoring
import pytest

#: JAX's duration events, by the column they fill
EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "compile",
}

_CURRENT = ["(outside a test)"]
_SUMS: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)


def _listen(event: str, duration: float, **_) -> None:
    column = EVENTS.get(event)
    if column is not None:
        sums = _SUMS[_CURRENT[0]]
        sums[column] += duration
        sums[column + "_n"] += 1


jax.monitoring.register_event_duration_secs_listener(_listen)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _CURRENT[0] = item.nodeid.split("::")[0]
    yield


def pytest_sessionfinish(session):
    out = getattr(session.config, "workeroutput", None)
    if out is not None:  # an xdist worker: the controller prints
        out["compile_profile"] = {k: dict(v) for k, v in _SUMS.items()}


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    for module, sums in getattr(node, "workeroutput", {}).get("compile_profile", {}).items():
        _SUMS[module].update(sums)


def pytest_terminal_summary(terminalreporter):
    write = terminalreporter.write_line
    rows = sorted(_SUMS.items(), key=lambda kv: -kv[1]["compile"])
    total = collections.Counter()
    for _, sums in rows:
        total.update(sums)
    write("JAX compile events per test module (seconds, count):")
    write(f"{'module':<48} {'trace':>12} {'lower':>12} {'compile':>13}")
    for module, s in [("all modules", total), *rows[:30]]:
        cells = (f"{s[c]:7.1f} {int(s[c + '_n']):>5}" for c in ("trace", "lower", "compile"))
        write(f"{module:<48} " + " ".join(cells))
