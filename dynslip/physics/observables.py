r"""Observables of a frame that are continuous in the parameters (pure JAX): the contact edge
located between nodes, and the polar angle $\theta(\bar r)$ at fixed material radii.

The node-based ``theta_max`` and ``rbar_max`` of a frame are the last contact node's values:
piecewise constant in the parameters (``rbar_max``) or jumping where the contact set changes
(``theta_max``), so a fit or a derivative cannot use them. Here the edge is located where the
contact condition crosses zero.

**The contact function.** A node is in contact when its penalty pressure exceeds the contact
threshold, $\phi'(d_i)/(\lambda_\theta\lambda_\phi)_i > p_c$
(:meth:`~dynslip.physics.sheet.SheetModel.diagnostics`), with $d_i$ the penetration into the
ball. The pressure is increasing in $d$, so the condition is $d_i > d^*_i$, with $d^*_i$ the
penetration at which the pressure equals the threshold (:func:`threshold_penetration`, the
penalty's pressure inverted). The contact function is the penetration past it,

$$c_i = d_i - d^*_i ,$$

positive exactly on the node-based contact set. It is built from the gap, not from the
pressure, because the pressure is identically zero at every free node, so interpolating it
would carry no information from the first free node. It would also place the edge by the
size of the last node's pressure, a step for a membrane, rather than by where the sheet
leaves the ball. The gap of the first free node moves with the lip as the sheet lifts off,
and the function is smooth (C^1) in the positions everywhere.

**The located edge.** Let $j$ be the last node in contact ($c_j > 0$, the node-based edge) and
$k = j + 1$ the first out ($c_k \le 0$). The edge lies at the fraction
$f = c_j/(c_j - c_k) \in [0, 1)$ of the element between them, so
$\bar r_{edge} = \bar r_j + f(\bar r_k - \bar r_j)$ and
$\theta_{edge} = \theta_j + f(\theta_k - \theta_j)$, with $\theta = \operatorname{atan2}(\rho,
z - z_b)$ the polar angle seen from the ball's centre. When node $k$ enters contact, $c_k$
passes through zero, so $f \to 1$ before and the new fraction $\to 0$ after: the edge moves
continuously through the change of the node set. A new contact patch that opens beyond a free
node is a genuine jump (a different contact), and the edge follows it.

**theta at fixed rbar.** The polar angle of the material circle of radius $\bar r$, interpolated
linearly in the material coordinate between the nodes on either side (:func:`theta_at`). On
the contact ($\bar r \le \bar r_{edge}$) it is the paper's $\theta(\bar r)$ (inscribed circles
on the ball). Beyond the edge the circle is off the ball, and the value is its polar angle
from the ball's centre, not a contact angle. At a node's radius it is exactly the node's
value.

Example: a profile with a known edge (the contact function crosses zero at rbar = 0.35)::

    >>> import jax.numpy as jnp
    >>> rbar = jnp.linspace(0.0, 1.0, 11)
    >>> c = 0.35 - rbar                  # positive inside, zero at 0.35
    >>> e = located_edge(rbar, 2 * rbar, c, c > 0)
    >>> round(float(e.rbar), 12), round(float(e.theta), 12)
    (0.35, 0.7)
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

__all__ = ["OBS_RBAR", "Edge", "theta_key", "contact_function", "located_edge", "polar_angle",
           "theta_at", "threshold_penetration"]

OBS_RBAR = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
"""The fixed material radii (R) at which every frame records theta (:func:`theta_key`)."""


def theta_key(r: float) -> str:
    """The frame's key of theta at the material radius ``r`` (R): ``theta_rbar_30`` for 0.3, a
    scalar of its own, so that every scalar of a frame is differentiated
    (:func:`dynslip.physics.driver.tangent.observables`)."""
    return f"theta_rbar_{round(100 * r):02d}"


class Edge(NamedTuple):
    """The located contact edge: its material radius ``rbar`` (R) and polar angle ``theta``
    (rad), NaN without contact; ``fraction`` the place between the last node in contact and the
    next one (0: at the node)."""

    rbar: jnp.ndarray
    theta: jnp.ndarray
    fraction: jnp.ndarray


def polar_angle(rho, z, zb):
    """Each node's polar angle seen from the ball's centre, atan2(rho, z - zb) (rad)."""
    return jnp.arctan2(rho, z - zb)


def threshold_penetration(penalty, pressure):
    r"""The penetration $d^*$ (R) at which the penalty pressure per reference area
    (:func:`dynslip.physics.penalty.penalty_pressure`) equals ``pressure`` (> 0): the inverse of
    $k d^2/(2w)$ below $d = w$ and of $k(d - w/2)$ above it."""
    k, w = penalty.k, penalty.w
    p = jnp.maximum(pressure, 0.0)
    return jnp.where(p < k * w / 2, jnp.sqrt(2 * w * p / k), p / k + w / 2)


def contact_function(model, rho, z, zb, contact_threshold):
    """The contact function c_i = d_i - d*_i of the module docstring (R): positive exactly where
    the node's penalty pressure exceeds ``contact_threshold`` (G h0 / R)."""
    d = model.penetration(rho, z, zb)
    p_star = contact_threshold * model.areal_stretch(rho, z)
    return d - threshold_penetration(model.penalty, p_star)


def located_edge(rbar, theta, c, contact) -> Edge:
    """The contact edge located where the contact function ``c`` (N,) crosses zero after the
    last node of ``contact`` (N, bool): the module docstring. ``rbar``, ``theta`` (N,) the
    nodes' material radii and polar angles."""
    n = rbar.shape[0]
    idx = jnp.arange(n)
    some = jnp.any(contact)
    j = jnp.maximum(jnp.max(jnp.where(contact, idx, -1)), 0)
    k = jnp.minimum(j + 1, n - 1)
    cj, ck = c[j], c[k]
    den = cj - ck
    # the bracket holds on the node-based set (c_j > 0 >= c_k); clipped where rounding makes
    # the pressure test and the gap disagree at the threshold
    safe = jnp.where((den > 0) & (k > j), den, 1.0)
    f = jnp.where((den > 0) & (k > j), jnp.clip(cj / safe, 0.0, 1.0), 0.0)
    rb = rbar[j] + f * (rbar[k] - rbar[j])
    th = theta[j] + f * (theta[k] - theta[j])
    nan = jnp.nan
    return Edge(jnp.where(some, rb, nan), jnp.where(some, th, nan), jnp.where(some, f, nan))


def theta_at(rbar, theta, points=OBS_RBAR):
    """The polar angle of the material circles of radii ``points`` (R): ``theta`` (N,)
    interpolated linearly in the material coordinate ``rbar`` (N,); NaN outside the mesh."""
    pts = jnp.asarray(points, dtype=rbar.dtype)
    return jnp.interp(pts, rbar, theta, left=jnp.nan, right=jnp.nan)
