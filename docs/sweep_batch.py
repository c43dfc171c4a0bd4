"""Run a sweep file as ``dynslip sweep`` does, with what its command line does not set: the
size of a lockstep batch, the mesh size of every member, and fewer values per grid axis.

    python docs/sweep_batch.py SWEEP [--mode batched] [--batch-size 32] [--nodes 20] [--head 2]

The sweep goes to ``sweep/`` in the working folder (``summary.json``, ``members/``,
``sweep.nc``); ``wall.json`` there holds the wall time of the whole sweep. ``--batch-size``
sets :data:`dynslip.app.sweep_runners.BATCH_SIZE` (default its ``"auto"``: one member per
batch on the CPU). ``--nodes`` and ``--head`` rewrite a copy of the sweep file (its scenario
paths made absolute) in the working folder: ``numerics.nodes`` among its overrides, and each
grid axis cut to its first values. docs/results.py runs it for the tables of docs/sweeps.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml


def _absolute(value, folder: Path):
    """A scenario path (a string ending in .yaml) made absolute against ``folder``."""
    if isinstance(value, str) and value.endswith((".yaml", ".yml")):
        return str((folder / value).resolve())
    if isinstance(value, list):
        return [_absolute(v, folder) for v in value]
    return value


def rewritten(path: Path, nodes: int | None, head: int | None) -> Path:
    """A copy of the sweep file in the working folder with ``nodes`` and ``head`` applied."""
    data = yaml.safe_load(path.read_text())
    data["base"] = _absolute(data.get("base"), path.parent)
    grid = data.get("grid") or {}
    for key, axis in list(grid.items()):
        axis = _absolute(axis, path.parent)
        if head and isinstance(axis, list):
            axis = axis[:head]
        elif head and isinstance(axis, dict) and "num" in axis:
            axis = {**axis, "num": min(head, int(axis["num"]))}
        grid[key] = axis
    if head and isinstance(data.get("list"), list):
        data["list"] = data["list"][:head]
    if nodes:
        data.setdefault("overrides", {})["numerics.nodes"] = nodes
    out = Path.cwd() / path.name
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sweep", type=Path)
    p.add_argument("--mode", default="sequential", choices=("sequential", "batched", "dask"))
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--nodes", type=int, default=None)
    p.add_argument("--head", type=int, default=None)
    a = p.parse_args(argv)
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    from dynslip.app import sweep_runners
    from dynslip.app.sweep import run_sweep

    root = Path(__file__).resolve().parents[1]
    path = a.sweep if a.sweep.is_absolute() else root / a.sweep
    if a.nodes or a.head:
        path = rewritten(path, a.nodes, a.head)
    if a.batch_size:
        sweep_runners.BATCH_SIZE = a.batch_size
    out = Path.cwd() / "sweep"
    from dynslip.errors import ComputationError

    t0 = time.perf_counter()
    try:
        run_sweep(path, out=out, mode=a.mode, plot=False)
    except ComputationError as err:  # every member failed; its summary is written: exit 3
        print(f"sweep_batch: {err}", file=sys.stderr)
        return 3
    finally:
        if out.is_dir():
            (out / "wall.json").write_text(json.dumps({"wall_s": time.perf_counter() - t0}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
