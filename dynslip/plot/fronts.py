"""Figures of stick fronts, drawn from a trajectory and its fronts dataset
(:mod:`dynslip.analysis.fronts`): the space-time map of the contact state with the front
tracks on top (:func:`draw_spacetime`, also the right panel of the animations) and the
``fronts.png`` figure (:func:`plot_fronts`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from dynslip.analysis.front_summary import rest_speed_of
from dynslip.analysis.fronts import BIRTH_EVENTS, DEATH_EVENTS, motion_state
from dynslip.data.files import save_figure
from dynslip.data.trajectory import stage_names
from dynslip.plot.forming import outcome_title
from dynslip.plot.style import STATE_COLORS, STATE_LABELS, pyplot, state_colormap

__all__ = ["draw_spacetime", "plot_fronts"]


def draw_spacetime(ax, ds: xr.Dataset, fronts: xr.Dataset | None = None, legend: bool = True):
    """Draw the space-time map of ``state`` (rbar across, time up) on ``ax``, fronts on top.

    The state is classified as the fronts were (:func:`motion_state`, attribute
    ``rest_speed`` of ``fronts``)."""
    from matplotlib.patches import Patch

    cmap, norm = state_colormap()
    t = np.asarray(ds["time"].values, dtype=float)
    rbar = np.asarray(ds["rbar"].values, dtype=float)
    ax.pcolormesh(
        _edges(rbar),
        _edges(t),
        motion_state(ds, rest_speed_of(fronts)),
        cmap=cmap,
        norm=norm,
        shading="flat",
        rasterized=True,
    )
    ax.plot(ds["rbar_max"].values, t, color="k", lw=0.8, ls=":", label="outermost contact")
    rmax = np.asarray(ds["rbar_max"].values, dtype=float)
    rmax = rmax[np.isfinite(rmax)]
    right = (
        rbar[-1]
        if rmax.size == 0
        else min(rbar[-1], 1.25 * rmax.max() + 2 * float(np.diff(rbar).max()))
    )
    stage = np.asarray(ds["stage"].values).astype(int)
    names = stage_names(ds)
    for change in np.flatnonzero(np.diff(stage) != 0) + 1:
        tb = 0.5 * (t[change - 1] + t[change])
        ax.axhline(tb, color="k", lw=0.6, ls="--")
    for s in np.unique(stage):
        first = np.flatnonzero(stage == s)[0]
        ax.text(
            right,
            t[first],
            f" {names[s] if s < len(names) else s}",
            va="bottom",
            ha="right",
            fontsize=7,
        )
    if fronts is not None and fronts.sizes.get("track", 0):
        pos = np.asarray(fronts["front_rbar"].values)
        for k in range(pos.shape[0]):
            ok = np.isfinite(pos[k])
            ax.plot(pos[k, ok], t[ok], color="k", lw=1.2)
        births = np.asarray(fronts["birth_event"].values)
        deaths = np.asarray(fronts["death_event"].values)
        t_birth = np.asarray(fronts["birth_time"].values, dtype=float)
        t_death = np.asarray(fronts["death_time"].values, dtype=float)
        for k in range(pos.shape[0]):
            ok = np.flatnonzero(np.isfinite(pos[k]))
            if ok.size == 0:
                continue
            # events only where they happen inside the time range shown
            if BIRTH_EVENTS[births[k]] != "run_start" and t_birth[k] == t[ok[0]]:
                ax.plot(pos[k, ok[0]], t[ok[0]], "o", ms=3.5, mfc="w", mec="k")
            if DEATH_EVENTS[deaths[k]] != "run_end" and t_death[k] == t[ok[-1]]:
                ax.plot(pos[k, ok[-1]], t[ok[-1]], "x", ms=4, color="k")
    ax.set_xlabel(r"material radius $\bar r / R$")
    ax.set_ylabel("time (s)")
    ax.set_xlim(rbar[0], right)
    if legend:
        handles = [Patch(color=c, label=m) for c, m in zip(STATE_COLORS, STATE_LABELS, strict=True)]
        ax.legend(
            handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2
        )


def _edges(x: np.ndarray) -> np.ndarray:
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = 0.5 * (x[1:] + x[:-1])
    return np.r_[x[0] - (mid[0] - x[0]), mid, x[-1] + (x[-1] - mid[-1])]


def plot_fronts(ds: xr.Dataset, fronts: xr.Dataset, path, outcome: str | None = None) -> Path:
    """Figure: fronts over the space-time map; front angle and speed against time; titled
    with the run's ``outcome`` (summary.json's, else where the contact ends)."""
    plt = pyplot()

    t = np.asarray(ds["time"].values, dtype=float)
    fig, axes = plt.subplots(1, 3, figsize=(13, 5.2), constrained_layout=True)
    fig.suptitle(outcome_title(ds, outcome), fontsize=10)
    draw_spacetime(axes[0], ds, fronts)
    axes[0].set_title("stick fronts over the contact state\n(o born, x removed)", fontsize=9)
    pos_t = np.asarray(fronts["front_theta"].values)
    spd = np.asarray(fronts["front_rbar_speed"].values)
    axes[1].plot(
        t, ds["theta_max"].values, color="0.5", lw=1, ls=":", label=r"contact edge $\theta_{max}$"
    )
    for k in range(pos_t.shape[0]):
        c = STATE_COLORS[1] if fronts["stuck_side"].values[k] == 1 else STATE_COLORS[3]
        axes[1].plot(t, pos_t[k], color=c, lw=1.2)
        axes[2].plot(t, spd[k], color=c, lw=1.0)
    axes[1].plot([], [], color=STATE_COLORS[1], label="stuck on the pole side")
    axes[1].plot([], [], color=STATE_COLORS[3], label="stuck on the equator side")
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel(r"front polar angle $\theta$ (rad)")
    axes[1].legend(fontsize=7)
    axes[2].axhline(0, color="k", lw=0.5)
    axes[2].set_xlabel("time (s)")
    axes[2].set_ylabel(r"front speed $d\bar r/dt$ (R/s), + toward equator")
    for ax in axes[1:]:
        stage = np.asarray(ds["stage"].values).astype(int)
        for change in np.flatnonzero(np.diff(stage) != 0) + 1:
            ax.axvline(0.5 * (t[change - 1] + t[change]), color="k", lw=0.6, ls="--")
    path = save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
