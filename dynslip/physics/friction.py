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

:class:`AbstractFriction` is the interface the driver uses. :class:`SlipWeakening`
(static/kinetic, physics.md Section 4 "Friction") carries one internal state per node,
the slip distance $\delta$ accumulated since the node last stuck:

$$\mu(\delta) = \mu_k + (\mu_s - \mu_k)\max(0, 1 - \delta/d_c),\qquad
  \dot\delta = |u_t|\ \text{(in contact)},$$

reset to 0 where the node has *healed* or is out of contact. Healing criterion (one for
every solver, :func:`heals`): the node's slip rate $|u_t| = |S|/(\eta A)$ is at most a
stated reference rate $v_h$ (``numerics.heal_rate_mm_s``). A node that settles onto its
friction limit approaches $S = 0$ only asymptotically (its slip rate decays like
$e^{-Kt/\eta}$), so the force criterion $S = 0$ alone ($v_h = 0$) never heals it and it
stays weakened at $\mu_k$ for ever; with $v_h > 0$ it heals once it has all but stopped.
The reset is a jump: the time-stepped driver applies it at every restart (the end of each
save segment, :func:`dynslip.physics.driver.simulate.simulate`), so its time resolution is the
save interval.
Slip-distance weakening is rate independent (no time scale enters $\mu$) and well
posed for $d_c > 0$; velocity weakening is neither and is not offered.

:class:`PressureDependent` (physics.md Section 4, "The experiment's world": rubber on a smooth
hard surface) makes the coefficient fall as the contact pressure $p = N/A$ rises, the power law
of Schallamach (1952),

$$\mu(p) = \min\bigl(\mu_\mathrm{ref}\,(p/p_\mathrm{ref})^{-a},\ \mu_\mathrm{max}\bigr),
  \qquad 0 \le a < 1,$$

the minimum rounded to $C^1$ in $\ln\mu$ over a band of relative width $e^{\pm w}$ below
$\mu_\mathrm{max}$ (:func:`capped_log`), so that the threshold $\mu(p) N$ is $C^1$ in $N$
and its derivative, which the return map differentiates, stays between $(1-a)\mu$ and
$\mu_\mathrm{max}$. The power law alone makes $\mu \to \infty$ as $p \to 0$ (its
derivative $d(\mu N)/dN = (1-a)\mu$ too); the bound $\mu_\mathrm{max}$ is where the
power law is no longer rubber's friction. At $a = 0$ the law is :class:`Coulomb` exactly.
:func:`capstan_reference_tension` is the tension at which a strip test measures
$\mu_\mathrm{ref}$ when the strip's friction follows this law.

:class:`Adhesive` (docs/adhesion.md) is slip weakening plus a Bowden-Tabor shear strength
$\tau_0$ over the node's contact area within the ball penalty's cohesive range: the threshold
$\mu\max(N, 0) + \tau_0 A_c$, positive under tension while the node adheres.
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax.numpy as jnp

from dynslip.physics.penalty import cohesive_fraction

__all__ = [
    "AbstractFriction",
    "Coulomb",
    "SlipWeakening",
    "PressureDependent",
    "Adhesive",
    "capped_log",
    "capstan_reference_tension",
    "soft_threshold",
    "weighted_form",
    "heals",
]


def soft_threshold(f, c, eps=0.0, weight=1.0):
    r"""Force-space soft threshold $S_\epsilon(f, c)$, elementwise.

    ``eps = 0`` is the ideal law $\operatorname{sign}(f)\max(|f|-c, 0)$. For
    ``eps > 0`` the kink at $|f| = c$ is replaced by the $C^1$ blend
    $(|f| - c + e)^2 / (4e)$ on $c - e < |f| < c + e$ with $e = \epsilon c/(c+\epsilon)$;
    $S = 0$ exactly for $|f| \le c - e$. ``c >= 0`` is required.

    ``weight`` $\gamma \ne 1$: the law's weighted form $\gamma\Psi_\gamma(y)$, the same
    curve $v = S_\epsilon(f)$ read at $y = f + (\gamma - 1)v$ (:func:`weighted_form`;
    ``f`` is then $y$).
    """
    if not (isinstance(weight, (int, float)) and weight == 1.0):
        return weighted_form(f, c, eps, weight)
    f = jnp.asarray(f)
    c = jnp.asarray(c)
    a = jnp.abs(f)
    ideal = jnp.maximum(a - c, 0.0)
    if isinstance(eps, (int, float)) and eps == 0.0:
        return jnp.sign(f) * ideal
    e, e_safe = _band_width(c, eps)
    blend = (a - c + e) ** 2 / (4.0 * e_safe)
    in_band = (a > c - e) & (a < c + e) & (e > 0)
    mag = jnp.where(in_band, blend, ideal)
    return jnp.sign(f) * mag


