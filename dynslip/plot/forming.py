"""Figures of a forming trajectory, drawn from the dataset alone (docs/trajectory-contract.md).

- ``meridian.png``: meridian snapshots (rho, z) of sheet and ball through the path;
- ``theta_rbar.png``: theta(rbar) on the contact region at the same times;
- ``state_map.png``: space-time map (rbar vs time) of the contact/slip ``state``.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib
import numpy as np
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from dynslip.analysis.paper import ROUGH_END_STATE
from dynslip.data import files as io
from dynslip.plot.style import STATE_LABELS, state_colormap

__all__ = [
    "make_figures",
    "snapshot_indices",
    "meridian",
    "theta_rbar",
    "state_map",
    "plot_meridian",
    "plot_theta",
    "plot_state_map",
]

def snapshot_indices(ds: xr.Dataset, per_stage: int = 2) -> list[int]:
    """Frames at the end of every stage plus ``per_stage - 1`` inside each (sorted, unique)."""
    stage = ds["stage"].values
    idx = {0}
    for s in np.unique(stage):
        where = np.flatnonzero(stage == s)
        for k in range(1, per_stage + 1):
            idx.add(
                int(
                    where[
                        min(
                            len(where) - 1, k * len(where) // per_stage - 1 if k < per_stage else -1
                        )
                    ]
                )
            )
    return sorted(idx)


def _names(ds):
    return json.loads(ds.attrs.get("stage_names", "[]"))


def _label(ds, i):
    names = _names(ds)
    s = int(ds["stage"].values[i])
    return f"t = {float(ds['time'].values[i]):.0f} s ({names[s] if s < len(names) else s})"


def plot_meridian(ds: xr.Dataset, ax, indices):
    cmap = matplotlib.colormaps["viridis"]
    for k, i in enumerate(indices):
        c = cmap(k / max(len(indices) - 1, 1))
        fr = ds.isel(time=i)
        rho, z = fr["rho"].values, fr["z"].values
        ax.plot(rho, z, color=c, lw=1.4, label=_label(ds, i))
        ax.plot(-rho, z, color=c, lw=1.4)
        zb = float(fr["ball_z"])
        ax.add_patch(Circle((0, zb), 1.0, fill=False, color=c, ls=":", lw=0.8))
        ax.plot(
            [float(fr["clamp_rho"]), -float(fr["clamp_rho"])],
            [float(fr["clamp_z"])] * 2,
            "s",
            color=c,
            ms=4,
        )
    ax.set_aspect("equal")
    ax.set_xlabel("rho / R")
    ax.set_ylabel("z / R")
    ax.set_title("meridian snapshots (ball dotted, clamp squares)")
    ax.legend(fontsize=7, loc="lower left")


def plot_theta(ds: xr.Dataset, ax, indices):
    cmap = matplotlib.colormaps["viridis"]
    rbar = ds["rbar"].values
    for k, i in enumerate(indices):
        th = ds["theta"].values[i]
        if np.all(np.isnan(th)):
            continue
        ax.plot(
            rbar, th, "o-", ms=2.5, color=cmap(k / max(len(indices) - 1, 1)), label=_label(ds, i)
        )
    ax.axhline(np.pi / 2, color="k", lw=0.6, ls="--")
    ax.text(0.02, np.pi / 2 + 0.03, "equator", fontsize=7)
    rough = ROUGH_END_STATE
    ax.plot(
        [rough["rbar_max"]],
        [rough["theta_max"]],
        "kx",
        ms=8,
        label=f"paper (rough): rbar_max {rough['rbar_max']:g}, theta_max {rough['theta_max']:g}",
    )
    ax.set_xlabel("rbar / R (material radius)")
    ax.set_ylabel("theta (rad), where in contact")
    ax.set_title("theta(rbar) on the contact region")
    ax.legend(fontsize=7)


def kinetic_mask(ds: xr.Dataset):
    """(time, rbar) True where a node slips with its slip distance past d_c (slip_weakening
    runs: friction at mu_k); None for laws without weakening."""
    if ds.attrs.get("friction_law") != "slip_weakening" or "slip_distance" not in ds:
        return None
    state = ds["state"].values
    return (state >= 2) & (ds["slip_distance"].values >= float(ds.attrs["d_c"]))


def plot_state_map(ds: xr.Dataset, ax, rbar_limit=None):
    state = ds["state"].values.astype(float)
    t = ds["time"].values
    rbar = ds["rbar"].values
    cmap, norm = state_colormap()
    m = ax.pcolormesh(t, rbar, state.T, cmap=cmap, norm=norm, shading="nearest")
    stage = ds["stage"].values
    names = _names(ds)
    for j in np.flatnonzero(np.diff(stage)):
        ax.axvline(t[j + 1], color="k", lw=0.6)
        s = int(stage[j + 1])
        ax.text(
            t[j + 1],
            0.98,
            names[s] if s < len(names) else str(s),
            rotation=90,
            va="top",
            ha="right",
            fontsize=7,
            transform=ax.get_xaxis_transform(),
        )
    kinetic = kinetic_mask(ds)
    if kinetic is not None and kinetic.any():
        # slipping with the slip distance past d_c: sliding at mu_k (unhatched slip: at mu_s onset,
        # weakening)
        ax.contourf(
            t, rbar, kinetic.T.astype(float), levels=[0.5, 1.5], colors="none", hatches=["////"]
        )
        ax.plot([], [], " ", label="//// sliding at mu_k (slip > d_c)")
    contact = ds["rbar_max"].values
    ax.plot(t, contact, "k-", lw=0.8, label="rbar_max (outermost contact)")
    if rbar_limit is None:
        rbar_limit = min(
            float(rbar[-1]),
            1.5 * float(np.nanmax(contact)) if np.isfinite(contact).any() else rbar[-1],
        )
    ax.set_ylim(0, rbar_limit)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("rbar / R")
    ax.set_title("contact and slip state")
    cb = ax.figure.colorbar(m, ax=ax, ticks=[0, 1, 2, 3])
    cb.ax.set_yticklabels(STATE_LABELS, fontsize=7)
    ax.legend(fontsize=7, loc="lower right")


def meridian(ds: xr.Dataset, indices=None) -> Figure:
    """The figure ``meridian.png`` from a trajectory dataset: meridian snapshots (rho, z) of
    sheet, ball and clamp at ``indices`` (default :func:`snapshot_indices`)."""
    fig = Figure(figsize=(7, 7))
    plot_meridian(ds, fig.subplots(), snapshot_indices(ds) if indices is None else indices)
    return fig


def theta_rbar(ds: xr.Dataset, indices=None) -> Figure:
    """The figure ``theta_rbar.png``: theta(rbar) on the contact region at ``indices``."""
    fig = Figure(figsize=(7, 5))
    plot_theta(ds, fig.subplots(), snapshot_indices(ds) if indices is None else indices)
    return fig


def state_map(ds: xr.Dataset) -> Figure:
    """The figure ``state_map.png``: the contact and slip state against time and rbar."""
    fig = Figure(figsize=(9, 5))
    plot_state_map(ds, fig.subplots())
    return fig


def make_figures(ds: xr.Dataset, out: Path) -> list[Path]:
    """Write the three figures into ``out``; returns their paths. The figures are not
    pyplot's (no backend is chosen or changed)."""
    out = Path(out)
    idx = snapshot_indices(ds)
    return [
        io.save_figure(meridian(ds, idx), out / "meridian.png", dpi=120),
        io.save_figure(theta_rbar(ds, idx), out / "theta_rbar.png", dpi=120),
        io.save_figure(state_map(ds), out / "state_map.png", dpi=120),
    ]
