"""The sheet's axisymmetric mesh: node material radii (pole first, units of R), element
lengths and mid radii, element and lumped node reference areas, and the stretches of a deformed
configuration (meridional lambda_theta, hoop lambda_phi) per element and per node."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

__all__ = ["Mesh", "element_stretches", "make_mesh", "mesh_from_radii", "node_stretches"]


class Mesh(eqx.Module):
    """Material radii of the nodes and the derived element/node measures (units of R)."""

    rbar: jnp.ndarray  # (N,) node material radii, rbar[0] = 0
    dr: jnp.ndarray  # (N-1,) element lengths
    rmid: jnp.ndarray  # (N-1,) element mid radii
    area_el: jnp.ndarray  # (N-1,) element reference areas 2 pi rmid dr
    area: jnp.ndarray  # (N,) lumped node reference areas

    @property
    def n(self) -> int:
        return int(self.rbar.shape[0])


def make_mesh(n: int, r_edge: float, grading: float = 1.0, edge_grading: float = 1.0) -> Mesh:
    """Mesh of ``n`` nodes from the pole to the material radius ``r_edge``, at
    ``rbar_i = r_edge v_i**grading``, ``v_i = 1 - (1 - i/(n-1))**edge_grading``: uniform for
    both 1; ``grading > 1`` grades it toward the pole (first element ``r_edge/(n-1)**grading``,
    last about ``grading`` times the uniform one), ``edge_grading > 1`` toward the held edge
    (last element ``r_edge/(n-1)**edge_grading``, first about ``edge_grading`` times the
    uniform one: where the sheet wraps a tube's rim near its edge)."""
    if n < 4:
        raise ValueError("a sheet mesh needs at least 4 nodes")
    if grading < 1.0 or edge_grading < 1.0:
        raise ValueError("mesh grading must be at least 1 (1 is uniform)")
    v = 1.0 - (1.0 - np.linspace(0.0, 1.0, n)) ** edge_grading
    return mesh_from_radii(r_edge * v**grading)


def mesh_from_radii(rbar) -> Mesh:
    """The mesh of the given node material radii (pole first): element lengths, mid radii,
    element areas and lumped node areas (half of each adjacent element's)."""
    rbar = np.asarray(rbar, dtype=float)
    dr = np.diff(rbar)
    rmid = 0.5 * (rbar[1:] + rbar[:-1])
    area_el = 2 * np.pi * rmid * dr
    area = np.zeros(rbar.size)
    area[:-1] += 0.5 * area_el
    area[1:] += 0.5 * area_el
    return Mesh(*(jnp.asarray(a) for a in (rbar, dr, rmid, area_el, area)))


def element_stretches(mesh: Mesh, rho, z):
    """Element stretches (lambda_theta, lambda_phi), each (N-1,)."""
    drho = rho[1:] - rho[:-1]
    dz = z[1:] - z[:-1]
    ds = jnp.sqrt(drho**2 + dz**2)
    lt = ds / mesh.dr
    lp = (rho[1:] + rho[:-1]) / (mesh.rbar[1:] + mesh.rbar[:-1])
    return lt, lp


def node_stretches(mesh: Mesh, rho, z):
    """Node stretches: meridional as the mean of the adjacent elements; hoop rho/rbar
    (at the pole, the first element's hoop stretch)."""
    lt_e, lp_e = element_stretches(mesh, rho, z)
    lt = jnp.concatenate([lt_e[:1], 0.5 * (lt_e[1:] + lt_e[:-1]), lt_e[-1:]])
    rb = jnp.where(mesh.rbar > 0, mesh.rbar, 1.0)
    lp = jnp.where(mesh.rbar > 0, rho / rb, lp_e[0])
    return lt, lp
