"""Runners of the static scenarios: compute, write ``result.nc``, ``summary.json``, the
figures, and print a summary table.

``static``: the selected fully mobilised member (boundary-value problem), then the
paper's march and mu search from the stated initial shape; ``figure4``: the same for
Hookean, neo-Hookean and Gent; ``family``: mu along the fully mobilised family;
``cylinder``: the 2D capstan bounds and vertical force. A search that finds no root
writes what it computed (``complete = 0``, summary ``status: failed``) and raises
:class:`dynslip.errors.ComputationError` (exit 3).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import xarray as xr

from dynslip.analysis.paper import PAPER_MU, paper_mu
from dynslip.data import files as io
from dynslip.errors import ComputationError
from dynslip.plot.style import MODEL_LABELS as LABEL

__all__ = ["PAPER_MU", "compute_static", "static_dataset", "run_static", "run_figure4", "run_family",
           "run_cylinder", "paper_mu"]

SAT_REL = 0.02  # |F_m| = mu F_N within 2% counts as saturated


def _scales(p) -> dict:
    g_pa = p.youngs_modulus_MPa * 1e6 / 3.0
    r_m, h0_m = p.ball_radius_mm * 1e-3, p.thickness_mm * 1e-3
    return {"R_m": r_m, "G_Pa": g_pa, "h0_m": h0_m, "force_scale_N": g_pa * h0_m * r_m}


def _rule_text(sel) -> str:
    if sel.rule == "switch_radius":
        return f"fully mobilised member whose F_m changes sign at rbar_s = {sel.value:g} R"
    return f"fully mobilised member whose F_m changes sign (and lambda_theta peaks) at theta_s = {sel.value:g} rad"


def compute_static(material, model: str, *, rbar_max, theta_max, initial_shape, selection, num,
                   jm=None) -> dict:
    """Member, march and search for one material. Returns a dict of arrays and scalars; on a
    failed search the dict has ``status = "failed"`` and ``error`` (nothing is raised here)."""
    import jax.numpy as jnp

    from dynslip.physics import sphere as S

    n = num.n_nodes
    rbar = S.grid(n, rbar_max)
    h = float(rbar[1] - rbar[0])
    t0 = time.perf_counter()
    member = S.solve_member(material, selection.value, theta_max, rbar_max, num.switch_guess,
                            by=selection.rule, rtol=num.ode_rtol)
    t_bvp = time.perf_counter() - t0
    out: dict = {"model": model, "rbar": rbar, "h": h, "member": member, "t_bvp_s": t_bvp,
                 "fv_tol": num.fv_tolerance(),
                 "rule": _rule_text(selection), "paper_mu": paper_mu(model, jm)}
    if member.converged:
        th_m, _ = S.sample_member(material, member, rbar_max, rbar, rtol=num.ode_rtol)
    else:
        th_m = np.full(n, np.nan)
    out["theta_member"] = th_m
    if initial_shape == "fully_mobilised":
        if not member.converged:
            out.update(status="failed", theta=th_m, theta_initial=th_m,
                       error=f"{LABEL.get(model, model)}: the fully mobilised boundary-value problem did not "
                       f"converge for {out['rule']} (largest end-condition residual {member.residual:.3g})")
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
        sr = S.search_mu(material, theta0, h, num.mu_bracket[0], num.mu_bracket[1], mu_tol=num.mu_tol,
                         fv_tol=num.fv_tolerance(), **march_kw)
    except ComputationError as err:
        part = err.partial
        out.update(status="failed", error=f"{LABEL.get(model, model)}: {err}", theta=np.asarray(part["theta"][0]),
                   mu=float("nan"), fv_bracket=part["fv"], mu_bracket=part["mu"],
                   theta_bracket_ends=part["theta"], t_search_s=time.perf_counter() - t0)
        _add_fields(out, material, np.asarray(part["theta"][0]), h, num.mu_bracket[0], num)
        return out
    out["t_search_s"] = time.perf_counter() - t0
    out.update(status="ok", mu=sr.mu, theta=sr.theta, fv_bracket=sr.fv_bracket, mu_bracket=num.mu_bracket,
               evaluations=sr.evaluations, march_steps=int(sr.march.steps), march_converged=bool(sr.march.converged))
    _add_fields(out, material, sr.theta, h, sr.mu, num)
    try:
        S.check_static_range(material, out["lambda_theta"], out["lambda_phi"], "in the final state")
    except ValueError as err:
        out.update(status="failed", error=str(err))
    return out


def _add_fields(out, material, theta, h, mu, num):
    import jax.numpy as jnp

    from dynslip.physics import sphere as S

    f = S.fields(material, jnp.asarray(theta), h)
    fm, fn = np.asarray(f.fm), np.asarray(f.fn)
    out.update(lambda_theta=np.asarray(f.lt), lambda_phi=np.asarray(f.lp), T_theta=np.asarray(f.tt),
               T_phi=np.asarray(f.tp), F_m=fm, F_N=fn)
    with np.errstate(divide="ignore", invalid="ignore"):
        out["mu_mobilised"] = np.where(fn > 0, np.abs(fm) / fn, np.nan)
    # Direction of friction F_f = -F_m: +1 toward the equator (increasing theta), -1 toward the
    # pole, 0 where F_m vanishes (the pole) to round-off.
    scale = np.max(np.abs(fm)) if np.all(np.isfinite(fm)) else 1.0
    out["friction_direction"] = np.where(np.abs(fm) <= 1e-12 * scale, 0, -np.sign(fm)).astype(np.int8)
    chk = S.check_equilibrium(material, theta, h, mu, vtol=num.rest_velocity, force_tol=1e-8)
    out["check"] = chk
    out["saturated_fraction"] = S.saturation_fraction(fm, fn, mu, SAT_REL) if np.isfinite(mu) else float("nan")
    rbar = out["rbar"]
    th = np.asarray(theta)
    i_t, i_p = int(np.nanargmax(out["lambda_theta"])), int(np.nanargmax(out["lambda_phi"]))
    i_s, i_i = S.sign_change_index(fm), S.inflection_index(th)
    out["extrema"] = {
        "lambda_theta_max": float(out["lambda_theta"][i_t]), "lambda_theta_max_rbar": float(rbar[i_t]),
        "lambda_theta_max_theta": float(th[i_t]),
        "lambda_phi_max": float(out["lambda_phi"][i_p]), "lambda_phi_max_rbar": float(rbar[i_p]),
        "lambda_phi_max_theta": float(th[i_p]),
        "F_m_sign_change_rbar": float(rbar[i_s]) if i_s >= 0 else None,
        "theta_inflection_rbar": float(rbar[i_i]) if i_i >= 0 else None,
    }


def static_dataset(res: dict, scenario_json: str, kind: str, scales: dict) -> xr.Dataset:
    """The result dataset of one static computation (plots read this)."""
    d = ("rbar",)
    nd = "1"
    v = io.variable
    member = res["member"]
    data = {
        "theta": v(res["theta"], d, "rad", "polar angle of the material point"),
        "theta_initial": v(res["theta_initial"], d, "rad", "initial shape of the march"),
        "theta_member": v(res["theta_member"], d, "rad", "selected fully mobilised member (ODE solution)"),
    }
    if "lambda_theta" in res:
        data.update({
            "lambda_theta": v(res["lambda_theta"], d, nd, "meridional stretch"),
            "lambda_phi": v(res["lambda_phi"], d, nd, "hoop stretch"),
            "T_theta": v(res["T_theta"], d, nd, "meridional tension per deformed length", scale="G*h0"),
            "T_phi": v(res["T_phi"], d, nd, "hoop tension per deformed length", scale="G*h0"),
            "F_m": v(res["F_m"], d, nd, "meridional elastic force density", scale="G*h0/R"),
            "F_N": v(res["F_N"], d, nd, "normal force density", scale="G*h0/R"),
            "mu_mobilised": v(res["mu_mobilised"], d, nd, "mobilised friction coefficient |F_f|/F_N"),
            "friction_direction": v(res["friction_direction"], d, nd,
                                    "direction of friction on the sheet: +1 toward the equator, -1 toward the pole"),
        })
    data["mu"] = v(res.get("mu", np.nan), (), nd, "friction coefficient returned by the mu search")
    data["mu_family"] = v(member.mu, (), nd, "friction coefficient of the selected fully mobilised member")
    chk = res.get("check", {})
    data["F_v"] = v(chk.get("F_v", np.nan), (), nd, "vertical force of the ball on the sheet (eq. Fz)", scale="G*h0*R")
    data["F_v_identity"] = v(chk.get("F_v_identity", np.nan), (), nd,
                             "2 pi T_theta(theta_max) sin^2(theta_max)", scale="G*h0*R")
    ds = xr.Dataset(data, coords={"rbar": v(res["rbar"], d, nd, "undeformed radius", scale="R")})
    ds.attrs.update(io.provenance(scenario_json, kind))
    ds.attrs.update(scales)
    ds.attrs.update(model=res["model"], selection_rule=res["rule"], status=res["status"],
                    complete=int(res["status"] == "ok"), switch_rbar=member.rbar_s,
                    switch_theta=member.theta_s, pole_stretch=member.lam0)
    if res["status"] != "ok":
        ds.attrs["error"] = res.get("error", "")
    io.check_units(ds)
    return ds


def _summary(res: dict) -> dict:
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
        s.update(F_v=chk["F_v"], F_v_identity=chk["F_v_identity"], F_v_identity_residual=chk["F_v_residual"],
                 T_theta_edge=chk["T_theta_edge"], coulomb_excess=chk["coulomb_excess"],
                 max_velocity=chk["vmax"], min_F_N=chk["min_F_N"], equilibrium_ok=chk["ok"],
                 saturated_fraction=res["saturated_fraction"], saturation_tolerance=SAT_REL, **res["extrema"])
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


def _table(console, title: str, rows: list[dict]) -> None:
    from rich.table import Table

    t = Table(title=title)
    cols = [("model", "model"), ("mu", "mu"), ("mu_family", "mu (BVP)"), ("paper_mu", "paper"),
            ("mu_vs_paper_percent", "vs paper %"), ("F_v", "F_v [G h0 R]"), ("saturated_fraction", "saturated"),
            ("lambda_theta_max", "max l_t"), ("lambda_theta_max_theta", "at theta"), ("status", "status")]
    for _, name in cols:
        t.add_column(name, justify="right")
    for r in rows:
        cells = []
        for key, _ in cols:
            val = r.get(key)
            cells.append("-" if val is None else (f"{val:.4g}" if isinstance(val, float) else str(val)))
        t.add_row(*cells)
    console.print(t)
    if rows:
        console.print(f"selection rule: {rows[0]['selection_rule']}")


def _fail(res_list, out: Path):
    msgs = [r["error"] for r in res_list if r["status"] != "ok"]
    if msgs:
        raise ComputationError("; ".join(msgs) + f" (partial results kept in {out}, complete = 0)")


def run_static(sc, out: Path, console) -> dict:
    """``kind: static``: one material, Fig. 4 row."""
    from dynslip.plot.static import save_figure4_row
    from dynslip.schema.static import material_of

    p = sc.physics
    mat = material_of(p.material)
    res = compute_static(mat, p.material.model, rbar_max=p.rbar_max, theta_max=p.theta_max,
                         initial_shape=p.initial_shape, selection=p.selection, num=sc.numerics,
                         jm=getattr(p.material, "jm", None))
    ds = static_dataset(res, sc.to_json(), "static", _scales(p))
    io.write_netcdf(ds, out / "result.nc")
    summary = _summary(res)
    io.write_json(out / "summary.json", summary)
    if "lambda_theta" in res:
        save_figure4_row(ds, out / "figure4_row.png")
    _table(console, f"static: {LABEL.get(res['model'], res['model'])}", [summary])
    _fail([res], out)
    return summary


def run_figure4(sc, out: Path, console) -> dict:
    """``kind: figure4``: Hookean, neo-Hookean, Gent in one 3x3 figure."""
    from dynslip.physics.materials import make_material
    from dynslip.plot.static import save_figure4

    p = sc.physics
    results, sums, dss = [], [], []
    for model in ("hookean", "neo_hookean", "gent"):
        mat = make_material(model, jm=p.jm)
        res = compute_static(mat, model, rbar_max=p.rbar_max, theta_max=p.theta_max, initial_shape=p.initial_shape,
                             selection=p.selection, num=sc.numerics, jm=p.jm if model == "gent" else None)
        results.append(res)
        sums.append(_summary(res))
        dss.append(static_dataset(res, sc.to_json(), "figure4", _scales(p)))
    ds = xr.concat(dss, dim="model", combine_attrs="drop_conflicts", data_vars="all", coords="minimal")
    ds = ds.assign_coords(model=io.variable(["hookean", "neo_hookean", "gent"], ("model",), "1", "material model"))
    ds.attrs.update(io.provenance(sc.to_json(), "figure4"), complete=int(all(r["status"] == "ok" for r in results)))
    ds.attrs.pop("model", None)
    ds.attrs.pop("status", None)
    for name in ("switch_rbar", "switch_theta", "pole_stretch"):
        ds.attrs.pop(name, None)
    io.write_netcdf(ds, out / "result.nc")
    summary = {"status": "ok" if ds.attrs["complete"] else "failed", "models": sums,
               "mu": {s["model"]: s.get("mu") for s in sums}, "selection_rule": sums[0]["selection_rule"]}
    io.write_json(out / "summary.json", summary)
    if all("lambda_theta" in r for r in results):
        save_figure4(ds, out / "figure4.png")
    _table(console, "Fig. 4: the three models", sums)
    _fail(results, out)
    return summary


def run_family(sc, out: Path, console) -> dict:
    """``kind: family``: mu along the fully mobilised family of the three models."""
    from dynslip.physics import sphere as S
    from dynslip.physics.materials import make_material
    from dynslip.plot.static import save_family

    p, num = sc.physics, sc.numerics
    values = np.linspace(p.switch_from, p.switch_to, num.n_members)
    models = ["hookean", "neo_hookean", "gent"]
    cols = {k: np.full((3, len(values)), np.nan) for k in ("mu", "pole_stretch", "switch_rbar", "switch_theta")}
    selected = []
    for i, model in enumerate(models):
        mat = make_material(model, jm=p.jm)
        # Continuation from the middle of the range outward, both ways.
        mid = len(values) // 2
        up = S.solve_family(mat, values[mid:], p.theta_max, p.rbar_max, num.switch_guess, by=p.switch_by,
                            rtol=num.ode_rtol)
        g = (up[0].lam0, up[0].mu, up[0].rbar_s) if up[0].converged else num.switch_guess
        down = S.solve_family(mat, values[:mid][::-1], p.theta_max, p.rbar_max, g, by=p.switch_by,
                              rtol=num.ode_rtol)[::-1]
        for j, m in enumerate(down + up):
            if m.converged:
                cols["mu"][i, j], cols["pole_stretch"][i, j] = m.mu, m.lam0
                cols["switch_rbar"][i, j], cols["switch_theta"][i, j] = m.rbar_s, m.theta_s
        sel = S.solve_member(mat, p.selection.value, p.theta_max, p.rbar_max, num.switch_guess,
                             by=p.selection.rule, rtol=num.ode_rtol)
        selected.append(sel)
    v = io.variable
    dims = ("model", "member")
    ds = xr.Dataset(
        {
            "mu": v(cols["mu"], dims, "1", "friction coefficient of the fully mobilised member"),
            "pole_stretch": v(cols["pole_stretch"], dims, "1", "stretch at the pole"),
            "switch_rbar": v(cols["switch_rbar"], dims, "1", "undeformed radius where F_m changes sign", scale="R"),
            "switch_theta": v(cols["switch_theta"], dims, "rad", "polar angle where F_m changes sign"),
            "mu_selected": v([m.mu for m in selected], ("model",), "1", "mu of the member picked by the selection rule"),
            "switch_rbar_selected": v([m.rbar_s for m in selected], ("model",), "1", "switch radius of that member",
                                      scale="R"),
            "switch_theta_selected": v([m.theta_s for m in selected], ("model",), "rad", "switch angle of that member"),
            "mu_paper": v([paper_mu(m, p.jm) or np.nan for m in models], ("model",), "1", "the paper's mu"),
        },
        coords={
            "model": v(models, ("model",), "1", "material model"),
            "switch_value": v(values, ("member",), "rad" if p.switch_by == "switch_angle" else "1",
                              f"family parameter ({p.switch_by})"),
        },
    )
    ds.attrs.update(io.provenance(sc.to_json(), "family"), **_scales(p), switch_by=p.switch_by,
                    selection_rule=_rule_text(p.selection), complete=1)
    io.check_units(ds)
    io.write_netcdf(ds, out / "result.nc")
    rows = []
    for i, model in enumerate(models):
        pm = paper_mu(model, p.jm)
        rows.append({"model": model, "mu": selected[i].mu, "mu_family": selected[i].mu, "paper_mu": pm,
                     "mu_vs_paper_percent": 100 * (selected[i].mu / pm - 1) if pm else None,
                     "status": "ok" if selected[i].converged else "failed",
                     "selection_rule": _rule_text(p.selection),
                     "members_converged": int(np.isfinite(cols["mu"][i]).sum())})
    summary = {"status": "ok", "selection_rule": _rule_text(p.selection), "selected": rows,
               "mu_range": {m: [float(np.nanmin(cols["mu"][i])), float(np.nanmax(cols["mu"][i]))]
                            for i, m in enumerate(models)}}
    io.write_json(out / "summary.json", summary)
    save_family(ds, out / "family.png")
    _table(console, "fully mobilised family: selected members", rows)
    return summary


def run_cylinder(sc, out: Path, console) -> dict:
    """``kind: cylinder``: capstan bounds and the vertical force in 2D (paper Section 5)."""
    import jax
    import jax.numpy as jnp
    from rich.table import Table

    from dynslip.physics import cylinder as C
    from dynslip.plot.static import save_cylinder

    p, num = sc.physics, sc.numerics
    angles = np.linspace(p.theta_max_from, p.theta_max_to, num.n_angles)
    key = jax.random.PRNGKey(num.seed)
    fv = np.zeros((num.n_angles, num.n_profiles))
    fv_closed = np.zeros_like(fv)
    excess = 0.0
    for k, tmax in enumerate(angles):
        key, sub = jax.random.split(key)
        th, t, ff = C.random_admissible(sub, p.mu, float(tmax), num.n_profiles, num.n_nodes)
        fv[k] = np.asarray(jax.vmap(lambda tt, f: C.vertical_force(tt, f, th))(t, ff))
        fv_closed[k] = np.asarray(C.vertical_force_closed(t[:, -1], tmax))
        lo, hi = C.capstan_bounds(p.mu, th)
        excess = max(excess, float(jnp.max(jnp.maximum(lo - t, t - hi) / hi)))
    # Profiles at the largest angle for the figure.
    th, t, ff = C.random_admissible(jax.random.PRNGKey(num.seed + 1), p.mu, float(angles[-1]),
                                    min(num.n_profiles, 50), num.n_nodes)
    lo, hi = C.capstan_bounds(p.mu, th)
    v = io.variable
    ds = xr.Dataset(
        {
            "F_v": v(fv, ("theta_max", "profile"), "1", "vertical force per unit length, random admissible states",
                     scale="T0"),
            "F_v_closed": v(fv_closed, ("theta_max", "profile"), "1", "T(theta_max) sin(theta_max)", scale="T0"),
            "F_v_lower": v(np.exp(-p.mu * angles) * np.sin(angles), ("theta_max",), "1",
                           "lower bound T0 exp(-mu theta_max) sin(theta_max)", scale="T0"),
            "T": v(np.asarray(t), ("sample", "theta"), "1", "tension of random admissible states", scale="T0"),
            "T_lower": v(np.asarray(lo), ("theta",), "1", "capstan lower bound T0 exp(-mu theta)", scale="T0"),
            "T_upper": v(np.asarray(hi), ("theta",), "1", "capstan upper bound T0 exp(mu theta)", scale="T0"),
            "mu": v(p.mu, (), "1", "friction coefficient"),
        },
        coords={"theta_max": v(angles, ("theta_max",), "rad", "lift-off angle"),
                "theta": v(np.asarray(th), ("theta",), "rad", "polar angle on the cylinder")},
    )
    ds.attrs.update(io.provenance(sc.to_json(), "cylinder"), complete=1)
    io.check_units(ds)
    io.write_netcdf(ds, out / "result.nc")
    rel = np.max(np.abs(fv - fv_closed) / np.abs(fv_closed))
    summary = {
        "status": "ok",
        "mu": p.mu,
        "capstan_ratio_at_pi": float(np.exp(p.mu * np.pi)),
        "min_F_v": float(fv.min()),
        "min_F_v_over_lower_bound": float(np.min(fv / (np.exp(-p.mu * angles) * np.sin(angles))[:, None])),
        "all_F_v_positive": bool((fv > 0).all()),
        "max_rel_diff_F_v_vs_closed_form": float(rel),
        "max_capstan_bound_violation": excess,
        "n_states": int(fv.size),
        "conclusion": "F_v > 0 for every admissible state: no invagination in 2D" if (fv > 0).all()
        else "some admissible state has F_v <= 0",
    }
    io.write_json(out / "summary.json", summary)
    save_cylinder(ds, out / "cylinder.png")
    tab = Table(title="2D cylinder (paper Section 5)")
    tab.add_column("quantity")
    tab.add_column("value", justify="right")
    for k, val in summary.items():
        tab.add_row(k, f"{val:.4g}" if isinstance(val, float) else str(val))
    console.print(tab)
    return summary