def _band_width(c, eps):
    r"""The smoothing band's half-width $e = \epsilon c/(c + \epsilon)$ (0 where $c + \epsilon
    = 0$), and $e$ safe to divide by (1 where it is 0)."""
    # Double-where: at c + eps = 0 the quotient is replaced before it is formed, so
    # reverse-mode derivatives stay finite (a 1e-300 guard underflows when squared).
    den = c + eps
    den_safe = jnp.where(den > 0, den, 1.0)
    e = jnp.where(den > 0, eps * c / den_safe, 0.0)
    return e, jnp.where(e > 0, e, 1.0)


def weighted_form(y, c, eps, weight):
    r"""The soft threshold's curve $v = S_\epsilon(f, c)$ read at $y = f + (\gamma - 1)v$
    (``weight`` $\gamma > 0$): returns $\gamma v$, elementwise.

    $y$ grows along the curve, so $v = \Psi_\gamma(y)$ is a function: 0 for $|y| \le c - e$;
    in the band, with $b = |y| - c + e$ and $a = |f| - c + e$ solving $a + (\gamma - 1)\,a^2/
    (4e) = b$, $a = 2b/(1 + \sqrt{1 + (\gamma - 1)\,b/e})$ and $v = a^2/(4e)$, for
    $0 < b < (\gamma + 1)\,e$; past it $v = (|y| - c)/\gamma$. So $\gamma\Psi_\gamma$ is
    $S_\epsilon$ at $\gamma = 1$ and the ideal threshold of $y$ at $\epsilon = 0$, and a
    node's row $\eta A u_t = \gamma\Psi_\gamma(y) - (\gamma - 1)\eta A u_t$ has exactly
    the law's roots (:func:`dynslip.physics.solver.increment.weighted_slip`)."""
    y = jnp.asarray(y)
    c = jnp.asarray(c)
    r = jnp.abs(y)
    if isinstance(eps, (int, float)) and eps == 0.0:
        return jnp.sign(y) * jnp.maximum(r - c, 0.0)
    e, e_safe = _band_width(c, eps)
    # the band's b, kept inside it so that the unused branch's root stays finite
    b = jnp.clip(r - c + e, 0.0, (weight + 1.0) * e)
    a = 2.0 * b / (1.0 + jnp.sqrt(1.0 + (weight - 1.0) * b / e_safe))
    band = weight * a**2 / (4.0 * e_safe)
    in_band = (r > c - e) & (r < c + weight * e) & (e > 0)
    mag = jnp.where(in_band, band, jnp.maximum(r - c, 0.0))
    return jnp.sign(y) * mag


def heals(slip_speed, normal, heal_rate):
    r"""The healing criterion: stuck again where $|u_t| \le v_h$, or out of contact ($N \le 0$).

    ``slip_speed`` is $S/(\eta A)$ (R/s), ``heal_rate`` $v_h \ge 0$ (R/s); ``heal_rate = 0``
    is the bare force criterion $S = 0$.
    """
    return (jnp.abs(slip_speed) <= heal_rate) | (normal <= 0.0)


