"""Compare two run folders number by number: ``python benchmarks/compare_runs.py RUN_A RUN_B``.

Every numeric variable of ``trajectory.nc`` (a forming run; ``result.nc`` for the static
kinds; xarray, coordinates included) and every number of
``summary.json`` (nested dicts and lists walked; strings and booleans must be equal too) except
the timings (:data:`TIMINGS`), by the largest absolute difference. NaN equals NaN, inf equals
inf of the same sign. Prints the largest differences and exits 1 when one is above the
tolerance (``--tol``, default 1e-12), or when the two differ in shape, keys or variables; 0
otherwise. A run folder is what ``dynslip run --out`` leaves (or its ``.incomplete-*`` copy).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import xarray as xr

#: summary keys that are wall-clock timings, not results (compared nowhere): the forming runs',
#: and the static runs' phases (``t_<phase>_s``)
TIMINGS = {"compile_s", "run_s", "time_per_step_ms", "wall_s", "t_bvp_s", "t_search_s"}

#: the dataset of a run folder: a forming run's trajectory, or a static run's result
DATASETS = ("trajectory.nc", "result.nc")


def _diff_arrays(a: np.ndarray, b: np.ndarray) -> float:
    """The largest absolute difference of two numeric arrays, NaN against NaN and inf against
    the same inf counting 0; inf where the shapes or the non-finite places differ."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return math.inf
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    if same.all():
        return 0.0
    if not (np.isfinite(a) | same).all() or not (np.isfinite(b) | same).all():
        return math.inf
    return float(np.max(np.abs(np.where(same, 0.0, a - b))))


def _numeric(da: xr.DataArray) -> bool:
    return np.issubdtype(da.dtype, np.number) or np.issubdtype(da.dtype, np.bool_)


def compare_trajectories(a: Path, b: Path) -> list[tuple[str, float]]:
    """(name, largest absolute difference) of every numeric variable and coordinate of two
    trajectory files; a variable in one file only counts inf."""
    rows = []
    label = a.name
    with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
        names = sorted(set(da.variables) | set(db.variables))
        for name in names:
            if name not in da.variables or name not in db.variables:
                rows.append((f"{label}:{name} (in one file only)", math.inf))
                continue
            va, vb = da.variables[name], db.variables[name]
            if not (_numeric(va) and _numeric(vb)):
                equal = va.shape == vb.shape and bool(np.all(va.values == vb.values))
                rows.append((f"{label}:{name}", 0.0 if equal else math.inf))
                continue
            rows.append((f"{label}:{name}", _diff_arrays(va.values, vb.values)))
    return rows


def _walk(a, b, path: str, rows: list) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k in TIMINGS:
                continue
            if k not in a or k not in b:
                rows.append((f"{path}.{k} (in one summary only)", math.inf))
            else:
                _walk(a[k], b[k], f"{path}.{k}", rows)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            rows.append((f"{path} (lengths {len(a)}, {len(b)})", math.inf))
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _walk(x, y, f"{path}[{i}]", rows)
    elif (isinstance(a, (int, float)) and not isinstance(a, bool)
          and isinstance(b, (int, float)) and not isinstance(b, bool)):
        rows.append((path, _diff_arrays(np.asarray(a), np.asarray(b))))
    else:  # strings, booleans, None, or a type that changed
        rows.append((path, 0.0 if (type(a) is type(b) and a == b) else math.inf))


def compare_summaries(a: Path, b: Path) -> list[tuple[str, float]]:
    """(key path, largest absolute difference) of every number of two summary.json files, the
    timings left out; a string, boolean or structure that differs counts inf."""
    rows: list = []
    _walk(json.loads(a.read_text()), json.loads(b.read_text()), "summary.json:", rows)
    return rows


def compare_runs(a: Path, b: Path) -> list[tuple[str, float]]:
    """Both comparisons of two run folders, largest difference first."""
    name = next((d for d in DATASETS if (a / d).exists()), DATASETS[0])
    rows = compare_trajectories(a / name, b / name)
    rows += compare_summaries(a / "summary.json", b / "summary.json")
    return sorted(rows, key=lambda r: -r[1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_a", type=Path)
    p.add_argument("run_b", type=Path)
    p.add_argument("--tol", type=float, default=1e-12, help="largest allowed |a - b|")
    p.add_argument("--show", type=int, default=8, help="how many of the largest to print")
    args = p.parse_args(argv)
    rows = compare_runs(args.run_a, args.run_b)
    n_traj = sum(r[0].startswith(DATASETS) for r in rows)
    print(f"{args.run_a} vs {args.run_b}: {n_traj} dataset variables, "
          f"{len(rows) - n_traj} summary values compared (timings left out)")
    for name, d in rows[: args.show]:
        print(f"  {d:.3e}  {name}")
    bad = [r for r in rows if not r[1] <= args.tol]
    print(f"largest difference {rows[0][1] if rows else 0.0:.3e}; "
          f"{len(bad)} above {args.tol:g}: {'FAIL' if bad else 'same'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
