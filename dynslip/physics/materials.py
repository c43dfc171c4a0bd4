r"""Hyperelastic membrane energies, tensions and the tension-field relaxation.

Every material is an incompressible isotropic strain energy $W(\lambda_\theta,\lambda_\phi)$
per unit *reference volume*, in units of the shear modulus $G$
(paper Section 4.2; physics.md Section 2):

- Hookean (small strain): $2[(l_t-1)^2 + (l_p-1)^2 + (l_t-1)(l_p-1)]$
- Mooney-Rivlin: $C_1(I_1-3) + C_2(I_2-3)$ with $2C_1 + 2C_2 = 1$
- neo-Hookean: $(I_1-3)/2$
- Gent: $-(J_m/2)\ln(1-(I_1-3)/J_m)$

with $I_1 = l_t^2 + l_p^2 + 1/(l_t l_p)^2$ and $I_2 = (l_t l_p)^2 + l_t^{-2} + l_p^{-2}$.

Tensions (force per *deformed* length, units of $G h_0$) follow by automatic
differentiation, with the paper's eq. (2) typo fixed (physics.md Section 2):

$$T_\theta = \frac{1}{\lambda_\phi}\frac{\partial W}{\partial\lambda_\theta},\qquad
  T_\phi = \frac{1}{\lambda_\theta}\frac{\partial W}{\partial\lambda_\phi}.$$

The *relaxed* energy (tension-field theory, physics.md Section 4) replaces $W$ where
the membrane would be in compression: wrinkled in one direction it carries the
uniaxial energy $W(l, w(l))$, with $w(l)$ the natural width under uniaxial stretch
$l$ ($l^{-1/2}$ for every incompressible model, $1-(l-1)/2$ for the Hookean one);
slack (both stretches at or below one) it carries nothing. The Hookean natural width
vanishes at $l = 3$: beyond it the relaxed Hookean energy is meaningless and is
refused (NaN inside kernels, :class:`MaterialRangeError` at the public API).
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.errors import MaterialRangeError

__all__ = [
    "AbstractMaterial",
    "AbstractIncompressible",
    "Hookean",
    "NeoHookean",
    "MooneyRivlin",
    "Gent",
    "tensions",
    "relaxed_energy",
    "relaxed_tensions",
    "check_range",
    "make_material",
    "MATERIALS",
]


def invariants(lt, lp):
    """First and second invariants of the left Cauchy-Green tensor (incompressible)."""
    lz2 = 1.0 / (lt * lp) ** 2
    i1 = lt**2 + lp**2 + lz2
    i2 = (lt * lp) ** 2 + 1.0 / lt**2 + 1.0 / lp**2
    return i1, i2


class AbstractMaterial(eqx.Module):
    """A membrane strain energy $W(\\lambda_\\theta, \\lambda_\\phi)$ in units of $G$.

    The equinox pattern: every method is abstract or final (no concrete method is
    overridden). Each final material implements :meth:`energy` (elementwise, jit- and
    grad-safe), :meth:`max_uniaxial_stretch` and, unless an abstract class between
    implements it (:class:`AbstractIncompressible`), :meth:`natural_width`;
    :meth:`in_range` and :attr:`name` are final.
    """

    @abc.abstractmethod
    def energy(self, lt, lp):
        """Strain energy per reference volume, units of G; NaN or inf outside range."""

    @abc.abstractmethod
    def natural_width(self, l):
        """Width under uniaxial stretch ``l`` with zero transverse stress."""

    @abc.abstractmethod
    def max_uniaxial_stretch(self):
        """Largest uniaxial stretch where the (relaxed) energy is defined (a float, or a 0-d
        array where the material's parameters are arrays)."""

    def in_range(self, lt, lp):
        """Boolean array: True where the relaxed energy is defined and finite."""
        lt = jnp.asarray(lt)
        lp = jnp.asarray(lp)
        ok = (lt > 0) & (lp > 0)
        lmax = self.max_uniaxial_stretch()
        return ok & (lt < lmax) & (lp < lmax) & jnp.isfinite(relaxed_energy(self, lt, lp))

    @property
    def name(self) -> str:
        return type(self).__name__


class AbstractIncompressible(AbstractMaterial):
    """A material whose natural width under uniaxial stretch is that of exact
    incompressibility (the Mooney-Rivlin family and Gent)."""

    def natural_width(self, l):
        """Width under uniaxial stretch ``l`` with zero transverse stress: ``l**-0.5`` (as
        ``rsqrt``: a power costs several times more, and the Newton matrix differentiates it
        twice)."""
        return jax.lax.rsqrt(jnp.asarray(l, float))


class Hookean(AbstractMaterial):
    r"""Small-strain (Hookean) membrane energy, $E = 3G$: paper eq. for $W_H$."""

    def energy(self, lt, lp):
        a, b = lt - 1.0, lp - 1.0
        return 2.0 * (a**2 + b**2 + a * b)

    def natural_width(self, l):
        return 1.0 - 0.5 * (l - 1.0)

    def max_uniaxial_stretch(self) -> float:
        return 3.0


class MooneyRivlin(AbstractIncompressible):
    r"""Mooney-Rivlin, $C_1(I_1-3)+C_2(I_2-3)$ with $2C_1+2C_2 = 1$ (units of $G$)."""

    c1: float = 0.5
    c2: float = 0.0

    def energy(self, lt, lp):
        i1, i2 = invariants(lt, lp)
        return self.c1 * (i1 - 3.0) + self.c2 * (i2 - 3.0)

    def max_uniaxial_stretch(self) -> float:
        return float("inf")


class NeoHookean(AbstractIncompressible):
    r"""neo-Hookean, $(I_1 - 3)/2$ (Mooney-Rivlin with $C_2 = 0$)."""

    def energy(self, lt, lp):
        i1, _ = invariants(lt, lp)
        return 0.5 * (i1 - 3.0)

    def max_uniaxial_stretch(self) -> float:
        return float("inf")


class Gent(AbstractIncompressible):
    r"""Gent, $-(J_m/2)\ln(1-(I_1-3)/J_m)$; infinite at $I_1 \ge J_m + 3$."""

    jm: float = 50.0

    def energy(self, lt, lp):
        i1, _ = invariants(lt, lp)
        arg = 1.0 - (i1 - 3.0) / self.jm
        safe = jnp.where(arg > 0, arg, 1.0)
        return jnp.where(arg > 0, -0.5 * self.jm * jnp.log(safe), jnp.inf)

    def max_uniaxial_stretch(self):
        r"""The largest real root of $l^3 - (J_m + 3)l + 2 = 0$ ($I_1 = l^2 + 2/l = J_m + 3$),
        in the trigonometric closed form of a cubic with three real roots ($J_m > 0$):
        $l = 2\sqrt{(J_m+3)/3}\,\cos\bigl(\tfrac13\arccos(-(3/(J_m+3))^{3/2})\bigr)$, so
        that it traces with a traced $J_m$ (1 at $J_m = 0$, the double root)."""
        s = 3.0 / (jnp.asarray(self.jm, float) + 3.0)
        return 2.0 * jnp.sqrt(1.0 / s) * jnp.cos(jnp.arccos(-(s**1.5)) / 3.0)


def _grad2(fn):
    """Elementwise gradient of a scalar function of two scalars, vectorised."""
    g = jax.grad(fn, argnums=(0, 1))

    def wrapped(lt, lp):
        lt, lp = jnp.broadcast_arrays(jnp.asarray(lt, float), jnp.asarray(lp, float))
        f = g
        for _ in range(lt.ndim):
            f = jax.vmap(f)
        return f(lt, lp)

    return wrapped


def tensions(material: AbstractMaterial, lt, lp):
    r"""Tensions $(T_\theta, T_\phi)$ per deformed length, units of $G h_0$ (unrelaxed).

    $T_\theta = W_{,\lambda_\theta}/\lambda_\phi$, $T_\phi = W_{,\lambda_\phi}/\lambda_\theta$
    (paper eqs. (1)-(2), the second with the typo fixed).
    """
    dw_dt, dw_dp = _grad2(material.energy)(lt, lp)
    return dw_dt / lp, dw_dp / lt


def relaxed_energy(material: AbstractMaterial, lt, lp):
    r"""Tension-field relaxed energy (units of $G$), elementwise.

    Taut: $W(l_t, l_p)$. Wrinkled across the meridian ($l_t > 1$, $l_p < w(l_t)$):
    $W(l_t, w(l_t))$. Wrinkled across the hoop ($l_p > 1$, $l_t < w(l_p)$):
    $W(w(l_p), l_p)$. Slack (otherwise, both stretches $\le 1$): 0. The result is
    $C^1$ across the region boundaries, since $\partial W/\partial l_p = 0$ at
    $l_p = w(l_t)$. NaN where the material refuses the stretch (Hookean beyond 3).
    """
    lt = jnp.asarray(lt, float)
    lp = jnp.asarray(lp, float)
    wt = material.natural_width(lt)  # width across the hoop under meridional stretch
    wp = material.natural_width(lp)
    wrinkled_p = (lt > 1.0) & (lp < wt)  # hoop direction wrinkled
    wrinkled_t = (lp > 1.0) & (lt < wp)  # meridional direction wrinkled
    slack = (lt <= 1.0) & (lp <= 1.0)
    taut = ~(wrinkled_p | wrinkled_t | slack)
    one = jnp.ones_like(lt)
    # The stretches the energy is evaluated at, chosen per region before one evaluation (three
    # evaluations, one per region, cost 2.5x in the Newton matrix): (l_t, l_p) taut,
    # (l_t, w(l_t)) and (w(l_p), l_p) wrinkled, (1, 1) slack (W(1, 1) = 0, and constant: no
    # gradient). Safe arguments, so that no region's width gives a NaN gradient where it is
    # not taken.
    lt_u = jnp.where(wrinkled_p, lt, one)
    lp_u = jnp.where(wrinkled_t, lp, one)
    a = jnp.where(taut | wrinkled_p, lt, jnp.where(wrinkled_t, material.natural_width(lp_u), one))
    b = jnp.where(taut | wrinkled_t, lp, jnp.where(wrinkled_p, material.natural_width(lt_u), one))
    w = jnp.where(slack, 0.0, material.energy(a, b))
    lmax = material.max_uniaxial_stretch()
    bad = (lt <= 0) | (lp <= 0) | (lt >= lmax) | (lp >= lmax)
    return jnp.where(bad, jnp.nan, w)


def relaxed_tensions(material: AbstractMaterial, lt, lp):
    """Tensions from the relaxed energy (per deformed length, units of G h0)."""
    dw_dt, dw_dp = _grad2(lambda a, b: relaxed_energy(material, a, b))(lt, lp)
    return dw_dt / lp, dw_dp / lt


def check_range(material: AbstractMaterial, lt, lp, where: str = "") -> None:
    """Raise :class:`MaterialRangeError` if any stretch is outside the material's range."""
    lt = np.asarray(lt, float)
    lp = np.asarray(lp, float)
    ok = np.asarray(material.in_range(lt, lp))
    if not ok.all():
        idx = np.flatnonzero(~ok.ravel())[0]
        i1 = (
            lt.ravel()[idx] ** 2
            + lp.ravel()[idx] ** 2
            + 1 / (lt.ravel()[idx] * lp.ravel()[idx]) ** 2
        )
        raise MaterialRangeError(
            f"{material.name}: stretches (lambda_theta={lt.ravel()[idx]:.4g}, "
            f"lambda_phi={lp.ravel()[idx]:.4g}, I1={i1:.4g}) outside the material's range"
            + (f" {where}" if where else "")
            + f"; largest uniaxial stretch allowed {float(material.max_uniaxial_stretch()):.4g}"
        )


#: the one registry of materials: a model's name (the schema's ``model``) -> its class; the
#: schema builds them (:meth:`dynslip.schema.materials.MaterialSpec.core`)
MATERIALS: dict[str, type[AbstractMaterial]] = {
    "hookean": Hookean, "neo_hookean": NeoHookean, "mooney_rivlin": MooneyRivlin, "gent": Gent,
}


def make_material(model: str, *, jm: float = 50.0, c1: float = 0.5, c2: float = 0.0):
    """Material from its name (:data:`MATERIALS`), for code that holds no schema (the
    benchmarks, and tests of the physics alone); the package builds materials through the
    schema."""
    if model not in MATERIALS:
        raise ValueError(f"unknown material model {model!r}")
    params = {"mooney_rivlin": {"c1": float(c1), "c2": float(c2)}, "gent": {"jm": float(jm)}}
    return MATERIALS[model](**params.get(model, {}))