class AbstractFriction(eqx.Module):
    """A friction law: tangential slip force from the driving and normal forces.

    ``slip_force(ft, fn, internal, eps, area)`` returns $S$ (same shape as ``ft``), the part of
    the tangential force that is not cancelled by friction; the slip velocity is
    $S/(\\eta A)$. ``eps`` is the force-space smoothing per node (the law's own ``eps``
    when None). ``area`` is the node's contact area as :meth:`contact_area` chooses it (units
    of $R^2$), so that a law may depend on the contact pressure $N/A$; the laws here other
    than :class:`PressureDependent` ignore it. Laws with memory carry ``n_internal()`` values
    per node.
    """

    eps: eqx.AbstractVar[float | jnp.ndarray]

    @abc.abstractmethod
    def threshold(self, fn, internal=None, area=None):
        """Friction threshold $\\mu N$ per node (``area``: the node's reference area)."""

    def slip_force(self, ft, fn, internal=None, eps=None, area=None, weight=1.0):
        """Unbalanced tangential force $S$; exactly zero while stuck. ``weight`` $\ne 1$: the
        law's weighted form read at ``ft`` $= y$ (:func:`weighted_form`)."""
        e = self.eps if eps is None else eps
        return soft_threshold(ft, self.threshold(fn, internal, area), e, weight)

    def stuck(self, ft, fn, internal=None, eps=None, area=None):
        """Force criterion for sticking: $S = 0$ exactly."""
        return self.slip_force(ft, fn, internal, eps, area) == 0.0

    def coefficient(self, internal, n: int):
        """The current friction coefficient per node (n,)."""
        raise NotImplementedError

    def contact_area(self, area, areal_stretch, penetration=None):
        """The area the law reads its pressure on, from the node's reference area, its
        areal stretch $\\lambda_t\\lambda_\\phi$ and its penetration into the ball (R; None:
        not known): the reference area (a law that ignores it)."""
        return area

    def n_internal(self) -> int:
        """Number of internal state variables per node (0: memoryless law)."""
        return 0

    def internal_rate(self, slip_speed, normal, internal):
        """Rate of the per-node internal state (shape of ``internal``)."""
        return jnp.zeros_like(internal)

    def reset(self, internal, slip_speed, normal, heal_rate=0.0):
        r"""The internal state after a restart (unchanged for memoryless laws); ``slip_speed``
        $S/(\eta A)$ and ``heal_rate`` as in :func:`heals`."""
        return internal


class Coulomb(AbstractFriction):
    r"""Ideal Coulomb friction, $\mu$ constant, optional force-space smoothing $\epsilon$.

    ``mu`` is dimensionless, ``eps`` in the units of the forces passed (the driver
    passes node forces in units of $G h_0 R$, so the scenario's smoothing, stated as
    a force density in units of $G h_0/R$, is multiplied by the node's reference area).
    """

    mu: float | jnp.ndarray = 1.0
    eps: float | jnp.ndarray = 0.0

    def threshold(self, fn, internal=None, area=None):
        return self.mu * jnp.maximum(fn, 0.0)

    def coefficient(self, internal, n: int):
        return jnp.full(n, self.mu, dtype=float)


class SlipWeakening(AbstractFriction):
    r"""Static/kinetic friction by slip-distance weakening (module docstring).

    ``mu_s >= mu_k >= 0``; ``d_c > 0`` the weakening length (units of R); one internal
    state per node, the slip distance since the node last stuck (units of R). With
    ``mu_s == mu_k`` it is :class:`Coulomb` with ``mu = mu_s`` exactly.
    """

    mu_s: float | jnp.ndarray = 0.99
    mu_k: float | jnp.ndarray = 0.82
    d_c: float | jnp.ndarray = 0.02
    eps: float | jnp.ndarray = 0.0

    def coefficient(self, internal, n: int | None = None):
        w = jnp.clip(1.0 - internal / self.d_c, 0.0, 1.0)
        return self.mu_k + (self.mu_s - self.mu_k) * w

    def threshold(self, fn, internal=None, area=None):
        mu = self.mu_s if internal is None else self.coefficient(internal)
        return mu * jnp.maximum(fn, 0.0)

    def n_internal(self) -> int:
        return 1

    def internal_rate(self, slip_speed, normal, internal):
        return jnp.where(normal > 0, jnp.abs(slip_speed), 0.0)

    def reset(self, internal, slip_speed, normal, heal_rate=0.0):
        return jnp.where(heals(slip_speed, normal, heal_rate), 0.0, internal)


