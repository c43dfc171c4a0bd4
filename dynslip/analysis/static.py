"""The static computation of one material (paper Section 3): the selected fully mobilised
member (the boundary-value problem, :mod:`dynslip.physics.static.family`), the paper's march
and $\\mu$ search from the stated initial shape (:mod:`dynslip.physics.static.search`), the
fields, checks and extrema of the result, and its summary.

A search that finds no root returns what it computed with ``status = "failed"`` and an
``error`` (nothing is raised here).
"""

from __future__ import annotations

import time
from typing import cast

import numpy as np

from dynslip.analysis.paper import MODEL_LABELS as LABEL
from dynslip.analysis.paper import paper_mu
from dynslip.errors import ComputationError
from dynslip.physics import static as S

SAT_REL = 0.02  # |F_m| = mu F_N within 2% counts as saturated


def rule_text(sel) -> str:
    if sel.rule == "switch_radius":
        return f"fully mobilised member whose F_m changes sign at rbar_s = {sel.value:g} R"
    return (f"fully mobilised member whose F_m changes sign (and lambda_theta peaks) at "
            f"theta_s = {sel.value:g} rad")


def compute_static(material, model: str, *, rbar_max, theta_max, initial_shape, selection, num,
                   jm=None) -> dict:
    """Member, march and search for one material. Returns a dict of arrays and scalars; on a
    failed search the dict has ``status = "failed"`` and ``error`` (nothing is raised here)."""
    import jax.numpy as jnp


    n = num.n_nodes
    rbar = S.grid(n, rbar_max)
    h = float(rbar[1] - rbar[0])
    t0 = time.perf_counter()
    member = S.solve_member(material, selection.value, theta_max, rbar_max, num.switch_guess,
                            by=selection.rule, rtol=num.ode_rtol)
    t_bvp = time.perf_counter() - t0
    out: dict = {"model": model, "rbar": rbar, "h": h, "member": member, "t_bvp_s": t_bvp,
                 "fv_tol": num.fv_tolerance(),
                 "rule": rule_text(selection), "paper_mu": paper_mu(model, jm)}
    if member.converged:
        th_m, _ = S.sample_member(material, member, rbar_max, rbar, rtol=num.ode_rtol)
    else:
        th_m = np.full(n, np.nan)
    out["theta_member"] = th_m
    if initial_shape == "fully_mobilised":
        if not member.converged:
            out.update(
                status="failed",
                theta=th_m,
                theta_initial=th_m,
                error=f"{LABEL.get(model, model)}: the fully mobilised boundary-value problem did "
                    f"not "
                f"converge for {out['rule']} (largest end-condition residual "
                f"{member.residual:.3g})",
            )
            return out
        theta0 = th_m
    else:
        theta0 = S.initial_shape("linear", rbar, theta_max)
    out["theta_initial"] = theta0
    march_kw = dict(method=num.march, vtol=num.rest_velocity, max_steps=num.max_steps,
                    rtol=num.diffrax_rtol, solver=num.diffrax_solver,
                    dt=float(S.stable_dt(material, jnp.asarray(theta0), h, num.dt_safety)))
    t0 = time.perf_counter()
    try:
        sr = S.search_mu(
            material,
            theta0,
            h,
            num.mu_bracket[0],
            num.mu_bracket[1],
            mu_tol=num.mu_tol,
            fv_tol=num.fv_tolerance(),
            **march_kw,
        )
    except ComputationError as err:
        part = cast(dict, err.partial)  # the search's failure carries its brackets
        out.update(
            status="failed",
            error=f"{LABEL.get(model, model)}: {err}",
            theta=np.asarray(part["theta"][0]),
            mu=float("nan"),
            fv_bracket=part["fv"],
            mu_bracket=part["mu"],
            theta_bracket_ends=part["theta"],
            t_search_s=time.perf_counter() - t0,
        )
        _add_fields(out, material, np.asarray(part["theta"][0]), h, num.mu_bracket[0], num)
        return out
    out["t_search_s"] = time.perf_counter() - t0
    out.update(
        status="ok",
        mu=sr.mu,
        theta=sr.theta,
        fv_bracket=sr.fv_bracket,
        mu_bracket=num.mu_bracket,
        evaluations=sr.evaluations,
        march_steps=int(sr.march.steps),
        march_converged=bool(sr.march.converged),
    )
    _add_fields(out, material, sr.theta, h, sr.mu, num)
    try:
        S.check_static_range(material, out["lambda_theta"], out["lambda_phi"], "in the final state")
    except ValueError as err:
        out.update(status="failed", error=str(err))
    return out


