"""``dynslip fronts TRAJECTORY``: the stick fronts of a saved trajectory, written beside it."""

from __future__ import annotations

import json
import re
from pathlib import Path

from dynslip.analysis.front_summary import fronts_dataset
from dynslip.data.files import write_json, write_netcdf
from dynslip.data.trajectory import body_index, open_trajectory
from dynslip.plot.bodies import plot_body_state
from dynslip.plot.fronts import plot_fronts

__all__ = ["run_fronts", "summary_lines"]


def run_fronts(trajectory_path, out_dir=None, rest_speed: float | None = None,
               body: str | None = None) -> list[Path]:
    """``dynslip fronts``: write ``fronts.nc``, ``fronts.png`` and ``fronts_summary.json``;
    with ``body`` (a held body's name, ``physics.named_bodies()``) only that body's state map,
    ``state_map_<name>.png`` (:mod:`dynslip.plot.bodies`; an unknown name raises
    :class:`~dynslip.errors.InputError` and writes nothing).

    ``out_dir`` defaults to the trajectory's folder; ``rest_speed`` (R/s): see
    :func:`motion_state`. Returns the three paths in that order.
    A file that is not a trajectory of this format version raises
    :class:`~dynslip.errors.InputError`.
    """
    trajectory_path = Path(trajectory_path)
    ds = open_trajectory(trajectory_path)
    out_dir = trajectory_path.parent if out_dir is None else Path(out_dir)
    if body is not None:

        body_index(ds, body)  # InputError before anything is written
        slug = re.sub(r"[^A-Za-z0-9]+", "_", body).strip("_").lower() or "body"
        return [plot_body_state(ds, body, out_dir / f"state_map_{slug}.png",
                                _outcome(trajectory_path))]
    fr = fronts_dataset(ds, rest_speed)
    stages = json.loads(fr.attrs["stage_summary"])
    return [
        write_netcdf(fr, out_dir / "fronts.nc"),
        plot_fronts(ds, fr, out_dir / "fronts.png", _outcome(trajectory_path)),
        write_json(out_dir / "fronts_summary.json", {"stages": stages}),
    ]


def _outcome(trajectory_path: Path) -> str | None:
    """The run's ``outcome`` from the summary.json beside its trajectory, or None."""
    f = trajectory_path.parent / "summary.json"
    try:
        return json.loads(f.read_text()).get("outcome") if f.is_file() else None
    except (OSError, ValueError, AttributeError):
        return None


def summary_lines(stages: list[dict]) -> list[str]:
    """One line per stage for the command line: front direction and rest order."""
    out = []
    for e in stages:
        if not e.get("frames"):
            out.append(f"{e['name']}: no saved frame")
            continue
        line = (
            f"{e['name']} ({e['t_start_s']:.4g}-{e['t_end_s']:.4g} s): {e['n_tracks']} front(s), "
            f"travel {e['front_direction'].replace('_', ' ')}"
        )
        if e.get("last_to_rest_rbar"):
            n_last = len(e["last_to_rest_rbar"])
            at_once = f" ({n_last} nodes at once)" if n_last > 1 else ""
            line += (
                f"; last to come to rest at rbar = {max(e['last_to_rest_rbar']):.3g}{at_once} "
                f"(t = {e['last_rest_time_s']:.4g} s); outermost contact rests last: "
                f"{'yes' if e['outermost_contact_rests_last'] else 'no'}"
            )
        if e.get("n_nodes_slipping_at_end"):
            line += f"; {e['n_nodes_slipping_at_end']} node(s) still slipping at the end"
        out.append(line)
    return out
