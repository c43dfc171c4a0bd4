"""Figures of sweeps and trapping windows; they read datasets (or the window's JSON) only.

- :func:`plot_sweep`: one panel per result (trapped, theta_max, rbar_max, opening radius,
  mu_mobilised_max, the trapping windows). One swept field: lines against it. Two numeric
  fields with 3 or more values each: maps. Otherwise lines against the first field,
  one per value of the second; further fields are held at their first value (said in
  the title). Failed members are marked with a red cross, never drawn as "not trapped".
- :func:`plot_window`: trapped(mu) at every evaluated mu, the windows shaded.
"""

from __future__ import annotations

from collections.abc import Hashable
from pathlib import Path

import numpy as np
import xarray as xr

from dynslip.analysis.paper import MEASURED_MU_S
from dynslip.data.files import save_figure
from dynslip.plot.style import pyplot

PANELS = [
    "trapped",
    "theta_max",
    "rbar_max",
    "opening_radius",
    "largest_stretch_lambda_theta",
    "mu_mobilised_max",
    "release_force",
]




def _label(da: xr.DataArray) -> str:
    u = da.attrs.get("units", "1")
    return f"{da.name}" + ("" if u in ("1", "") else f" [{u}]")


def _xvals(coord: xr.DataArray):
    vals = coord.values
    if vals.dtype.kind in "iuf":
        return vals.astype(float), None
    return np.arange(len(vals), dtype=float), [str(v) for v in vals]


def _reduce(ds: xr.Dataset) -> tuple[xr.Dataset, str]:
    """Hold every swept dimension past the first two at its first value."""
    dims = [d for d in ds["status"].dims]
    note = ""
    if len(dims) > 2:
        held = {d: 0 for d in dims[2:]}
        ds = ds.isel(held)
        note = " (" + ", ".join(f"{d}={ds[d].values.item()}" for d in held) + ")"
    return ds, note


def plot_sweep(ds: xr.Dataset, path) -> Path:
    """The sweep's figure (see the module docstring); written atomically to ``path``."""

    plt = pyplot()
    ds, note = _reduce(ds)
    dims = list(ds["status"].dims)
    panels = [p for p in PANELS if p in ds and np.isfinite(ds[p].values.astype(float)).any()]
    has_window = "window_lo" in ds
    n = len(panels) + (1 if has_window else 0)
    ncol = min(3, max(n, 1))
    nrow = max(1, -(-n // ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.4 * nrow), squeeze=False)
    x_dim = dims[0]
    x, ticks = _xvals(ds[x_dim])
    maps = len(dims) == 2 and all(
        ds[d].values.dtype.kind in "iuf" and ds.sizes[d] >= 3 for d in dims
    )
    failed = ds["status"].values != "ok"
    for ax, name in zip(axes.flat, panels, strict=False):
        da = ds[name]
        if maps:
            y, _ = _xvals(ds[dims[1]])
            m = ax.pcolormesh(x, y, da.values.T.astype(float), shading="nearest")
            fig.colorbar(m, ax=ax, label=_label(da))
            fy, fx = np.nonzero(failed.T)
            ax.plot(x[fx], y[fy], "rx", ms=8, label="failed")
            ax.set_ylabel(dims[1])
        elif len(dims) == 1:
            ax.plot(x, da.values.astype(float), "o-")
            ax.plot(x[failed], np.zeros(failed.sum()), "rx", ms=8, label="failed")
            ax.set_ylabel(_label(da))
        else:
            for j in range(ds.sizes[dims[1]]):
                ax.plot(
                    x,
                    da.isel({dims[1]: j}).values.astype(float),
                    "o-",
                    label=f"{dims[1]}={ds[dims[1]].values[j]}",
                )
                f = failed[:, j]
                ax.plot(x[f], np.zeros(f.sum()), "rx", ms=8)
            ax.set_ylabel(_label(da))
            ax.legend(fontsize=7)
        ax.set_xlabel(x_dim)
        if ticks:
            ax.set_xticks(x, ticks, rotation=20, fontsize=7)
        ax.set_title(name + note, fontsize=9)
    if has_window:
        ax = axes.flat[len(panels)]
        _window_panel(ax, ds, dims, x, ticks)
    if not maps and len(x) > 1:  # one x range for every panel, however many points each has
        pad = 0.35 * np.min(np.diff(np.sort(x)))  # room for the window bars (0.5 step wide)
        for ax in list(axes.flat)[:n]:
            ax.set_xlim(x.min() - pad, x.max() + pad)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    out = save_figure(fig, path, dpi=120)
    plt.close(fig)
    return out


def _window_panel(ax, ds: xr.Dataset, dims: list[Hashable], x: np.ndarray, ticks) -> None:
    """Each member's trapping windows as vertical bars over the first swept field."""
    groups = [None] if len(dims) == 1 else list(range(ds.sizes[dims[1]]))
    step = np.min(np.abs(np.diff(x))) if len(x) > 1 else 1.0
    width = 0.5 * step / max(len(groups), 1)
    for g, j in enumerate(groups):
        sub = ds if j is None else ds.isel({dims[1]: j})
        label = None if j is None else f"{dims[1]}={ds[dims[1]].values[j]}"
        offset = (g - (len(groups) - 1) / 2) * width
        for i in range(len(x)):
            lo = sub["window_lo"].values[i]
            hi = sub["window_hi"].values[i]
            for a, b in zip(lo, hi, strict=True):
                if np.isfinite(a) and np.isfinite(b):
                    ax.bar(
                        x[i] + offset,
                        b - a,
                        bottom=a,
                        width=width,
                        color=f"C{g}",
                        alpha=0.7,
                        label=label,
                    )
                    label = None
        none = np.isfinite(sub["n_windows"].values) & (sub["n_windows"].values == 0)
        lo_r, hi_r = _window_range(ds)
        marker_y = np.full(none.sum(), lo_r + 0.03 * (hi_r - lo_r))
        ax.plot(x[none] + offset, marker_y, "x", color=f"C{g}", ms=7)
    ax.set_xlabel(dims[0])
    if ticks:
        ax.set_xticks(x, ticks, rotation=20, fontsize=7)
    ax.set_ylim(*_window_range(ds))
    ax.set_ylabel("mu (trapped; x: no window)")
    ax.set_title("trapping windows", fontsize=8)
    if len(groups) > 1:
        ax.legend(fontsize=7)


def _window_range(ds: xr.Dataset) -> tuple[float, float]:
    """The mu range the windows were searched over (from the sweep file in the attributes)."""
    import json

    try:
        w = json.loads(ds.attrs["sweep"])["window"]
        return float(w["lo"]), float(w["hi"])
    except (KeyError, TypeError, ValueError):
        lo, hi = float(np.nanmin(ds["window_lo"])), float(np.nanmax(ds["window_hi"]))
        return (lo, hi) if hi > lo else (0.0, 1.0)


def plot_window(result: dict, path) -> Path:
    """trapped(mu) at every evaluated mu (failed runs as red crosses), windows shaded."""

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.4 if result.get("resolution_check") else 2.6))
    ev = [(m, v) for m, v in result["evaluations"]]
    ok = [(m, v) for m, v in ev if v is not None]
    ax.plot([m for m, _ in ok], [1.0 if v else 0.0 for _, v in ok], "ko", ms=4, label="runs")
    bad = [m for m, v in ev if v is None]
    ax.plot(bad, [0.5] * len(bad), "rx", ms=8, label="failed")
    for lo, hi in result["windows"]:
        ax.axvspan(lo, hi, color="C2", alpha=0.3)
    ax.set_yticks([0, 1], ["not trapped", "trapped"])
    ax.set_xlabel(result.get("field", "mu"))
    ax.set_xlim(*result["range"])
    ax.set_title(f"trapping windows (tol {result['tol']:g})", fontsize=9)
    ax.legend(fontsize=7, loc="center right")
    says = (result.get("resolution_check") or {}).get("says")
    if says:  # whether the search can be read as physics, beside its windows
        import textwrap

        ax.set_xlabel(
            result.get("field", "mu") + "\n" + "\n".join(textwrap.wrap(says, 95)), fontsize=7
        )
    fig.tight_layout()
    out = save_figure(fig, path, dpi=120)
    plt.close(fig)
    return out