def _add_fields(out, material, theta, h, mu, num):
    import jax.numpy as jnp


    f = S.fields(material, jnp.asarray(theta), h)
    fm, fn = np.asarray(f.fm), np.asarray(f.fn)
    out.update(lambda_theta=np.asarray(f.lt), lambda_phi=np.asarray(f.lp), T_theta=np.asarray(f.tt),
               T_phi=np.asarray(f.tp), F_m=fm, F_N=fn)
    with np.errstate(divide="ignore", invalid="ignore"):
        out["mu_mobilised"] = np.where(fn > 0, np.abs(fm) / fn, np.nan)
    # Direction of friction F_f = -F_m: +1 toward the equator (increasing theta), -1 toward the
    # pole, 0 where F_m vanishes (the pole) to round-off.
    scale = np.max(np.abs(fm)) if np.all(np.isfinite(fm)) else 1.0
    out["friction_direction"] = np.where(np.abs(fm) <= 1e-12 * scale, 0, -np.sign(fm)).astype(
        np.int8
    )
    chk = S.check_equilibrium(material, theta, h, mu, vtol=num.rest_velocity, force_tol=1e-8)
    out["check"] = chk
    out["saturated_fraction"] = (
        S.saturation_fraction(fm, fn, mu, SAT_REL) if np.isfinite(mu) else float("nan")
    )
    rbar = out["rbar"]
    th = np.asarray(theta)
    i_t, i_p = int(np.nanargmax(out["lambda_theta"])), int(np.nanargmax(out["lambda_phi"]))
    i_s, i_i = S.sign_change_index(fm), S.inflection_index(th)
    out["extrema"] = {
        "lambda_theta_max": float(out["lambda_theta"][i_t]),
        "lambda_theta_max_rbar": float(rbar[i_t]),
        "lambda_theta_max_theta": float(th[i_t]),
        "lambda_phi_max": float(out["lambda_phi"][i_p]),
        "lambda_phi_max_rbar": float(rbar[i_p]),
        "lambda_phi_max_theta": float(th[i_p]),
        "F_m_sign_change_rbar": float(rbar[i_s]) if i_s >= 0 else None,
        "theta_inflection_rbar": float(rbar[i_i]) if i_i >= 0 else None,
    }


def static_summary(res: dict) -> dict:
    member = res["member"]
    s = {
        "status": res["status"],
        "model": res["model"],
        "mu": res.get("mu"),
        "mu_family": member.mu,
        "paper_mu": res["paper_mu"],
        "selection_rule": res["rule"],
        "switch_rbar": member.rbar_s,
        "switch_theta": member.theta_s,
        "pole_stretch": member.lam0,
        "n_nodes": int(len(res["rbar"])),
    }
    if res["paper_mu"] and res.get("mu") is not None and np.isfinite(res.get("mu", np.nan)):
        s["mu_vs_paper_percent"] = 100.0 * (res["mu"] / res["paper_mu"] - 1.0)
    if res["paper_mu"] and member.converged:
        s["mu_family_vs_paper_percent"] = 100.0 * (member.mu / res["paper_mu"] - 1.0)
    chk = res.get("check")
    if chk:
        s.update(
            F_v=chk["F_v"],
            F_v_identity=chk["F_v_identity"],
            F_v_identity_residual=chk["F_v_residual"],
            T_theta_edge=chk["T_theta_edge"],
            coulomb_excess=chk["coulomb_excess"],
            max_velocity=chk["vmax"],
            min_F_N=chk["min_F_N"],
            equilibrium_ok=chk["ok"],
            saturated_fraction=res["saturated_fraction"],
            saturation_tolerance=SAT_REL,
            **res["extrema"],
        )
    for k in ("evaluations", "march_steps", "march_converged", "t_bvp_s", "t_search_s"):
        if k in res:
            s[k] = res[k]
    s["fv_tolerance"] = res.get("fv_tol")
    if "fv_bracket" in res:
        s["mu_bracket"] = list(res["mu_bracket"])
        s["F_v_at_bracket_ends"] = list(res["fv_bracket"])
    if res["status"] != "ok":
        s["error"] = res.get("error", "")
    return s


