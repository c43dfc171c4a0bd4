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

from typing import Literal, cast

import numpy as np

from dynslip.analysis.paper import PAPER_MU, paper_mu
from dynslip.analysis.plane_strain import cylinder_study, cylinder_summary
from dynslip.analysis.static import (
    FIGURE4_MODELS,
    compute_static,
    family,
    family_summary,
    figure4_summary,
    rule_text,
    static_summary,
)
from dynslip.app.outputs import Outputs
from dynslip.data import files as io
from dynslip.data.static import cylinder_dataset, family_dataset, figure4_dataset, static_dataset
from dynslip.errors import ComputationError
from dynslip.plot.static import save_cylinder, save_family, save_figure4, save_figure4_row
from dynslip.plot.style import MODEL_LABELS as LABEL
from dynslip.schema.materials import MaterialSpec
from dynslip.schema.static import material_of

__all__ = ["PAPER_MU", "run_static", "run_figure4", "run_family",
           "run_cylinder", "paper_mu"]

#: the names of FIGURE4_MODELS, each a value of MaterialSpec.model
_Fig4Model = Literal["hookean", "neo_hookean", "gent"]


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


def _fail(res_list, outs: Outputs):
    msgs = [r["error"] for r in res_list if r["status"] != "ok"]
    if msgs:
        where = outs.folder if outs.writes else outs.where("result.nc")
        raise ComputationError("; ".join(msgs)
                               + f" (partial results kept in {where}, complete = 0)")


def run_static(sc, out, console) -> dict:
    """``kind: static``: one material, Fig. 4 row."""

    outs = Outputs.of(out)
    p = sc.physics
    mat = material_of(p.material)
    res = compute_static(mat, p.material.model, rbar_max=p.rbar_max, theta_max=p.theta_max,
                         initial_shape=p.initial_shape, selection=p.selection, num=sc.numerics,
                         jm=getattr(p.material, "jm", None))
    ds = static_dataset(res, sc.to_json(), "static", _scales(p))
    outs.netcdf(ds, "result.nc")
    summary = static_summary(res)
    outs.json(summary)
    if "lambda_theta" in res and outs.writes:
        save_figure4_row(ds, outs.folder / "figure4_row.png")
    _table(console, f"static: {LABEL.get(res['model'], res['model'])}", [summary])
    _fail([res], outs)
    return summary


def run_figure4(sc, out, console) -> dict:
    """``kind: figure4``: Hookean, neo-Hookean, Gent in one 3x3 figure."""

    outs = Outputs.of(out)
    p = sc.physics
    results, sums, dss = [], [], []
    for model in FIGURE4_MODELS:
        mat = MaterialSpec(model=cast(_Fig4Model, model), jm=p.jm).core()
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
        sums.append(static_summary(res))
        dss.append(static_dataset(res, sc.to_json(), "figure4", _scales(p)))
    ds = figure4_dataset(
        dss, FIGURE4_MODELS, sc.to_json(), all(r["status"] == "ok" for r in results)
    )
    outs.netcdf(ds, "result.nc")
    summary = figure4_summary(sums, bool(ds.attrs["complete"]))
    outs.json(summary)
    if all("lambda_theta" in r for r in results) and outs.writes:
        save_figure4(ds, outs.folder / "figure4.png")
    _table(console, "Fig. 4: the three models", sums)
    _fail(results, outs)
    return summary


def run_family(sc, out, console) -> dict:
    """``kind: family``: mu along the fully mobilised family of the three models."""

    outs = Outputs.of(out)
    p, num = sc.physics, sc.numerics
    values = np.linspace(p.switch_from, p.switch_to, num.n_members)
    materials = {model: MaterialSpec(model=cast(_Fig4Model, model), jm=p.jm).core()
                 for model in FIGURE4_MODELS}
    cols, selected = family(
        materials,
        values,
        p.theta_max,
        p.rbar_max,
        num.switch_guess,
        num.ode_rtol,
        p.switch_by,
        p.selection,
    )
    models = list(materials)
    ds = family_dataset(
        cols, selected, values, models, [paper_mu(m, p.jm) or np.nan for m in models], p.switch_by
    )
    ds.attrs.update(io.provenance(sc.to_json(), "family"), **_scales(p), switch_by=p.switch_by,
                    selection_rule=rule_text(p.selection), complete=1)
    io.check_units(ds)
    outs.netcdf(ds, "result.nc")
    rows, summary = family_summary(cols, selected, models, p.jm, p.selection)
    outs.json(summary)
    if outs.writes:
        save_family(ds, outs.folder / "family.png")
    _table(console, "fully mobilised family: selected members", rows)
    return summary


def run_cylinder(sc, out, console) -> dict:
    """``kind: cylinder``: capstan bounds and the vertical force in 2D (paper Section 5)."""
    from rich.table import Table


    outs = Outputs.of(out)
    p, num = sc.physics, sc.numerics
    angles = np.linspace(p.theta_max_from, p.theta_max_to, num.n_angles)
    study = cylinder_study(p.mu, angles, num.n_profiles, num.n_nodes, num.seed)
    ds = cylinder_dataset(p.mu, angles, study)
    ds.attrs.update(io.provenance(sc.to_json(), "cylinder"), complete=1)
    io.check_units(ds)
    outs.netcdf(ds, "result.nc")
    summary = cylinder_summary(p.mu, angles, study)
    outs.json(summary)
    if outs.writes:
        save_cylinder(ds, outs.folder / "cylinder.png")
    tab = Table(title="2D cylinder (paper Section 5)")
    tab.add_column("quantity")
    tab.add_column("value", justify="right")
    for k, val in summary.items():
        tab.add_row(k, f"{val:.4g}" if isinstance(val, float) else str(val))
    console.print(tab)
    return summary
