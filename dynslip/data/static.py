"""The result dataset of one static computation (``result.nc`` of ``kind: static``, a row
of ``figure4``): the shapes, stretches, tensions and forces on the grid, with units."""

from __future__ import annotations

import numpy as np
import xarray as xr

from dynslip.data import files as io


def static_dataset(res: dict, scenario_json: str, kind: str, scales: dict) -> xr.Dataset:
    """The result dataset of one static computation (plots read this)."""
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
