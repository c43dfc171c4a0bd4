"""``dynslip compare RUN_A RUN_B ...``: the end states of forming runs side by side.

Reads each run's ``trajectory.nc`` (a run folder or the file itself), compares the end
states (:mod:`dynslip.analysis.compare`), writes ``compare.json`` and ``compare.png``
(:mod:`dynslip.plot.compare`) into ``out`` (default ``outputs/compare/``) and prints
the table.
"""

from __future__ import annotations

import json
from pathlib import Path

from dynslip.analysis.compare import compare, end_state, trapped_text
from dynslip.data.files import write_json
from dynslip.data.trajectory import TRAJECTORY_FILE, open_trajectory
from dynslip.errors import InputError
from dynslip.plot.compare import plot_compare

__all__ = ["run_compare"]


def _traj_path(p: Path) -> Path:
    p = Path(p)
    return p / TRAJECTORY_FILE if p.is_dir() else p


def _summary(p: Path) -> dict | None:
    """The run's ``summary.json`` beside its trajectory (whether it trapped), or None."""
    f = _traj_path(p).parent / "summary.json"
    if not f.is_file():
        return None
    try:
        return json.loads(f.read_text())
    except (OSError, ValueError):
        return None


def run_compare(runs: list[Path], out: Path | None = None, console=None) -> dict:
    """Compare the end states of two or more saved forming runs."""
    if len(runs) < 2:
        raise InputError(f"runs: {len(runs)} given; compare needs at least two run folders")
    out = Path(out) if out else Path("outputs") / "compare"
    states = {}
    for r in runs:
        ds = open_trajectory(_traj_path(r))
        states[str(r)] = end_state(ds, _summary(r))
        ds.close()
    result = compare(states)
    plot_compare(states, out / "compare.png")
    write_json(out / "compare.json", result)
    if console is not None:
        _print(console, result)
    return result


def _print(console, result: dict) -> None:
    from rich.table import Table

    t = Table(title="end states")
    names = list(result["runs"])
    # a run's name is never cut: the column is as wide as the longest name (folded, never
    # ellipsised, on a terminal narrower than that)
    t.add_column("run", min_width=max(len(n) for n in names), overflow="fold", no_wrap=False)
    for c in ("trapped", "theta_max", "rbar_max", "mu_mobilised_max"):
        t.add_column(c, justify="right", overflow="fold")
    for n, v in result["runs"].items():
        t.add_row(
            n,
            trapped_text(v["trapped"]),
            f"{v['theta_max']:.4f}",
            f"{v['rbar_max']:.4f}",
            f"{v['mu_mobilised_max']:.4f}",
        )
    console.print(t, crop=False)
    for k, v in result["differences"].items():
        console.print(
            f"max |delta theta| ({k}) = {v['max_abs_dtheta']:.4g} rad on rbar <= "
            f"{v['common_rbar_max']:.3f}",
            crop=False,
            soft_wrap=True,
        )
