"""A trajectory as 3D surfaces for ParaView (and VisIt, pyvista): the sheet's meridian revolved
about the axis, the rigid ball as a sphere (or its own outline revolved, :func:`revolved_mesh`)
and each held body's outline revolved, with :mod:`meshio` meshes for each saved frame. The
outlines come in as plain data (``dynslip.app.drawn``): this layer knows no body object.

Physical units: points in mm (the ball centre on the axis, at ``ball_z``); the field names
carry their units (``pressure [MPa]``). The sheet is ``n_phi`` meridians of the ``rbar``
nodes, node ``i`` of meridian ``j`` at point ``j * n_nodes + i``, joined by quads (those at
the pole, where ``rho = 0``, are degenerate: two corners coincide). Point data are the
per-node variables; cell data (both stretches and both tensions) are the mean of an
element's two end nodes, as the contract stores node values.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from dynslip.data.trajectory import STUCK, state_array

#: point data: name in the file -> (variable, factor from the core's scales: "R", "R/s",
#: "G*h0/R" or None)
POINT_FIELDS = {
    "state [0 free, 1 stuck, 2 slip to pole, 3 slip to equator]": ("state", None),
    "stuck [1]": ("stuck", None),
    "slip_velocity [mm/s]": ("slip_velocity", "R"),
    "slip_distance [mm]": ("slip_distance", "R"),
    "pressure [MPa]": ("pressure", "G*h0/R"),
    "friction [MPa]": ("friction", "G*h0/R"),
    "mu_mobilised [1]": ("mu_mobilised", None),
}
#: cell data: name in the file -> (variable, factor)
CELL_FIELDS = {
    "lambda_theta [1]": ("lambda_theta", None),
    "lambda_phi [1]": ("lambda_phi", None),
    "T_theta [N/mm]": ("T_theta", "G*h0"),
    "T_phi [N/mm]": ("T_phi", "G*h0"),
}


def scales(ds: xr.Dataset) -> dict[str, float]:
    """Factors from the core's units to those of the files (mm, mm/s, MPa, N/mm)."""
    r_mm = float(ds.attrs["R_m"]) * 1e3
    g_mpa = float(ds.attrs["G_Pa"]) * 1e-6
    h0_mm = float(ds.attrs["h0_m"]) * 1e3
    return {"R": r_mm, "G*h0": g_mpa * h0_mm, "G*h0/R": g_mpa * h0_mm / r_mm}


def _values(ds: xr.Dataset, name: str, k: int) -> np.ndarray:
    if name == "state":
        return state_array(ds)[k].astype(np.int32)
    if name == "stuck":
        return (state_array(ds)[k] == STUCK).astype(np.int32)
    if name not in ds:
        return np.zeros(ds.sizes["rbar"])  # a field the file lacks (e.g. slip_distance)
    return np.asarray(ds[name].transpose("time", "rbar").values[k], dtype=float)


def _quads(n_nodes: int, n_phi: int) -> np.ndarray:
    i = np.arange(n_nodes - 1)
    j = np.arange(n_phi)
    a = (j[:, None] * n_nodes + i[None, :]).ravel()
    b = (((j[:, None] + 1) % n_phi) * n_nodes + i[None, :]).ravel()
    return np.stack([a, a + 1, b + 1, b], axis=1)


def sheet_mesh(ds: xr.Dataset, k: int, n_phi: int = 48):
    """The sheet at saved frame ``k`` as a meshio mesh of quads."""
    import meshio

    sc = scales(ds)
    rho = np.asarray(ds["rho"].transpose("time", "rbar").values[k], float) * sc["R"]
    z = np.asarray(ds["z"].transpose("time", "rbar").values[k], float) * sc["R"]
    n = rho.size
    phi = 2.0 * np.pi * np.arange(n_phi) / n_phi
    pts = np.stack(
        [np.outer(np.cos(phi), rho).ravel(), np.outer(np.sin(phi), rho).ravel(), np.tile(z, n_phi)],
        axis=1,
    )
    point_data = {}
    for label, (var, scale) in POINT_FIELDS.items():
        v = _values(ds, var, k)
        v = v * sc[scale] if scale else v
        point_data[label] = np.tile(v, n_phi)
    cell_data = {}
    for label, (var, scale) in CELL_FIELDS.items():
        v = _values(ds, var, k)
        v = 0.5 * (v[:-1] + v[1:]) * (sc[scale] if scale else 1.0)
        cell_data[label] = [np.tile(v, n_phi)]
    return meshio.Mesh(
        pts, [("quad", _quads(n, n_phi))], point_data=point_data, cell_data=cell_data
    )


def revolved_mesh(outline, scale: float, shift: float = 0.0, n_phi: int = 48):
    """The surface of revolution of a meridian outline (M, 2) = (rho, z) (units of R, a closed
    polyline), scaled by ``scale`` (mm per R) and displaced by ``shift`` (R) along the axis:
    quads between consecutive outline points and meridians."""
    import meshio

    o = np.asarray(outline, float)
    rho, z = o[:, 0] * scale, (o[:, 1] + shift) * scale
    phi = 2.0 * np.pi * np.arange(n_phi) / n_phi
    pts = np.stack(
        [np.outer(np.cos(phi), rho).ravel(), np.outer(np.sin(phi), rho).ravel(), np.tile(z, n_phi)],
        axis=1,
    )
    return meshio.Mesh(pts, [("quad", _quads(o.shape[0], n_phi))])


def ball_mesh(ds: xr.Dataset, k: int, n_theta: int = 24, n_phi: int = 48, outline=None):
    """The rigid ball at saved frame ``k``: a sphere of radius R about (0, 0, ball_z), quads;
    ``outline`` (M, 2), units of R, at ``ball_z = 0``: that outline revolved instead (a ball
    that is not the unit sphere, e.g. the coin's disc)."""
    import meshio

    r = scales(ds)["R"]
    if outline is not None:
        return revolved_mesh(outline, r, float(ds["ball_z"].values[k]), n_phi)
    zc = float(ds["ball_z"].values[k]) * r
    th = np.linspace(0.0, np.pi, n_theta + 1)
    phi = 2.0 * np.pi * np.arange(n_phi) / n_phi
    pts = np.stack(
        [
            np.outer(np.cos(phi), r * np.sin(th)).ravel(),
            np.outer(np.sin(phi), r * np.sin(th)).ravel(),
            np.tile(zc + r * np.cos(th), n_phi),
        ],
        axis=1,
    )
    return meshio.Mesh(pts, [("quad", _quads(n_theta + 1, n_phi))])
