"""Figures of a forming trajectory, drawn from the dataset alone (docs/trajectory-contract.md).

- ``meridian.png``: meridian snapshots (rho, z) of sheet and ball through the path;
- ``theta_rbar.png``: theta(rbar) on the contact region at the same times;
- ``state_map.png``: space-time map (rbar vs time) of the contact/slip ``state``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from dynslip.analysis.paper import ROUGH_END_STATE
from dynslip.data import files as io
from dynslip.plot.style import STATE_LABELS, state_colormap

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "end_words",
    "make_figures",
    "meridian",
    "outcome_title",
    "plot_meridian",
    "plot_state_map",
    "plot_theta",
    "snapshot_indices",
    "state_map",
    "theta_rbar",
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


def end_words(ds: xr.Dataset) -> str:
    """Where the contact ends in the last frame, from the dataset alone."""
    end = ds.isel(time=-1)
    theta = float(end["theta_max"])
    if not np.isfinite(theta):
        return "no contact at the end"
    return f"contact ends at theta_max = {theta:.3g} rad (rbar_max {float(end['rbar_max']):.3g} R)"


def outcome_title(ds: xr.Dataset, outcome: str | None) -> str:
    """The outcome line of every figure: summary.json's ``outcome`` (trapped or not, where the
    contact ends) where given, else where the contact ends (trapped is in summary.json)."""
    return f"end: {outcome}" if outcome else f"end: {end_words(ds)} (trapped: see summary.json)"


#: one line style per stage (cycled), so that curves of different stages lying on top of
#: each other stay distinguishable
STAGE_STYLES = ("-", "--", "-.", ":")


def _stage_style(ds, i):
    import matplotlib

    s = int(ds["stage"].values[i])
    return matplotlib.colormaps["tab10"](s % 10), STAGE_STYLES[s % len(STAGE_STYLES)], s


def ball_patch(ball, zb: float, **kw):
    """The ball's meridian section as a patch at height ``zb``: the unit circle for None (the
    default sphere), else the body's outline (:meth:`~dynslip.physics.bodies.base.AbstractBody.
    outline`) mirrored about the axis."""
    from matplotlib.patches import Circle, Polygon

    if ball is None:
        return Circle((0, zb), 1.0, **kw)
    o = ball.meridian_points(400, zb)
    return Polygon(np.concatenate([o, (o * [-1.0, 1.0])[::-1]]), closed=True, **kw)


def plot_meridian(ds: xr.Dataset, ax, indices, zoom: bool = False, ball=None):
    """Sheet (mirrored about the axis), ball and clamp at ``indices``: a colour and a line style
    per stage; a ball outline only where the ball has moved (more than 0.05 R) since the last
    one drawn, the end position filled; ``zoom``: the neighbourhood of the ball only. ``ball``:
    the ball's body (:mod:`dynslip.physics.bodies`; None: the unit sphere)."""
    drawn_z: list[float] = []
    last = indices[-1]
    width: dict[int, int] = {}
    for i in indices:
        c, ls, s = _stage_style(ds, i)
        fr = ds.isel(time=i)
        rho, z = fr["rho"].values, fr["z"].values
        lw = 2.6 if i == last else max(0.9, 2.2 - 0.4 * width.setdefault(s, len(width)))
        label = _label(ds, i)
        if i == 0:  # the flat start: thin grey, whatever its stage
            c, ls, lw, label = "0.55", "-", 1.0, "t = 0 s (start)"
        ax.plot(rho, z, color=c, ls=ls, lw=lw, label=label, zorder=3 if i == last else 2)
        ax.plot(-rho, z, color=c, ls=ls, lw=lw, zorder=3 if i == last else 2)
        zb = float(fr["ball_z"])
        if i == last:
            ax.add_patch(ball_patch(ball, zb, facecolor="0.85", edgecolor="k", lw=1.0, zorder=1))
        elif all(abs(zb - q) > 0.05 for q in drawn_z):
            ax.add_patch(ball_patch(ball, zb, fill=False, edgecolor=c, ls="-", lw=0.7, zorder=1))
        drawn_z.append(zb)
        if not zoom:
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
    if zoom:
        # centred on the ball where the sheet wraps it furthest (the end, when it wraps most there)
        th = np.asarray(ds["theta_max"].values, dtype=float)[list(indices)]
        k = indices[int(np.nanargmax(th))] if np.isfinite(th).any() else last
        k = last if np.isfinite(th[-1]) and th[-1] >= np.nanmax(th) - 1e-9 else k
        zb = float(ds["ball_z"].values[k])
        ax.set_xlim(-1.8, 1.8)
        ax.set_ylim(zb - 1.6, zb + 1.6)
        where = (
            "at the end"
            if k == last
            else f"at t = {float(ds['time'].values[k]):.0f} s, the widest contact"
        )
        ax.set_title(f"near the ball {where} (the end position filled grey)", fontsize=9)
    else:
        ax.set_title("whole sheet (clamp: squares; ball outline where it moved)", fontsize=9)


def plot_theta(ds: xr.Dataset, ax, indices):
    rbar = ds["rbar"].values
    for i in indices:
        th = ds["theta"].values[i]
        if np.all(np.isnan(th)):
            continue
        c, ls, _ = _stage_style(ds, i)
        ax.plot(rbar, th, marker="o", ls=ls, ms=2.5, color=c, label=_label(ds, i))
    ax.axhline(np.pi / 2, color="k", lw=0.6, ls="--")
    # at the axes' left edge whatever the rbar range (in data x it fell outside the axes,
    # unseen, and its extent collapsed the constrained layout)
    ax.text(0.01, np.pi / 2, "equator", fontsize=7, va="bottom",
            transform=ax.get_yaxis_transform())
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
    ax.set_title("theta(rbar) on the contact region", fontsize=9)
    ax.legend(fontsize=7)


def kinetic_mask(ds: xr.Dataset):
    """(time, rbar) True where a node slips with its slip distance past d_c (a weakening law,
    slip weakening or adhesive: friction at mu_k); None for laws without weakening."""
    if not float(ds.attrs.get("d_c", 0.0)) > 0 or "slip_distance" not in ds:
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
    ax.set_title("contact and slip state", fontsize=9)
    cb = ax.figure.colorbar(m, ax=ax, ticks=[0, 1, 2, 3])
    cb.ax.set_yticklabels(STATE_LABELS, fontsize=7)
    # the legend sits below the map, never on it
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.13), ncol=2, frameon=False)


def meridian(ds: xr.Dataset, indices=None, outcome: str | None = None, ball=None) -> Figure:
    """The figure ``meridian.png`` from a trajectory dataset: meridian snapshots (rho, z) of
    sheet, ball and clamp at ``indices`` (default :func:`snapshot_indices`, one per stage),
    whole and near the ball; ``outcome``: summary.json's ``outcome`` for the title; ``ball``:
    the ball's body (None: the unit sphere)."""
    from matplotlib.figure import Figure

    idx = snapshot_indices(ds, per_stage=1) if indices is None else indices
    fig = Figure(figsize=(11, 7), layout="constrained")
    ax0, ax1 = fig.subplots(1, 2, width_ratios=[1, 1.3])
    plot_meridian(ds, ax0, idx, ball=ball)
    plot_meridian(ds, ax1, idx, zoom=True, ball=ball)
    handles, labels = ax0.get_legend_handles_labels()
    ax1.legend(
        handles,
        labels,
        fontsize=8,
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        frameon=False,
        title="sheet at (a line style per stage)",
        title_fontsize=8,
    )
    fig.suptitle(f"meridian section\n{outcome_title(ds, outcome)}", fontsize=10)
    return fig


def theta_rbar(ds: xr.Dataset, indices=None, outcome: str | None = None) -> Figure:
    """The figure ``theta_rbar.png``: theta(rbar) on the contact region at ``indices``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 5), layout="constrained")
    plot_theta(
        ds, fig.subplots(), snapshot_indices(ds, per_stage=1) if indices is None else indices
    )
    fig.suptitle(outcome_title(ds, outcome), fontsize=9)
    return fig


def state_map(ds: xr.Dataset, outcome: str | None = None) -> Figure:
    """The figure ``state_map.png``: the contact and slip state against time and rbar."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 5.5), layout="constrained")
    plot_state_map(ds, fig.subplots())
    fig.suptitle(outcome_title(ds, outcome), fontsize=9)
    return fig


def make_figures(ds: xr.Dataset, out: Path, outcome: str | None = None,
                 ball=None) -> list[Path]:
    """Write the three figures into ``out``; returns their paths. ``outcome``: the run's
    answer in words (summary.json's ``outcome``) for their titles; ``ball``: the ball's body
    drawn in the meridian (None: the unit sphere). The figures are not pyplot's (no backend is
    chosen or changed)."""
    out = Path(out)
    idx = snapshot_indices(ds, per_stage=1)
    return [
        io.save_figure(meridian(ds, idx, outcome, ball), out / "meridian.png", dpi=120),
        io.save_figure(theta_rbar(ds, idx, outcome), out / "theta_rbar.png", dpi=120),
        io.save_figure(state_map(ds, outcome), out / "state_map.png", dpi=120),
    ]
