"""``dynslip compare RUN_A RUN_B ...``: the end states of forming runs side by side.

Reads each run's ``trajectory.nc`` (a run folder or the file itself), compares the end
states (:mod:`dynslip.analysis.compare`), writes ``compare.json`` and ``compare.png``
(:mod:`dynslip.plot.compare`) into ``out`` (default ``outputs/compare/``) and prints
the table.
"""

from __future__ import annotations

from pathlib import Path

from dynslip.analysis.compare import compare, end_state
from dynslip.data.files import write_json
from dynslip.data.trajectory import open_trajectory
from dynslip.errors import InputError
from dynslip.plot.compare import plot_compare

__all__ = ["run_compare"]


def _traj_path(p: Path) -> Path:
    p = Path(p)
    return p / "trajectory.nc" if p.is_dir() else p


def run_compare(runs: list[Path], out: Path | None = None, console=None) -> dict:
    """Compare the end states of two or more saved forming runs."""
    if len(runs) < 2:
        raise InputError(f"runs: {len(runs)} given; compare needs at least two run folders")
    out = Path(out) if out else Path("outputs") / "compare"
    states = {}
    for r in runs:
        ds = open_trajectory(_traj_path(r))
        states[str(r)] = end_state(ds)
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
    for c in ("run", "theta_max", "rbar_max", "mu_mobilised_max"):
        t.add_column(c)
    for n, v in result["runs"].items():
        t.add_row(
            n, f"{v['theta_max']:.4f}", f"{v['rbar_max']:.4f}", f"{v['mu_mobilised_max']:.4f}"
        )
    console.print(t)
    for k, v in result["differences"].items():
        console.print(
            f"max |delta theta| ({k}) = {v['max_abs_dtheta']:.4g} rad on rbar <= "
            f"{v['common_rbar_max']:.3f}"
        )