class Adhesive(SlipWeakening):
    r"""Slip weakening with an interfacial shear strength (Bowden-Tabor) and a contact range
    (docs/adhesion.md): the threshold per node is

    $$c = \mu(\delta)\max(N, 0) + \tau_0(\delta)\,A_c,\qquad
      \tau_0(\delta) = \tau_k + (\tau_s - \tau_k)\max(0, 1 - \delta/d_c),$$

    the shear strength weakening with the slip distance as $\mu$ does (``tau_s >= tau_k >= 0``,
    $G h_0/R$), and $A_c$ the node's contact area: its deformed area $A_0\lambda_t
    \lambda_\phi$ (``deformed_area``; False: $A_0$) times the fraction $s(d)$ of the cohesive
    range it is within (:func:`dynslip.physics.penalty.cohesive_fraction`, range ``reach`` R:
    1 at contact, 0 at a gap of ``reach``). So the threshold stays $\tau_0 A_c > 0$ where the
    node is held in the cohesive range under a tensile normal force (friction under tension
    while adhesion holds), and falls continuously to 0 as the gap opens. The normal adhesion
    itself is the ball's penalty's well (:class:`dynslip.physics.penalty.Penalty`
    ``adhesion``, same ``reach``). The slip distance advances and heals as
    :class:`SlipWeakening`'s, where $N > 0$ (a node held under tension keeps its static
    values). With ``tau_s = tau_k = 0`` it is :class:`SlipWeakening` exactly."""

    tau_s: float | jnp.ndarray = 0.0
    tau_k: float | jnp.ndarray = 0.0
    reach: float | jnp.ndarray = 1.0e-3
    deformed_area: bool = eqx.field(static=True, default=True)

    def contact_area(self, area, areal_stretch, penetration=None):
        if penetration is None:
            raise ValueError("Adhesive friction needs the node's penetration into the ball")
        a = area * areal_stretch if self.deformed_area else area
        return a * cohesive_fraction(self.reach, penetration)

    def shear_strength(self, internal=None):
        r"""$\tau_0(\delta)$ per node ($\tau_s$ without a slip distance)."""
        if internal is None:
            return self.tau_s
        w = jnp.clip(1.0 - internal / self.d_c, 0.0, 1.0)
        return self.tau_k + (self.tau_s - self.tau_k) * w

    def threshold(self, fn, internal=None, area=None):
        if area is None:
            raise ValueError("Adhesive friction needs the node's contact area")
        return super().threshold(fn, internal, area) + self.shear_strength(internal) * area


#: width $w$ of the $C^1$ rounding of the cap, in $\ln\mu$: the power law holds exactly where
#: $\mu \le \mu_\mathrm{max} e^{-w}$ (5% below the cap), the cap where it would exceed
#: $\mu_\mathrm{max} e^{w}$
CAP_BLEND = 0.05

#: the smallest pressure the law evaluates its power at, relative to $p_\mathrm{ref}$ (below it,
#: and below the cap's pressure, $\mu$ is the cap); keeps $p^{-a}$ and its derivative finite
_P_FLOOR = 1e-200


def capped_log(x, w):
    r"""$C^1$ rounding of $\min(x, 0)$ on $|x| < w$: $x$ for $x \le -w$,
    $x - (x + w)^2/(4w)$ between, $0$ at $x = w$ and beyond (the callers clip $x \le w$)."""
    return jnp.where(x <= -w, x, x - (x + w) ** 2 / (4.0 * w))


