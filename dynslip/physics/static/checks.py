r"""Checks on a static shape of the paper's model: the material's range, the saturation of
friction, sign changes and inflections, and the equilibrium of an end state.

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$ (the paper's contact-region model, Section 3;
the package docstring of :mod:`dynslip.physics.static` states the whole model).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from dynslip.errors import MaterialRangeError
from dynslip.physics.materials import AbstractMaterial
from dynslip.physics.static.grid import fields, vertical_force, vertical_force_identity
from dynslip.physics.static.march import velocity


def check_static_range(material: AbstractMaterial, lt, lp, where: str = "") -> None:
    """Raise :class:`MaterialRangeError` where the (unrelaxed) energy is not finite or a
    stretch is not positive (Gent beyond its locking stretch). The paper's model is
    unrelaxed and taut on the ball, so the relaxed Hookean limit of stretch 3 does not apply."""
    lt = np.asarray(lt, float)
    lp = np.asarray(lp, float)
    w = np.asarray(material.energy(jnp.asarray(lt), jnp.asarray(lp)))
    bad = ~((lt > 0) & (lp > 0) & np.isfinite(w) & np.isfinite(lt) & np.isfinite(lp))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MaterialRangeError(
            f"{material.name}: stretches (lambda_theta={lt[i]:.4g}, lambda_phi={lp[i]:.4g}) "
            f"at node {i} outside the material's range{(' ' + where) if where else ''}"
            + (
                f"; the Gent model locks at I1 = J_m + 3 = {material.jm + 3:g}"
                if hasattr(material, "jm")
                else ""
            )
        )


def saturation_fraction(fm, fn, mu, rel=0.02):
    """Fraction of interior nodes where $|F_m| = \\mu F_N$ within ``rel`` (relative)."""
    fm = np.asarray(fm)[1:-1]
    fn = np.asarray(fn)[1:-1]
    return float(np.mean(np.abs(np.abs(fm) - mu * fn) <= rel * mu * np.abs(fn)))


def sign_change_index(fm):
    """Index of the first interior node after which F_m turns from positive to negative."""
    fm = np.asarray(fm)[1:-1]
    idx = np.flatnonzero((fm[:-1] > 0) & (fm[1:] <= 0))
    return int(idx[0]) + 1 if idx.size else -1


def inflection_index(theta):
    """Index of the first node where the second difference of theta turns from + to -."""
    th = np.asarray(theta)
    d2 = th[2:] - 2 * th[1:-1] + th[:-2]
    idx = np.flatnonzero((d2[:-1] > 0) & (d2[1:] <= 0))
    return int(idx[0]) + 1 if idx.size else -1


def check_equilibrium(material, theta, h, mu, *, vtol, force_tol=1e-8, edge_tol=None) -> dict:
    r"""Check a returned state as an equilibrium, with the grid formulas:
    $|F_m| \le \mu F_N + $ tol at every interior node, $\max|\dot\theta| \le$ ``vtol``,
    $F_N > 0$ at interior nodes, and (if ``edge_tol``) $|T_\theta(\bar r_{max})| \le$ ``edge_tol``.
    Returns a dict of the measured quantities with ``ok``."""
    f = fields(material, jnp.asarray(theta), h)
    fm, fn = np.asarray(f.fm)[1:-1], np.asarray(f.fn)[1:-1]
    excess = float(np.max(np.abs(fm) - mu * fn))
    vmax = float(jnp.max(jnp.abs(velocity(material, jnp.asarray(theta), h, mu))))
    fv = float(vertical_force(material, jnp.asarray(theta), h))
    fv_id = float(vertical_force_identity(material, jnp.asarray(theta), h))
    out = {
        "coulomb_excess": excess,
        "vmax": vmax,
        "min_F_N": float(fn.min()),
        "T_theta_edge": float(f.tt[-1]),
        "F_v": fv,
        "F_v_identity": fv_id,
        "F_v_residual": fv - fv_id,
    }
    ok = excess <= force_tol + vmax and vmax <= vtol and out["min_F_N"] > 0
    if edge_tol is not None:
        ok = ok and abs(out["T_theta_edge"]) <= edge_tol
    out["ok"] = bool(ok)
    return out
