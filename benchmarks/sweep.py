"""Sweep throughput (members per minute): sequential, batched and dask runs of a method 2 sweep.

``run() -> dict`` (called by ``benchmarks/run.py``) runs the same small sweep over mu of
the method 2 scenario three times, once per mode, each into a fresh folder, and reports
members per minute for each, the ratio to sequential, and an estimate for the issue's
target (64 members at 100 nodes) from the measured per-member time. Settings, from
the environment:

- ``DYNSLIP_BENCH_SWEEP_NODES`` (default 20): nodes of every member;
- ``DYNSLIP_BENCH_SWEEP_MEMBERS`` (default 4): members (values of mu in 0.4..1.6);
- ``DYNSLIP_BENCH_SWEEP_MODES`` (default ``sequential,batched,dask``).

Every mode starts in a fresh process state only as far as JAX allows: the sequential
run goes first and pays the compilation in this process; the dask workers are new
processes and pay it again (with the persistent compilation cache warm). The first
member's time is reported apart (``first_member_s``) so that compilation is visible.

"batched" runs members of one shape in lockstep through the vmapped solver
(:mod:`dynslip.physics.driver.batch`), ``BATCH_SIZE`` members at a time
(:mod:`dynslip.app.sweep_runners`:
``"auto"`` is one member per batch on the CPU, where lockstep pays for its slowest member's
steps, and a worker's whole share on an accelerator), on the in-process or dask workers.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def _base(tmp: Path) -> Path:
    """The method 2 scenario (the shipped file when there is one, else the kind's defaults)."""
    shipped = ROOT / "scenarios" / "method2_let_go.yaml"
    p = tmp / "method2_pinned.yaml"
    p.write_text(shipped.read_text() if shipped.exists() else yaml.safe_dump({"kind": "forming"}))
    return p


def _differences(ref, ds) -> dict:
    """Which variables and attributes differ from the sequential run (empty: identical).

    The tree is shared and edited while a benchmark runs: a dask worker started later can
    import newer simulator code than this process, and ``git_commit`` can move.
    """
    import numpy as np

    diff = {}
    for name in ref.data_vars:
        a, b = ref[name].values, ds[name].values if name in ds else None
        if b is None or a.shape != b.shape:
            diff[name] = "missing or other shape"
        elif a.dtype.kind == "f":
            if not np.array_equal(a, b, equal_nan=True):
                diff[name] = float(np.nanmax(np.abs(a - b)))
        elif not np.array_equal(a, b):
            diff[name] = "differs"
    for key in ref.attrs:
        if ref.attrs[key] != ds.attrs.get(key):
            diff[f"attr:{key}"] = "differs"
    return diff


def run() -> dict:
    from rich.console import Console

    from dynslip.app.sweep import run_sweep

    nodes = int(os.environ.get("DYNSLIP_BENCH_SWEEP_NODES", "20"))
    n = int(os.environ.get("DYNSLIP_BENCH_SWEEP_MEMBERS", "4"))
    modes = os.environ.get("DYNSLIP_BENCH_SWEEP_MODES", "sequential,batched,dask").split(",")
    console = Console(stderr=True)
    out: dict = {"nodes": nodes, "members": n, "machine_cores": os.cpu_count()}
    out["load_average_before"] = os.getloadavg()[
        0
    ]  # the machine is shared: figures scale with load
    with tempfile.TemporaryDirectory(prefix="dynslip-bench-sweep-") as tmp:
        tmp = Path(tmp)
        base = _base(tmp)
        mus = [
            round(1.3 + 0.9 * i / max(n - 1, 1), 6) for i in range(n)
        ]  # mu_s >= mu_k = 1.25 (method2_let_go.yaml)
        spec = {
            "base": base.name,
            "overrides": {"numerics.nodes": nodes, "physics.friction.law": "slip_weakening"},
            "grid": {"physics.friction.mu_s": mus},
        }
        path = tmp / "bench_sweep.yaml"
        path.write_text(yaml.safe_dump(spec))
        datasets = {}
        for mode in modes:
            t0 = time.perf_counter()
            summary = run_sweep(path, out=tmp / mode, mode=mode, console=console, plot=False)
            wall = time.perf_counter() - t0
            members = [json.loads(p.read_text()) for p in (tmp / mode / "members").glob("*.json")]
            walls = sorted(m["wall_s"] for m in members)
            out[mode] = {
                "load_average_1min": os.getloadavg()[0],
                "wall_s": wall,
                "members_per_minute": 60.0 * n / wall,
                "member_s_min": walls[0],
                "member_s_max": walls[-1],
                "n_ok": summary["n_ok"],
                "note": summary["batched"] or "",
            }
            import xarray as xr

            datasets[mode] = xr.load_dataset(tmp / mode / "sweep.nc")
        if "sequential" in out:
            seq = out["sequential"]
            for mode in modes:
                out[mode]["speed_vs_sequential"] = (
                    out[mode]["members_per_minute"] / seq["members_per_minute"]
                )
            # the target, from the steady per-member time (compilation excluded)
            steady = seq["member_s_min"]
            out["estimate_64_members_s_at_this_N"] = 64 * steady
        ref = datasets.get("sequential")
        if ref is not None:
            out["identical_to_sequential"] = {
                m: _differences(ref, ds) for m, ds in datasets.items()
            }
    return out


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    print(json.dumps(run(), indent=2))
