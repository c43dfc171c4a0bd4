r"""Friction laws for the overdamped whole-sheet model, as swappable ``eqx.Module``\ s.

In overdamped dynamics Coulomb friction is a *soft threshold* on the tangential
force (paper Section 4.2; physics.md Section 4, "Friction"): a node with tangential
driving force $F_t$ and normal force $N$ slips relative to the ball at

$$\eta A\,u_t = S(F_t, \mu N),\qquad S(f, c) = \operatorname{sign}(f)\max(|f| - c, 0),$$

and the friction force on it is $f = S(F_t, \mu N) - F_t$ (it cancels $F_t$ while
stuck, and is $-\mu N\,\operatorname{sign}(F_t)$ while slipping). The dissipated
power $-f\,u_t = (F_t - S) S / (\eta A) \ge 0$.

Smoothing, where used, is in *force space* only: the law is exactly zero for
$|f| \le c - e$ and exact for $|f| \ge c + e$, with a quadratic blend between, and a
width $e = \epsilon c/(c + \epsilon)$ that never exceeds $c$ (so a node with no
normal force moves freely, $S = f$). Smoothing in velocity is not offered: it makes
loaded-but-stuck nodes creep (physics.md).

:class:`AbstractFriction` is the interface the driver uses; the next issue adds a
slip-distance-weakening law (static/kinetic), which needs a per-node internal state:
:meth:`AbstractFriction.n_internal` and :meth:`AbstractFriction.internal_rate` are
the hooks (zero-sized for the laws here).
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp

__all__ = ["AbstractFriction", "Coulomb", "soft_threshold"]


def soft_threshold(f, c, eps=0.0):
    r"""Force-space soft threshold $S_\epsilon(f, c)$, elementwise.

    ``eps = 0`` is the ideal law $\operatorname{sign}(f)\max(|f|-c, 0)$. For
    ``eps > 0`` the kink at $|f| = c$ is replaced by the $C^1$ blend
    $(|f| - c + e)^2 / (4e)$ on $c - e < |f| < c + e$ with $e = \epsilon c/(c+\epsilon)$;
    $S = 0$ exactly for $|f| \le c - e$. ``c >= 0`` is required.
    """
    f = jnp.asarray(f)
    c = jnp.asarray(c)
    a = jnp.abs(f)
    ideal = jnp.maximum(a - c, 0.0)
    if isinstance(eps, (int, float)) and eps == 0.0:
        return jnp.sign(f) * ideal
    # Double-where: at c + eps = 0 the quotient is replaced before it is formed, so
    # reverse-mode derivatives stay finite (a 1e-300 guard underflows when squared).
    den = c + eps
    den_safe = jnp.where(den > 0, den, 1.0)
    e = jnp.where(den > 0, eps * c / den_safe, 0.0)
    e_safe = jnp.where(e > 0, e, 1.0)
    blend = (a - c + e) ** 2 / (4.0 * e_safe)
    in_band = (a > c - e) & (a < c + e) & (e > 0)
    mag = jnp.where(in_band, blend, ideal)
    return jnp.sign(f) * mag


class AbstractFriction(eqx.Module):
    """A friction law: tangential slip force from the driving and normal forces.

    ``slip_force(ft, fn, internal)`` returns $S$ (same shape as ``ft``), the part of
    the tangential force that is not cancelled by friction; the slip velocity is
    $S/(\\eta A)$. ``stuck(ft, fn, internal)`` is the force criterion (True where the
    law gives exactly zero slip).
    """

    @abc.abstractmethod
    def slip_force(self, ft, fn, internal=None):
        """Unbalanced tangential force $S$; exactly zero while stuck."""

    @abc.abstractmethod
    def threshold(self, fn, internal=None):
        """Friction threshold $\\mu N$ per node."""

    def stuck(self, ft, fn, internal=None):
        """Force criterion for sticking: $S = 0$ exactly."""
        return self.slip_force(ft, fn, internal) == 0.0

    def n_internal(self) -> int:
        """Number of internal state variables per node (0: memoryless law)."""
        return 0

    def internal_rate(self, slip_speed, internal):
        """Rate of the per-node internal state (none here)."""
        return internal


class Coulomb(AbstractFriction):
    r"""Ideal Coulomb friction, $\mu$ constant, optional force-space smoothing $\epsilon$.

    ``mu`` is dimensionless, ``eps`` in the units of the forces passed (the driver
    passes node forces in units of $G h_0 R$, so the scenario's smoothing, stated as
    a force density in units of $G h_0/R$, is multiplied by the node's reference area).
    """

    mu: float | jnp.ndarray = 1.0
    eps: float | jnp.ndarray = 0.0

    def threshold(self, fn, internal=None):
        return self.mu * jnp.maximum(fn, 0.0)

    def slip_force(self, ft, fn, internal=None, eps=None):
        e = self.eps if eps is None else eps
        return soft_threshold(ft, self.threshold(fn), e)
