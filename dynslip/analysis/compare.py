"""Compare the end states of forming runs (e.g. method 1 against method 2).

``dynslip compare RUN_A RUN_B ...`` reads each run's ``trajectory.nc`` (a run folder
or the file itself), takes the last saved frame as the end state, and reports
theta(rbar) of each on the contact region, the largest |delta theta| on the region
common to all, and each run's theta_max, rbar_max and mu_mobilised_max (largest mobilised
|F_f|/F_N on the end state's contact region). Writes ``compare.json`` and
``compare.png`` into ``--out`` (default ``outputs/compare/``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynslip.errors import InputError


def _traj_path(p: Path) -> Path:
    p = Path(p)
    return p / "trajectory.nc" if p.is_dir() else p


def end_state(ds) -> dict:
    """theta(rbar) on the contact region of the last frame, and its summary figures."""
    last = ds.isel(time=-1)
    rbar = np.asarray(ds["rbar"].values, float)
    theta = np.asarray(last["theta"].values, float)
    mob = np.asarray(last["mu_mobilised"].values, float)
    contact = np.isfinite(theta)
    return {
        "rbar": rbar,
        "theta": theta,
        "contact": contact,
        "theta_max": float(last["theta_max"].values),
        "rbar_max": float(last["rbar_max"].values),
        "mu_mobilised_max": float(np.nanmax(mob)) if np.isfinite(mob).any() else float("nan"),
    }


def difference(a: dict, b: dict) -> dict:
    """max |theta_a - theta_b| over the material radii in contact in both end states.

    The runs may have different meshes: b is interpolated linearly onto a's nodes,
    within the range where b is in contact.
    """
    rb = b["rbar"][b["contact"]]
    if rb.size < 2 or not a["contact"].any():
        return {"max_abs_dtheta": float("nan"), "common_rbar_max": float("nan"), "rbar": [], "dtheta": []}
    sel = a["contact"] & (a["rbar"] <= rb.max()) & (a["rbar"] >= rb.min())
    tb = np.interp(a["rbar"][sel], rb, b["theta"][b["contact"]])
    d = a["theta"][sel] - tb
    return {
        "max_abs_dtheta": float(np.max(np.abs(d))) if d.size else float("nan"),
        "common_rbar_max": float(a["rbar"][sel].max()) if d.size else float("nan"),
        "rbar": a["rbar"][sel].tolist(),
        "dtheta": d.tolist(),
    }


def run_compare(runs: list[Path], out: Path | None = None, console=None) -> dict:
    """Compare the end states of two or more saved forming runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dynslip.data.files import save_figure, write_json
    from dynslip.data.trajectory import open_trajectory

    if len(runs) < 2:
        raise InputError(f"runs: {len(runs)} given; compare needs at least two run folders")
    out = Path(out) if out else Path("outputs") / "compare"
    states = {}
    for r in runs:
        ds = open_trajectory(_traj_path(r))
        states[str(r)] = end_state(ds)
        ds.close()
    names = list(states)
    ref = states[names[0]]
    result = {"runs": {}, "differences": {}}
    for n in names:
        s = states[n]
        result["runs"][n] = {k: s[k] for k in ("theta_max", "rbar_max", "mu_mobilised_max")}
    for n in names[1:]:
        d = difference(ref, states[n])
        result["differences"][f"{names[0]} - {n}"] = {
            "max_abs_dtheta": d["max_abs_dtheta"],
            "common_rbar_max": d["common_rbar_max"],
        }

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for n in names:
        s = states[n]
        ax0.plot(s["rbar"][s["contact"]], s["theta"][s["contact"]], label=f"{n} (mu_mobilised_max {s['mu_mobilised_max']:.3g})")
    ax0.set_xlabel(r"$\bar r$ (material radius / R)")
    ax0.set_ylabel(r"$\theta$ (rad)")
    ax0.set_title("end states on the contact region")
    ax0.legend(fontsize=8)
    for n in names[1:]:
        d = difference(ref, states[n])
        ax1.plot(d["rbar"], d["dtheta"], label=f"{names[0]} - {n}")
    ax1.axhline(0, color="0.6", lw=0.8)
    ax1.set_xlabel(r"$\bar r$")
    ax1.set_ylabel(r"$\Delta\theta$ (rad)")
    ax1.set_title("difference on the common contact region")
    ax1.legend(fontsize=8)
    save_figure(fig, out / "compare.png", dpi=120)
    plt.close(fig)
    write_json(out / "compare.json", result)
    if console is not None:
        from rich.table import Table

        t = Table(title="end states")
        for c in ("run", "theta_max", "rbar_max", "mu_mobilised_max"):
            t.add_column(c)
        for n, v in result["runs"].items():
            t.add_row(n, f"{v['theta_max']:.4f}", f"{v['rbar_max']:.4f}", f"{v['mu_mobilised_max']:.4f}")
        console.print(t)
        for k, v in result["differences"].items():
            console.print(f"max |delta theta| ({k}) = {v['max_abs_dtheta']:.4g} rad on rbar <= {v['common_rbar_max']:.3f}")
    return result
