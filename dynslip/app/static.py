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

from pathlib import Path

import numpy as np
import xarray as xr

from dynslip.analysis.paper import PAPER_MU, paper_mu
from dynslip.analysis.static import _rule_text, _summary, compute_static
from dynslip.data import files as io
from dynslip.data.static import static_dataset
from dynslip.errors import ComputationError
from dynslip.plot.style import MODEL_LABELS as LABEL

__all__ = ["PAPER_MU", "run_static", "run_figure4", "run_family",
           "run_cylinder", "paper_mu"]


def _scales(p) -> dict:
    g_pa = p.youngs_modulus_MPa * 1e6 / 3.0
    r_m, h0_m = p.ball_radius_mm * 1e-3, p.thickness_mm * 1e-3
    return {"R_m": r_m, "G_Pa": g_pa, "h0_m": h0_m, "force_scale_N": g_pa * h0_m * r_m}


def _table(console, title: str, rows: list[dict]) -> None:
    from rich.table import Table

    t = Table(title=title)
    cols = [
        ("model", "model"),
        ("mu", "mu"),
        ("mu_family", "mu (BVP)"),
        ("paper_mu", "paper"),
        ("mu_vs_paper_percent", "vs paper %"),
        ("F_v", "F_v [G h0 R]"),
        ("saturated_fraction", "saturated"),
        ("lambda_theta_max", "max l_t"),
        ("lambda_theta_max_theta", "at theta"),
        ("status", "status"),
    ]
    for _, name in cols:
        t.add_column(name, justify="right")
    for r in rows:
        cells = []
        for key, _ in cols:
            val = r.get(key)
            cells.append(
                "-" if val is None else (f"{val:.4g}" if isinstance(val, float) else str(val))
            )
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
        res = compute_static(
            mat,
            model,
            rbar_max=p.rbar_max,
            theta_max=p.theta_max,
            initial_shape=p.initial_shape,
            selection=p.selection,
            num=sc.numerics,
            jm=p.jm if model == "gent" else None,
        )
        results.append(res)
        sums.append(_summary(res))
        dss.append(static_dataset(res, sc.to_json(), "figure4", _scales(p)))
    ds = xr.concat(
        dss, dim="model", combine_attrs="drop_conflicts", data_vars="all", coords="minimal"
    )
    ds = ds.assign_coords(
        model=io.variable(["hookean", "neo_hookean", "gent"], ("model",), "1", "material model")
    )
    ds.attrs.update(
        io.provenance(sc.to_json(), "figure4"),
        complete=int(all(r["status"] == "ok" for r in results)),
    )
    ds.attrs.pop("model", None)
    ds.attrs.pop("status", None)
    for name in ("switch_rbar", "switch_theta", "pole_stretch"):
        ds.attrs.pop(name, None)
    io.write_netcdf(ds, out / "result.nc")
    summary = {
        "status": "ok" if ds.attrs["complete"] else "failed",
        "models": sums,
        "mu": {s["model"]: s.get("mu") for s in sums},
        "selection_rule": sums[0]["selection_rule"],
    }
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
    cols = {
        k: np.full((3, len(values)), np.nan)
        for k in ("mu", "pole_stretch", "switch_rbar", "switch_theta")
    }
    selected = []
    for i, model in enumerate(models):
        mat = make_material(model, jm=p.jm)
        # Continuation from the middle of the range outward, both ways.
        mid = len(values) // 2
        up = S.solve_family(
            mat,
            values[mid:],
            p.theta_max,
            p.rbar_max,
            num.switch_guess,
            by=p.switch_by,
            rtol=num.ode_rtol,
        )
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
            "switch_rbar": v(
                cols["switch_rbar"],
                dims,
                "1",
                "undeformed radius where F_m changes sign",
                scale="R",
            ),
            "switch_theta": v(
                cols["switch_theta"], dims, "rad", "polar angle where F_m changes sign"
            ),
            "mu_selected": v(
                [m.mu for m in selected],
                ("model",),
                "1",
                "mu of the member picked by the selection rule",
            ),
            "switch_rbar_selected": v(
                [m.rbar_s for m in selected],
                ("model",),
                "1",
                "switch radius of that member",
                scale="R",
            ),
            "switch_theta_selected": v(
                [m.theta_s for m in selected], ("model",), "rad", "switch angle of that member"
            ),
            "mu_paper": v(
                [paper_mu(m, p.jm) or np.nan for m in models], ("model",), "1", "the paper's mu"
            ),
        },
        coords={
            "model": v(models, ("model",), "1", "material model"),
            "switch_value": v(
                values,
                ("member",),
                "rad" if p.switch_by == "switch_angle" else "1",
                f"family parameter ({p.switch_by})",
            ),
        },
    )
    ds.attrs.update(io.provenance(sc.to_json(), "family"), **_scales(p), switch_by=p.switch_by,
                    selection_rule=_rule_text(p.selection), complete=1)
    io.check_units(ds)
    io.write_netcdf(ds, out / "result.nc")
    rows = []
    for i, model in enumerate(models):
        pm = paper_mu(model, p.jm)
        rows.append(
            {
                "model": model,
                "mu": selected[i].mu,
                "mu_family": selected[i].mu,
                "paper_mu": pm,
                "mu_vs_paper_percent": 100 * (selected[i].mu / pm - 1) if pm else None,
                "status": "ok" if selected[i].converged else "failed",
                "selection_rule": _rule_text(p.selection),
                "members_converged": int(np.isfinite(cols["mu"][i]).sum()),
            }
        )
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
        fv[k] = np.asarray(jax.vmap(lambda tt, f: C.vertical_force(tt, f, th))(t, ff))  # noqa: B023 - called here
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
            "F_v": v(
                fv,
                ("theta_max", "profile"),
                "1",
                "vertical force per unit length, random admissible states",
                scale="T0",
            ),
            "F_v_closed": v(
                fv_closed, ("theta_max", "profile"), "1", "T(theta_max) sin(theta_max)", scale="T0"
            ),
            "F_v_lower": v(
                np.exp(-p.mu * angles) * np.sin(angles),
                ("theta_max",),
                "1",
                "lower bound T0 exp(-mu theta_max) sin(theta_max)",
                scale="T0",
            ),
            "T": v(
                np.asarray(t),
                ("sample", "theta"),
                "1",
                "tension of random admissible states",
                scale="T0",
            ),
            "T_lower": v(
                np.asarray(lo), ("theta",), "1", "capstan lower bound T0 exp(-mu theta)", scale="T0"
            ),
            "T_upper": v(
                np.asarray(hi), ("theta",), "1", "capstan upper bound T0 exp(mu theta)", scale="T0"
            ),
            "mu": v(p.mu, (), "1", "friction coefficient"),
        },
        coords={
            "theta_max": v(angles, ("theta_max",), "rad", "lift-off angle"),
            "theta": v(np.asarray(th), ("theta",), "rad", "polar angle on the cylinder"),
        },
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
        "min_F_v_over_lower_bound": float(
            np.min(fv / (np.exp(-p.mu * angles) * np.sin(angles))[:, None])
        ),
        "all_F_v_positive": bool((fv > 0).all()),
        "max_rel_diff_F_v_vs_closed_form": float(rel),
        "max_capstan_bound_violation": excess,
        "n_states": int(fv.size),
        "conclusion": "F_v > 0 for every admissible state: no invagination in 2D"
        if (fv > 0).all()
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
