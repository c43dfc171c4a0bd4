"""Compare the end states of forming runs (e.g. method 1 against method 2).

The last saved frame of each trajectory is its end state (:func:`end_state`): theta(rbar)
on the contact region, theta_max, rbar_max and mu_mobilised_max (largest mobilised
|F_f|/F_N on the end state's contact region); :func:`difference` is the largest
|delta theta| on the region common to two; :func:`compare` gathers both for two or more
runs. The command ``dynslip compare`` (:mod:`dynslip.app.compare`) reads the runs, writes
``compare.json`` and ``compare.png`` and prints the table.
"""

from __future__ import annotations

import numpy as np

__all__ = ["trapped_text", "end_state", "difference", "compare"]


def trapped_text(trapped) -> str:
    """summary.json's ``trapped`` in words: yes, no, or no answer (failed or unresolved; or no
    summary.json beside the trajectory)."""
    return {True: "yes", False: "no"}.get(trapped, "no answer")


def end_state(ds, summary: dict | None = None) -> dict:
    """theta(rbar) on the contact region of the last frame, and its summary figures;
    ``trapped`` from the run's ``summary`` (its summary.json) where given, else None."""
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
        "trapped": None if summary is None else summary.get("trapped"),
    }


def difference(a: dict, b: dict) -> dict:
    """max |theta_a - theta_b| over the material radii in contact in both end states.

    The runs may have different meshes: b is interpolated linearly onto a's nodes,
    within the range where b is in contact.
    """
    rb = b["rbar"][b["contact"]]
    if rb.size < 2 or not a["contact"].any():
        return {
            "max_abs_dtheta": float("nan"),
            "common_rbar_max": float("nan"),
            "rbar": [],
            "dtheta": [],
        }
    sel = a["contact"] & (a["rbar"] <= rb.max()) & (a["rbar"] >= rb.min())
    tb = np.interp(a["rbar"][sel], rb, b["theta"][b["contact"]])
    d = a["theta"][sel] - tb
    return {
        "max_abs_dtheta": float(np.max(np.abs(d))) if d.size else float("nan"),
        "common_rbar_max": float(a["rbar"][sel].max()) if d.size else float("nan"),
        "rbar": a["rbar"][sel].tolist(),
        "dtheta": d.tolist(),
    }


def compare(states: dict) -> dict:
    """``{"runs": ..., "differences": ...}`` of end states (name -> :func:`end_state`, the
    first the reference): each run's trapped (None: no answer), theta_max, rbar_max,
    mu_mobilised_max, and the difference of the reference to each other run (``"A - B"``)."""
    names = list(states)
    ref = states[names[0]]
    result: dict[str, dict] = {"runs": {}, "differences": {}}
    for n in names:
        s = states[n]
        result["runs"][n] = {
            k: s.get(k) for k in ("trapped", "theta_max", "rbar_max", "mu_mobilised_max")
        }
    for n in names[1:]:
        d = difference(ref, states[n])
        result["differences"][f"{names[0]} - {n}"] = {
            "max_abs_dtheta": d["max_abs_dtheta"],
            "common_rbar_max": d["common_rbar_max"],
        }
    return result
