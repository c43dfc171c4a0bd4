"""``dynslip fronts TRAJECTORY``: the stick fronts of a saved trajectory, written beside it."""

from __future__ import annotations

import json
from pathlib import Path

from dynslip.analysis.fronts import fronts_dataset
from dynslip.data.files import write_json, write_netcdf
from dynslip.data.trajectory import open_trajectory
from dynslip.plot.fronts import plot_fronts

__all__ = ["run_fronts"]


def run_fronts(trajectory_path, out_dir=None, rest_speed: float | None = None) -> list[Path]:
    """``dynslip fronts``: write ``fronts.nc``, ``fronts.png`` and ``fronts_summary.json``.

    ``out_dir`` defaults to the trajectory's folder; ``rest_speed`` (R/s): see
    :func:`motion_state`. Returns the three paths in that order.
    A file that is not a trajectory of this format version raises
    :class:`~dynslip.errors.InputError`.
    """
    trajectory_path = Path(trajectory_path)
    ds = open_trajectory(trajectory_path)
    out_dir = trajectory_path.parent if out_dir is None else Path(out_dir)
    fr = fronts_dataset(ds, rest_speed)
    stages = json.loads(fr.attrs["stage_summary"])
    return [
        write_netcdf(fr, out_dir / "fronts.nc"),
        plot_fronts(ds, fr, out_dir / "fronts.png"),
        write_json(out_dir / "fronts_summary.json", {"stages": stages}),
    ]
