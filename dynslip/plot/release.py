"""The release test's figure, drawn from the trajectory dataset alone.

- :func:`release_force`: the figure ``release_force.png``, a :class:`matplotlib.figure.Figure`
  (not pyplot's: no backend is chosen or changed); :func:`plot_release` writes it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import xarray as xr

from dynslip.analysis.paper import MEASURED_RELEASE_FORCE_N
from dynslip.analysis.release import release_metrics, sheet_force
from dynslip.data import files as io

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["release_force", "plot_release"]


def release_force(ds: xr.Dataset, metrics: dict | None = None) -> Figure:
    """The hold's force (N) against the ball's displacement (mm), the peak up to
    theta_max = pi/2 marked, the measured release force drawn; below it theta_max.
    ``metrics``: :func:`dynslip.analysis.release.release_metrics` of ``ds`` (computed when
    omitted)."""
    from matplotlib.figure import Figure

    if metrics is None:
        metrics = release_metrics(ds)
    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    zb = ds["ball_z"].values
    disp = (zb - zb[0]) * r_mm
    fig = Figure(figsize=(6.4, 6.4), layout="constrained")
    a, b = fig.subplots(2, 1, sharex=True)
    a.plot(
        disp,
        sheet_force(ds) * fs,
        "-",
        color="C0",
        label="force against the sheet (hold less ball drag)",
    )
    a.plot(
        disp, ds["ball_reaction"].values * fs, ":", color="C0", lw=0.8, label="force of the hold"
    )
    # the measured release force is a magnitude: drawn on the side of the run's pull
    sign = -1.0 if metrics["peak_force_N"] < 0 else 1.0
    a.axhline(
        sign * MEASURED_RELEASE_FORCE_N,
        color="k",
        ls=":",
        label=f"measured release force {MEASURED_RELEASE_FORCE_N:g} N (magnitude)",
    )
    a.plot(
        [metrics["peak_displacement_mm"]],
        [metrics["peak_force_N"]],
        "o",
        color="C3",
        label=f"peak {metrics['peak_force_N']:.2f} N (until opening radius R)",
    )
    if metrics.get("displacement_at_opening_R_mm") is not None:
        for ax in (a, b):
            ax.axvline(metrics["displacement_at_opening_R_mm"], color="0.5", ls="--", lw=0.8)
    a.set_ylabel("force (N)")
    a.legend(fontsize=8)
    b.plot(disp, ds["theta_max"].values, color="C1")
    b.axhline(math.pi / 2, color="0.5", ls=":", lw=0.8)
    b.set_ylabel(r"$\theta_{max}$ (rad)")
    b.set_xlabel("ball displacement along the axis (mm, + toward its pole)")
    opened = metrics.get("displacement_at_opening_R_mm")
    fig.suptitle(
        f"peak |force| {abs(metrics['peak_force_N']):.2f} N "
        f"(measured {MEASURED_RELEASE_FORCE_N:g} N); "
        + (
            "the ball tears out (opening radius R reached)"
            if opened is not None
            else "the opening radius R is not reached: the ball stays held"
        ),
        fontsize=9,
    )
    return fig


def plot_release(ds: xr.Dataset, metrics: dict, out: Path) -> Path:
    """Write release_force.png (:func:`release_force`) into ``out``; returns its path."""
    return io.save_figure(release_force(ds, metrics), Path(out) / "release_force.png")
