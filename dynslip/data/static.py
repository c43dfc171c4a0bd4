"""The result dataset of one static computation (``result.nc`` of ``kind: static``, a row
of ``figure4``): the shapes, stretches, tensions and forces on the grid, with units."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from dynslip.data import files as io

if TYPE_CHECKING:  # imported where used: a run imports xarray while its step compiles
    import xarray as xr


def static_dataset(res: dict, scenario_json: str, kind: str, scales: dict) -> xr.Dataset:
    """The result dataset of one static computation (plots read this)."""
    import xarray as xr

    d = ("rbar",)
    nd = "1"
    v = io.variable
    member = res["member"]
    data = {
        "theta": v(res["theta"], d, "rad", "polar angle of the material point"),
        "theta_initial": v(res["theta_initial"], d, "rad", "initial shape of the march"),
        "theta_member": v(
            res["theta_member"], d, "rad", "selected fully mobilised member (ODE solution)"
        ),
    }
    if "lambda_theta" in res:
        data.update(
            {
                "lambda_theta": v(res["lambda_theta"], d, nd, "meridional stretch"),
                "lambda_phi": v(res["lambda_phi"], d, nd, "hoop stretch"),
                "T_theta": v(
                    res["T_theta"], d, nd, "meridional tension per deformed length", scale="G*h0"
                ),
                "T_phi": v(res["T_phi"], d, nd, "hoop tension per deformed length", scale="G*h0"),
                "F_m": v(res["F_m"], d, nd, "meridional elastic force density", scale="G*h0/R"),
                "F_N": v(res["F_N"], d, nd, "normal force density", scale="G*h0/R"),
                "mu_mobilised": v(
                    res["mu_mobilised"], d, nd, "mobilised friction coefficient |F_f|/F_N"
                ),
                "friction_direction": v(
                    res["friction_direction"],
                    d,
                    nd,
                    "direction of friction on the sheet: +1 toward the equator, -1 toward the pole",
                ),
            }
        )
    data["mu"] = v(res.get("mu", np.nan), (), nd, "friction coefficient returned by the mu search")
    data["mu_family"] = v(
        member.mu, (), nd, "friction coefficient of the selected fully mobilised member"
    )
    chk = res.get("check", {})
    data["F_v"] = v(
        chk.get("F_v", np.nan),
        (),
        nd,
        "vertical force of the ball on the sheet (eq. Fz)",
        scale="G*h0*R",
    )
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


def figure4_dataset(
    dss: list[xr.Dataset], models, scenario_json: str, complete: bool
) -> xr.Dataset:
    """The datasets of the models (:func:`static_dataset`) along a ``model`` dimension."""
    import xarray as xr

    ds = xr.concat(
        dss, dim="model", combine_attrs="drop_conflicts", data_vars="all", coords="minimal"
    )
    ds = ds.assign_coords(model=io.variable(list(models), ("model",), "1", "material model"))
    ds.attrs.update(io.provenance(scenario_json, "figure4"), complete=int(complete))
    ds.attrs.pop("model", None)
    ds.attrs.pop("status", None)
    for name in ("switch_rbar", "switch_theta", "pole_stretch"):
        ds.attrs.pop(name, None)
    return ds


def family_dataset(cols: dict, selected: list, values, models: list[str], mu_paper: list,
                   switch_by: str) -> xr.Dataset:
    """The fully mobilised family (model, member) and the selected members (model)."""
    import xarray as xr

    v = io.variable
    dims = ("model", "member")
    return xr.Dataset(
        {
            "mu": v(cols["mu"], dims, "1", "friction coefficient of the fully mobilised member"),
            "pole_stretch": v(cols["pole_stretch"], dims, "1", "stretch at the pole"),
            "switch_rbar": v(cols["switch_rbar"], dims, "1",
                             "undeformed radius where F_m changes sign", scale="R"),
            "switch_theta": v(cols["switch_theta"], dims, "rad",
                              "polar angle where F_m changes sign"),
            "mu_selected": v([m.mu for m in selected], ("model",), "1",
                             "mu of the member picked by the selection rule"),
            "switch_rbar_selected": v([m.rbar_s for m in selected], ("model",), "1",
                                      "switch radius of that member", scale="R"),
            "switch_theta_selected": v([m.theta_s for m in selected], ("model",), "rad",
                                       "switch angle of that member"),
            "mu_paper": v(mu_paper, ("model",), "1", "the paper's mu"),
        },
        coords={
            "model": v(models, ("model",), "1", "material model"),
            "switch_value": v(values, ("member",), "rad" if switch_by == "switch_angle" else "1",
                              f"family parameter ({switch_by})"),
        },
    )


def cylinder_dataset(mu: float, angles, study: dict) -> xr.Dataset:
    """The 2D cylinder study (:func:`dynslip.analysis.plane_strain.cylinder_study`) with units."""
    import xarray as xr

    v = io.variable
    return xr.Dataset(
        {
            "F_v": v(study["fv"], ("theta_max", "profile"), "1",
                     "vertical force per unit length, random admissible states", scale="T0"),
            "F_v_closed": v(study["fv_closed"], ("theta_max", "profile"), "1",
                            "T(theta_max) sin(theta_max)", scale="T0"),
            "F_v_lower": v(np.exp(-mu * angles) * np.sin(angles), ("theta_max",), "1",
                           "lower bound T0 exp(-mu theta_max) sin(theta_max)", scale="T0"),
            "T": v(study["T"], ("sample", "theta"), "1", "tension of random admissible states",
                   scale="T0"),
            "T_lower": v(study["T_lower"], ("theta",), "1", "capstan lower bound T0 exp(-mu theta)",
                         scale="T0"),
            "T_upper": v(study["T_upper"], ("theta",), "1", "capstan upper bound T0 exp(mu theta)",
                         scale="T0"),
            "mu": v(mu, (), "1", "friction coefficient"),
        },
        coords={
            "theta_max": v(angles, ("theta_max",), "rad", "lift-off angle"),
            "theta": v(study["theta"], ("theta",), "rad", "polar angle on the cylinder"),
        },
    )
