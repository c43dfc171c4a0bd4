r"""Contact of the sheet's nodes with every body: the $C^2$ penalty of
:mod:`dynslip.physics.sheet` applied to each body's signed distance.

Node $i$ at $x_i$ penetrates body $k$ (displaced by $z_k$) by $\delta_{ik} = -d_k(x_i - z_k
e_z)$; the penalty energy per reference area is $\sum_k \phi(\delta_{ik})$, $\phi$
:func:`~dynslip.physics.penalty.penalty_energy`, and the force per reference area it exerts on
the node is

$$f_i = -\nabla_{x_i}\sum_k\phi(\delta_{ik}) = \sum_k p_{ik}\, n_k(x_i),\qquad
  p_{ik} = \phi'(\delta_{ik}) \ge 0,$$

$p$ :func:`~dynslip.physics.penalty.penalty_pressure`, exactly zero at a positive gap, $n_k$ the
body's outward normal. A node feels every body it penetrates; contact is detected by pressure,
never by a gap. The force on body $k$ along the axis is $-\sum_i A_i p_{ik} n_{k,z}$, the
derivative of the energy with respect to $z_k$. For the unit ball,
$\delta = 1 - |x - x_b|$ and $n = (\sin\theta, \cos\theta)$: exactly
:meth:`~dynslip.physics.sheet.SheetModel.penetration` and ``frame``.

Example::

    >>> import jax.numpy as jnp
    >>> from dynslip.physics.bodies.sphere import Sphere
    >>> from dynslip.physics.sheet import Penalty
    >>> c = contact_forces((Sphere(),), jnp.array([[0.0, 0.999], [0.0, 1.2]]), Penalty())
    >>> c.pressure.shape, float(c.pressure[0, 1])
    ((1, 2), 0.0)
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from dynslip.physics.penalty import Penalty, penalty_energy, penalty_pressure

__all__ = ["Contact", "contact_energy_density", "contact_forces"]


class Contact(eqx.Module):
    """Per body and node: ``pressure`` (K, N) the penalty pressure per reference area
    (units G h0 / R), ``normal`` (K, N, 2) the body's outward normal at the node,
    ``distance`` (K, N) the signed distance (R), ``s`` and ``tangent`` the surface coordinate
    and tangent of the closest point."""

    pressure: jnp.ndarray
    normal: jnp.ndarray
    distance: jnp.ndarray
    s: jnp.ndarray
    tangent: jnp.ndarray

    @property
    def force(self):
        """Force per reference area on each node from each body, p n: (K, N, 2)."""
        return self.pressure[..., None] * self.normal


def _positions(bodies, positions):
    return jnp.zeros(len(bodies)) if positions is None else jnp.asarray(positions, float)


def contact_forces(bodies, x_nodes, penalty: Penalty, positions=None) -> Contact:
    """Penalty contact of the nodes ``x_nodes`` (N, 2) = (rho, z) with each of ``bodies`` (a
    tuple of K bodies, displaced along the axis by ``positions`` (K,), 0 if None). Pure JAX;
    the loop is over the few bodies (static), not the nodes."""
    zs = _positions(bodies, positions)
    proj = [b.project(x_nodes, zs[k]) for k, b in enumerate(bodies)]
    d = jnp.stack([p.distance for p in proj])
    return Contact(
        pressure=penalty_pressure(penalty, -d),
        normal=jnp.stack([p.normal for p in proj]),
        distance=d,
        s=jnp.stack([p.s for p in proj]),
        tangent=jnp.stack([p.tangent for p in proj]),
    )


def contact_energy_density(bodies, x_nodes, penalty: Penalty, positions=None):
    """Penalty energy per reference area of each node, summed over the bodies (N,), as
    :func:`~dynslip.physics.penalty.penalty_energy` (times the nodes' reference areas, summed:
    the sheet's penalty energy, G h0 R^2); its negative gradient in x is
    :attr:`Contact.force` summed over the bodies."""
    zs = _positions(bodies, positions)
    return sum(penalty_energy(penalty, -b.distance(x_nodes, zs[k])) for k, b in enumerate(bodies))