#: the material models of the paper's Fig. 4 and of the family, in their order
FIGURE4_MODELS = ("hookean", "neo_hookean", "gent")


def figure4_summary(sums: list[dict], complete: bool) -> dict:
    """``summary.json`` of ``kind: figure4``: each model's static summary, and mu by model."""
    return {
        "status": "ok" if complete else "failed",
        "models": sums,
        "mu": {s["model"]: s.get("mu") for s in sums},
        "selection_rule": sums[0]["selection_rule"],
    }


def family(materials: dict, values, theta_max, rbar_max, guess, rtol, switch_by, selection):
    """The fully mobilised family of each material (``{model: material}``) over the family
    parameter ``values`` (``switch_by``: switch radius or angle), by continuation from the
    middle of the range outward, both ways; and the member the selection rule picks.

    Returns (``{"mu", "pole_stretch", "switch_rbar", "switch_theta"}`` arrays (model, member),
    NaN where a member did not converge; the selected members)."""

    cols = {
        k: np.full((len(materials), len(values)), np.nan)
        for k in ("mu", "pole_stretch", "switch_rbar", "switch_theta")
    }
    selected = []
    for i, mat in enumerate(materials.values()):
        # Continuation from the middle of the range outward, both ways.
        mid = len(values) // 2
        up = S.solve_family(mat, values[mid:], theta_max, rbar_max, guess, by=switch_by, rtol=rtol)
        g = (up[0].lam0, up[0].mu, up[0].rbar_s) if up[0].converged else guess
        down = S.solve_family(mat, values[:mid][::-1], theta_max, rbar_max, g, by=switch_by,
                              rtol=rtol)[::-1]
        for j, m in enumerate(down + up):
            if m.converged:
                cols["mu"][i, j], cols["pole_stretch"][i, j] = m.mu, m.lam0
                cols["switch_rbar"][i, j], cols["switch_theta"][i, j] = m.rbar_s, m.theta_s
        sel = S.solve_member(mat, selection.value, theta_max, rbar_max, guess, by=selection.rule,
                             rtol=rtol)
        selected.append(sel)
    return cols, selected


def family_summary(cols: dict, selected: list, models: list[str], jm, selection):
    """The table rows (one per model: the selected member against the paper's mu) and
    ``summary.json`` of ``kind: family``."""
    rows = []
    for i, model in enumerate(models):
        pm = paper_mu(model, jm)
        rows.append(
            {
                "model": model,
                "mu": selected[i].mu,
                "mu_family": selected[i].mu,
                "paper_mu": pm,
                "mu_vs_paper_percent": 100 * (selected[i].mu / pm - 1) if pm else None,
                "status": "ok" if selected[i].converged else "failed",
                "selection_rule": rule_text(selection),
                "members_converged": int(np.isfinite(cols["mu"][i]).sum()),
            }
        )
    summary = {"status": "ok", "selection_rule": rule_text(selection), "selected": rows,
               "mu_range": {m: [float(np.nanmin(cols["mu"][i])), float(np.nanmax(cols["mu"][i]))]
                            for i, m in enumerate(models)}}
    return rows, summary
