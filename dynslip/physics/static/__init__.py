r"""The paper's static model: the contact region of a membrane on a rigid sphere (paper
Section 3), one module per concept (:mod:`.grid` the grid formulas, :mod:`.march` the march
to rest, :mod:`.search` the search on $\mu$, :mod:`.family` the fully mobilised family,
:mod:`.checks` the checks), re-exported here; and its 2D case, a membrane on a rigid
cylinder (paper Section 5), in :mod:`.plane_strain`, not re-exported (its names are those of
the 2D formulas: ``vertical_force`` there is the 2D boundary term).

The rigid bodies of the forming model (``sphere``, ``cylinder``, ...) are in
:mod:`dynslip.physics.bodies`.

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$. A material point at undeformed radius
$\bar r$ sits at polar angle $\theta(\bar r)$ on the unit sphere; the sheet is in
contact from the pole $\bar r = 0$ to $\bar r_{max}$, where $\theta = \theta_{max}$.

Grid formulas (paper Section 3.3, physics.md Section 2): :mod:`.grid` states them.

Solvers:

- the paper's soft-threshold march $\dot\theta_i = S(F_{m,i}, \mu F_{N,i})$,
  $S(f, c) = \mathrm{sign}(f)\max(|f| - c, 0)$, to rest: :func:`march_explicit` (a jitted
  forward-Euler ``lax.while_loop``), :func:`march_implicit` (backward Euler with growing
  steps, each solved by semi-smooth Newton) and :func:`march_diffrax` (diffrax with a
  steady-state event);
- the search on $\mu$ for $F_v = 0$: :func:`search_mu` (bracket and bisection);
- the well-posed form, the fully mobilised family (:func:`solve_member`): $F_m = +\mu F_N$
  from the pole to the switch point, $F_m = -\mu F_N$ beyond, an ODE in $\bar r$ solved by
  shooting with unknowns (pole stretch, $\mu$, switch radius) and end conditions
  $\theta(\bar r_{max}) = \theta_{max}$, $T_\theta(\bar r_{max}) = 0$, and the switch angle
  $\theta(\bar r_s) = \theta_s$ that parameterises the family.
"""
from dynslip.physics.materials import tensions
from dynslip.physics.static.checks import (
    check_equilibrium,
    check_static_range,
    inflection_index,
    saturation_fraction,
    sign_change_index,
)
from dynslip.physics.static.family import (
    FamilyMember,
    sample_member,
    solve_family,
    solve_member,
)
from dynslip.physics.static.grid import (
    GridFields,
    fields,
    grid,
    initial_shape,
    vertical_force,
    vertical_force_identity,
)
from dynslip.physics.static.march import (
    MarchResult,
    march,
    march_diffrax,
    march_explicit,
    march_implicit,
    stable_dt,
    velocity,
    velocity_jacobian,
)
from dynslip.physics.static.search import (
    SearchResult,
    search_mu,
)

__all__ = [
    "grid",
    "initial_shape",
    "GridFields",
    "fields",
    "vertical_force",
    "vertical_force_identity",
    "velocity",
    "stable_dt",
    "MarchResult",
    "march_explicit",
    "march_diffrax",
    "velocity_jacobian",
    "march_implicit",
    "march",
    "SearchResult",
    "search_mu",
    "FamilyMember",
    "solve_member",
    "solve_family",
    "sample_member",
    "check_static_range",
    "saturation_fraction",
    "sign_change_index",
    "inflection_index",
    "check_equilibrium",
    "tensions",
]