class PressureDependent(AbstractFriction):
    r"""Friction falling with the contact pressure (Schallamach), bounded at low pressure
    (module docstring).

    ``mu_ref``: the coefficient at the reference pressure ``p_ref`` ($G h_0/R$, $> 0$);
    ``a``: the exponent, $0 \le a < 1$ ($a \ge 1$: a friction force that does not rise with
    the load); ``mu_max``: the bound, at least $\mu_\mathrm{ref} e^{w}$ so that the law
    passes through $(p_\mathrm{ref}, \mu_\mathrm{ref})$ exactly; ``blend``: $w$. The pressure
    is $p = N/A$ on the deformed area $A = A_0\lambda_t\lambda_\phi$ (``deformed_area``; False:
    on the reference area $A_0$, which overstates $p$ by the areal stretch, up to about 20 in a
    pocket, and so understates $\mu$). Memoryless.
    """

    mu_ref: float | jnp.ndarray = 0.99
    p_ref: float | jnp.ndarray = 0.2
    a: float | jnp.ndarray = 1.0 / 3.0
    mu_max: float | jnp.ndarray = 2.18
    blend: float | jnp.ndarray = CAP_BLEND
    eps: float | jnp.ndarray = 0.0
    deformed_area: bool = eqx.field(static=True, default=True)

    def contact_area(self, area, areal_stretch, penetration=None):
        return area * areal_stretch if self.deformed_area else area

    def mu(self, p):
        r"""$\mu(p)$ per node, $p \ge 0$ in the units of ``p_ref``."""
        a = jnp.asarray(self.a, dtype=float)
        w = self.blend
        # the pressure above which the power law is below the top of the blend band, mu_max e^w
        a_safe = jnp.where(a > 0, a, 1.0)
        ratio = self.mu_ref / (self.mu_max * jnp.exp(w))
        p_cap = jnp.where(a > 0, self.p_ref * ratio ** (1.0 / a_safe), 0.0)
        pc = jnp.maximum(jnp.maximum(p, p_cap), _P_FLOOR * self.p_ref)
        mu_pow = self.mu_ref * (pc / self.p_ref) ** (-a)
        x = jnp.log(mu_pow / self.mu_max)
        capped = self.mu_max * jnp.exp(capped_log(x, w))
        return jnp.where(x <= -w, mu_pow, capped)

    def threshold(self, fn, internal=None, area=None):
        if area is None:
            raise ValueError("PressureDependent friction needs the node's area (p = N / A)")
        n = jnp.maximum(fn, 0.0)
        return self.mu(n / area) * n

    def coefficient(self, internal, n: int, fn=None, area=None):
        r"""$\mu(N/A)$ per node given the normal force and area; NaN without them (the law's
        coefficient is a function of the pressure, not of a state)."""
        if fn is None or area is None:
            return jnp.full(n, jnp.nan, dtype=float)
        return self.mu(jnp.maximum(fn, 0.0) / area)


def capstan_reference_tension(t_hold, t_load, a):
    r"""The tension $T_\mathrm{ref}$ at which a capstan strip test, read with the belt formula
    $\mu = \ln(T_\mathrm{load}/T_\mathrm{hold})/\theta$, measures $\mu_\mathrm{ref} = \mu$
    of a strip whose friction follows $\mu = \mu_\mathrm{ref}(T/T_\mathrm{ref})^{-a}$
    (pressure $T/(R w)$ proportional to the tension, below the cap).

    $dT/d\theta = \mu_\mathrm{ref} (T/T_\mathrm{ref})^{-a} T$ integrates to
    $T_\mathrm{load}^a - T_\mathrm{hold}^a = a\,\mu_\mathrm{ref} T_\mathrm{ref}^a\,\theta$;
    with $\mu_\mathrm{ref}\theta = \ln(T_\mathrm{load}/T_\mathrm{hold})$,
    $T_\mathrm{ref} = [(T_\mathrm{load}^a - T_\mathrm{hold}^a)/(a \ln(T_\mathrm{load}/
    T_\mathrm{hold}))]^{1/a}$, a mean of the two tensions (their logarithmic mean's
    generalisation; $\sqrt{T_\mathrm{hold} T_\mathrm{load}}$ as $a \to 0$). Plain floats.
    """

    lr = math.log(t_load / t_hold)
    if a == 0:
        return math.sqrt(t_hold * t_load)
    return ((t_load**a - t_hold**a) / (a * lr)) ** (1.0 / a)
