"""The meridian with every body drawn: the sheet at chosen frames, the ball, and bodies of the
apparatus (held, or moving with the clamp), from a saved trajectory; ``world.png`` of a forming
run from its trajectory and its world (:func:`world_figure`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from dynslip.physics.bodies import Sphere
from dynslip.physics.bodies.held import held_entries

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_world", "world_figure", "drawn_ball"]


def plot_world(
    ds: xr.Dataset,
    frames: dict,
    held=(),
    with_clamp=(),
    out: Path | None = None,
    title: str = "",
    with_ball=(),
    limits=((0, 3.2), (-6.5, 2.0)),
    ball=None,
    moved=(),
    zoom=None,
) -> Figure:
    """``frames``: label -> time index. ``held``: bodies in the frame of the run; ``with_clamp``
    and ``with_ball``: bodies displaced by the clamp's or the ball's height of each frame;
    ``moved``: ``(body, shift)`` pairs, displaced by ``shift[i]`` at frame i (the trajectory's
    ``body_z``).
    ``limits``: the axes' ``((rho0, rho1), (z0, z1))``, or None to fit the frames and bodies.
    ``ball``: the ball's body, its outline dotted (None: the unit sphere). ``zoom``: limits of a
    second panel, the same frames drawn closer (the pocket about the ball). Units of R on both
    axes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0 if zoom is None else 10.0, 8.0), constrained_layout=True)
    axes = fig.subplots(1, 1 if zoom is None else 2, squeeze=False)[0]
    for k, ax in enumerate(axes):
        _draw(ax, ds, frames, held, with_clamp, with_ball, ball, moved)
        lim = limits if k == 0 else zoom
        _limits(ax, ds, frames, lim)
        ax.legend(loc="upper right", fontsize=7)
    axes[0].set_title(title + "\nball dotted, moving bodies shaded per frame, held bodies grey",
                      fontsize=9)
    if zoom is not None:
        axes[1].set_title("about the ball", fontsize=9)
    if out is not None:
        fig.savefig(out, dpi=120)
    return fig


def _draw(ax, ds, frames, held, with_clamp, with_ball, ball, moved):
    """The frames' sheet, ball and moving bodies, and the held bodies, on ``ax``."""
    colours = ["tab:blue", "tab:red", "tab:green", "tab:purple"]
    for body in held:
        o = body.outline()
        ax.fill(o[:, 0], o[:, 1], color="0.8", ec="0.4", lw=0.8, zorder=1)
    for (label, i), col in zip(frames.items(), colours, strict=False):
        zb = float(ds["ball_z"].values[i])
        if ball is None:
            th = np.linspace(0, np.pi, 200)
            ax.plot(np.sin(th), zb + np.cos(th), color=col, lw=0.8, ls=":", zorder=2)
        else:
            o = ball.meridian_points(400, zb)
            ax.plot(o[:, 0], o[:, 1], color=col, lw=0.8, ls=":", zorder=2)
        moving = [(b, float(ds["clamp_z"].values[i])) for b in with_clamp]
        moving += [(b, zb) for b in with_ball]
        moving += [(b, float(shift[i])) for b, shift in moved]
        for body, dz in moving:
            o = body.outline(dz)
            ax.fill(o[:, 0], o[:, 1], color=col, alpha=0.15, ec=col, lw=0.8, zorder=1)
        t = float(ds["time"].values[i])
        ax.plot(
            ds["rho"].values[i],
            ds["z"].values[i],
            color=col,
            lw=1.6,
            zorder=3,
            label=f"{label} (t = {t:.0f} s)",
        )
    ax.set_aspect("equal")
    ax.set_xlabel("rho / R")
    ax.set_ylabel("z / R")


def _limits(ax, ds, frames, limits):
    if limits is None:  # the sheet and the ball of the frames drawn, with a margin
        idx = list(frames.values())
        zs = ds["z"].values[idx]
        zb = ds["ball_z"].values[idx]
        ax.set_xlim(0, 1.1 * max(1.0, float(np.nanmax(ds["rho"].values))))
        ax.set_ylim(min(np.nanmin(zs), np.min(zb) - 1.0) - 1.5,
                    max(np.nanmax(zs), np.max(zb) + 1.0) + 0.5)
    else:
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])


def drawn_ball(ball):
    """The ball's body for the figures: None for the unit sphere (drawn as a circle)."""

    return None if isinstance(ball, Sphere) and ball.is_unit else ball


def world_figure(ds: xr.Dataset, world, outcome) -> Figure:
    """``world.png`` of the run of ``world`` (:class:`~dynslip.schema.world.World`: its ball,
    held bodies and name) whose trajectory is ``ds``: the meridian with the ball and every held
    body (the tube's wall, the bottle), at the deepest push, halfway back, the widest contact
    and the end."""
    import textwrap


    entries = held_entries(world.model.bodies)
    moves = [e.moves_with_ball or e.stage or e.free for e in entries]
    held = [e.body for e, m in zip(entries, moves, strict=True) if not m]
    # every moving body at its saved displacement (the ball's height for the bottle)
    moved = [(e.body, ds["body_z"].values[:, k]) for k, (e, m) in
             enumerate(zip(entries, moves, strict=True)) if m]
    theta = ds["theta_max"].values
    widest = int(np.nanargmax(theta)) if np.isfinite(theta).any() else 0
    last = ds.sizes["time"] - 1
    # the deepest push (the sheet's edge lowest, or the ball highest relative to it: the
    # tube's bottom), the widest contact and the end: the pocket's making
    depth = ds["ball_z"].values - ds["z"].values[:, -1]
    deep = int(np.argmax(depth))
    # halfway back from the deepest push: the lip and the neck under the ball while it refills
    after = np.arange(depth.size) >= deep
    half = int(np.argmin(np.where(after, np.abs(depth - 0.5 * (depth[deep] + depth[last])),
                                  np.inf)))
    frames: dict = {}
    for label, i in (("deepest push", deep), ("halfway back", half),
                     ("widest contact", widest), ("end", last)):
        if i not in frames.values():
            frames[label] = i
    end = "\n".join(textwrap.wrap(f"end: {outcome}", 55))
    zb = float(ds["ball_z"].values[last])
    return plot_world(ds, frames, held=held, moved=moved, limits=None,
                      ball=drawn_ball(world.ball), zoom=((0.0, 2.8), (zb - 2.2, zb + 1.4)),
                      title=f"{world.name} (N = {ds.sizes['rbar']})\n{end}")