def plot_critical_mu(result: dict, path) -> Path:
    """critical_mu.png: the path's critical mu (lowest window's lower edge, +- half its
    bracket) against the mesh size, with the Richardson value where extrapolable."""

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 3.2))
    pts = [
        (int(n), c["value"], c["err"], bool(c.get("open")), bool(c.get("failed_side")))
        for n, c in result["critical_mu"].items()
        if c
    ]
    if pts:
        ax.errorbar(
            [p[0] for p in pts],
            [p[1] for p in pts],
            yerr=[p[2] for p in pts],
            fmt="ko-",
            capsize=3,
            label="critical mu (window search)",
        )
        low = [
            p for p in pts if p[3]
        ]  # trapped at the range's lower end: mu_c is below it (an upper bound)
        if low:
            ax.plot(
                [p[0] for p in low],
                [p[1] for p in low],
                "wv",
                mec="k",
                ms=9,
                label="open: below the searched range",
            )
        bound = [p for p in pts if p[4]]  # the runs below failed or did not resolve the contact
        if bound:
            ax.plot(
                [p[0] for p in bound],
                [p[1] for p in bound],
                "ws",
                mec="C1",
                ms=9,
                mew=1.5,
                label="below: runs failed or unresolved (a bound)",
            )
    ex = result.get("extrapolation", {})
    if ex.get("extrapolable"):
        ax.axhspan(
            ex["value"] - ex["err"],
            ex["value"] + ex["err"],
            color="C0",
            alpha=0.2,
            label=f"extrapolated {ex['value']:.3f} (order {ex['order']:.2f})",
        )

    ax.axhline(MEASURED_MU_S, color="C3", ls=":", label=f"measured mu_s = {MEASURED_MU_S:g}")
    ax.set_xscale("log")
    ns = sorted(int(n) for n in result["critical_mu"])
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.minorticks_off()
    ax.set_xlabel("nodes N")
    ax.set_ylabel(result.get("field", "mu"))
    ax.set_title("critical mu of the path against the mesh", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    out = save_figure(fig, path, dpi=120)
    plt.close(fig)
    return out
