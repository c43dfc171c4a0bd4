"""fit.png: the observations against the fit (``dynslip fit``), from ``fit.json`` and the run
at the optimum."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynslip.data.files import save_figure
from dynslip.plot.style import pyplot

__all__ = ["plot_fit"]


def plot_fit(result: dict, path) -> Path:
    """Left: each observation's value +- its uncertainty against the model at the scan's best
    point and at the optimum (a bound drawn as its limit). Right: theta(rbar) of the optimum's
    end state (its trajectory, where written) with the observed points and the edge
    (rbar_max, theta_max) with their uncertainties."""
    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8))
    rows = result["residuals"]
    y = np.arange(len(rows))
    for i, r in enumerate(rows):
        v, s = r["value"], r["uncertainty"]
        scale = abs(v) if v else 1.0
        if r["kind"] == "bound":
            ax.plot([v / scale], [i], "k|", ms=14)
            ax.annotate("bound", (v / scale, i), textcoords="offset points", xytext=(4, 6),
                        fontsize=7)
        else:
            ax.errorbar([v / scale], [i], xerr=[s / scale], fmt="s", color="k", mfc="none",
                        capsize=3, label="observed +- 1 sd" if i == 0 else None)
        ax.plot([r["model"] / scale], [i], "o", color="tab:red", zorder=3,
                label="fit" if i == 0 else None)
    ax.set_yticks(y, [f"{r['name']} ({r['unit']})" for r in rows], fontsize=8)
    ax.set_xlabel("value / observed value")
    ax.set_title(f"cost {result['cost']:.3g}", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    ax.invert_yaxis()
    _theta_rbar(bx, result)
    best = ", ".join(f"{n.rsplit('.', 1)[-1]} = {v:.4g}" for n, v in result["best"].items())
    fig.suptitle(f"fit: {best}", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def _theta_rbar(ax, result: dict) -> None:
    folder = (result.get("optimum_run") or {}).get("folder")
    traj = Path(folder) / "trajectory.nc" if folder else None
    if traj is not None and traj.is_file():
        import xarray as xr

        with xr.open_dataset(traj) as ds:
            end = ds.isel(time=-1)
            rbar = ds["rbar"].values
            theta = np.arctan2(end["rho"].values, end["z"].values - float(end["ball_z"]))
            contact = np.asarray(end["state"].values) > 0
            ax.plot(rbar, theta, "-", color="0.6", lw=1, label="fit: polar angle of each circle")
            ax.plot(rbar[contact], theta[contact], ".", color="tab:red", ms=4,
                    label="fit: in contact")
            if "theta_edge" in end:
                ax.plot([float(end["rbar_edge"])], [float(end["theta_edge"])], "*",
                        color="tab:red", ms=10, label="fit: located edge")
    obs = {r["name"]: r for r in result["residuals"]}
    pts = [(float(n.split("=")[1].rstrip(")")), r) for n, r in obs.items()
           if n.startswith("theta(rbar=")]
    if pts:
        ax.errorbar([p for p, _ in pts], [r["value"] for _, r in pts],
                    yerr=[r["uncertainty"] for _, r in pts], fmt="ks", capsize=3,
                    label="observed theta(rbar)")
    if "theta_max" in obs and "rbar_max" in obs:
        t, rb = obs["theta_max"], obs["rbar_max"]
        ax.errorbar([rb["value"]], [t["value"]], xerr=[rb["uncertainty"]],
                    yerr=[t["uncertainty"]], fmt="D", color="k", mfc="none", capsize=3,
                    label="observed edge")
    ax.axhline(np.pi / 2, color="0.8", lw=0.8, ls="--")
    ax.set_xlabel("rbar (material radius / R)")
    ax.set_ylabel("theta (rad)")
    ax.set_xlim(0, 1.5)
    ax.legend(fontsize=7, loc="lower right")
