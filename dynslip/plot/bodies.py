"""The state map of one held body: each node's contact and slip state relative to the body
(free, stuck, slipping toward decreasing or increasing s, touching a frictionless body;
:mod:`dynslip.physics.bodies.observe`) against time and material radius, beside the contact's
extent in the body's surface coordinate s. ``dynslip fronts TRAJ --body NAME``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from dynslip.data.files import save_figure
from dynslip.data.trajectory import BODY_STATE_MEANINGS, body_index, stage_names
from dynslip.plot.forming import outcome_title
from dynslip.plot.style import STATE_COLORS

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["BODY_STATE_COLORS", "body_state_map", "plot_body_state"]

BODY_STATE_COLORS = (*STATE_COLORS, "#5aa469")
"""Colours of the ``body_state`` flags: the ball's four, and touching a frictionless body."""


def _stage_lines(ds, ax, t):
    stage = np.asarray(ds["stage"].values).astype(int)
    names = stage_names(ds)
    for j in np.flatnonzero(np.diff(stage)):
        ax.axvline(t[j + 1], color="k", lw=0.6)
        s = int(stage[j + 1])
        ax.text(t[j + 1], 0.98, names[s] if s < len(names) else str(s), rotation=90, va="top",
                ha="right", fontsize=7, transform=ax.get_xaxis_transform())


def body_state_map(ds: xr.Dataset, name: str, outcome: str | None = None) -> Figure:
    """The figure of held body ``name``'s state map (an unknown name raises
    :class:`~dynslip.errors.InputError`): left the state against time and material radius
    (zoomed to the nodes that touch it, the ball's outermost contact dotted), right the
    contact's extent in s and the nodes in contact."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch


    k = body_index(ds, name)
    t = np.asarray(ds["time"].values, float)
    rbar = np.asarray(ds["rbar"].values, float)
    state = np.asarray(ds["body_state"].values[:, k, :], float)
    fig = Figure(figsize=(11, 5.5), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, width_ratios=[1.4, 1.0])
    cmap = ListedColormap(BODY_STATE_COLORS)
    norm = BoundaryNorm(np.arange(len(BODY_STATE_COLORS) + 1) - 0.5, len(BODY_STATE_COLORS))
    ax.pcolormesh(t, rbar, state.T, cmap=cmap, norm=norm, shading="nearest", rasterized=True)
    ax.plot(t, ds["rbar_max"].values, "k:", lw=0.8, label="the ball's outermost contact")
    touched = np.flatnonzero((state > 0).any(axis=0))
    if touched.size:
        dr = float(np.diff(rbar).max())
        ax.set_ylim(max(rbar[0], rbar[touched[0]] - 6 * dr), min(rbar[-1], rbar[touched[-1]]
                    + 3 * dr) + 0.5 * dr)
    _stage_lines(ds, ax, t)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(r"material radius $\bar r / R$")
    ax.set_title(f"{name}: contact and slip state relative to the body", fontsize=9)
    used = sorted({int(v) for v in np.unique(state)} | {0, 1, 2, 3})
    handles = [Patch(color=BODY_STATE_COLORS[v], label=BODY_STATE_MEANINGS[v].replace("_", " "))
               for v in used]
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=2,
              frameon=False)
    r_mm = float(ds.attrs.get("R_m", np.nan)) * 1e3
    lo, hi = (np.asarray(ds[v].values[:, k], float) * r_mm for v in ("body_s_min", "body_s_max"))
    ax2.fill_between(t, lo, hi, color=STATE_COLORS[1], alpha=0.3, step="mid", lw=0)
    ax2.plot(t, lo, color=STATE_COLORS[1], lw=1.0, label="lowest s in contact")
    ax2.plot(t, hi, color=STATE_COLORS[3], lw=1.0, label="highest s in contact")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("surface coordinate s along the body's profile (mm)")
    ax2.set_title("the contact's extent on the body", fontsize=9)
    n = np.asarray(ds["body_n_contact"].values[:, k])
    ax3 = ax2.twinx()
    ax3.plot(t, n, color="0.4", lw=0.8, ls="--", label="nodes in contact")
    ax3.set_ylabel("nodes in contact", color="0.4")
    ax3.set_ylim(0, max(1, int(n.max())) * 1.15)
    _stage_lines(ds, ax2, t)
    if not np.isfinite(lo).any():
        ax2.text(0.5, 0.5, "never in contact", transform=ax2.transAxes, ha="center")
    h2, l2 = ax2.get_legend_handles_labels()
    h3, l3 = ax3.get_legend_handles_labels()
    ax2.legend(h2 + h3, l2 + l3, fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.12),
               ncol=2, frameon=False)
    fig.suptitle(outcome_title(ds, outcome), fontsize=9)
    return fig


def plot_body_state(ds: xr.Dataset, name: str, path, outcome: str | None = None) -> Path:
    """Write :func:`body_state_map` of held body ``name`` to ``path``; returns the path."""
    return save_figure(body_state_map(ds, name, outcome), path, dpi=120)
