r"""The pressure law reads the contact pressure on the deformed area: $p = N/(A_0\lambda_t
\lambda_\phi)$ (``pressure_on: deformed``, the default), or on the reference area $A_0$
(``pressure_on: reference``). Checked on a sheet draped over the ball, stretched so that the
two differ: the threshold is the law's $\mu(p)N$ at the hand-computed deformed pressure, the
load increment's rates read the stretch at the increment's end as the vector field does, and
the schema's switch reaches the law."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.field import Layout, StageArgs
from dynslip.physics.friction import PressureDependent, soft_threshold
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import BALL_HOLD, CLAMP_POSITION
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh, node_stretches
from dynslip.physics.solver import increment as ni
from dynslip.physics.terms import forces

N = 17
MODEL = SheetModel(
    make_mesh(N, 2.4), make_material("gent", jm=50.0), Penalty(jnp.asarray(1e4), jnp.asarray(1e-2))
)
LAYOUT = Layout(N)
# mu_ref at a pressure inside the pocket's range, a cap far away: the power law alone
LAWS = {on: PressureDependent(mu_ref=0.9, p_ref=1.0, a=1.0 / 3.0, mu_max=50.0,
                              deformed_area=on == "deformed")
        for on in ("deformed", "reference")}


def _draped(stretch=1.6):
    """Nodes pressed 2e-3 R into the ball (sin, cos of a polar angle ``stretch`` times the
    material one: stretched about ``stretch``^2 in area), then a taut span to the edge."""
    rbar = np.asarray(MODEL.mesh.rbar)
    th = np.minimum(stretch * rbar, 1.3)
    on, r, span = rbar * stretch < 1.3, 0.998, rbar - 1.3 / stretch
    rho = np.where(on, r * np.sin(th), r * np.sin(1.3) + 0.4 * span)
    z = np.where(on, r * np.cos(th), r * np.cos(1.3) - 0.6 * span)
    rho[0] = 0.0
    return jnp.asarray(rho), jnp.asarray(z)


def _args(friction):
    f = jnp.float64
    return StageArgs(
        t0=f(0.0), clamp_mode=jnp.asarray(CLAMP_POSITION, jnp.int32), vzc=f(-0.2),
        vrhoc=f(0.0), fc0=jnp.zeros(2), fc1=jnp.zeros(2),
        ball_mode=jnp.asarray(BALL_HOLD, jnp.int32), vzb=f(0.0), f0=f(0.0), f1=f(0.0),
        ramp=f(1.0), friction=friction, eps=f(0.0), drag=f(0.1), ball_drag=f(1.0),
        weight=f(0.0), support=f(0.0), support_z=f(0.0), support_k=f(0.0),
    )


def test_the_threshold_is_mu_of_the_deformed_pressure():
    r"""At each contact node the slip force is the law's soft threshold at mu(N/(A_0 J)) N with
    J = lambda_t lambda_phi from the node stretches; with ``reference`` at mu(N/A_0) N. The two
    differ by the areal stretch (J > 1.5 here), so the check can tell them apart."""
    rho, z = _draped()
    lt, lp = node_stretches(MODEL.mesh, rho, z)
    j = np.asarray(lt * lp)
    a0 = np.asarray(MODEL.mesh.area)
    k = {on: MODEL.kinematics(rho, z, 0.0, law, 0.0, 0.1) for on, law in LAWS.items()}
    normal = np.asarray(k["deformed"].normal)
    contact = (normal > 0) & (np.arange(N) > 0) & (np.arange(N) < N - 1)
    assert contact.sum() >= 4 and np.all(j[contact] > 1.5)
    for on, area in (("deformed", a0 * j), ("reference", a0)):
        law = LAWS[on]
        mu = np.asarray(law.mu(jnp.asarray(normal / area)))
        want = np.asarray(soft_threshold(k[on].ft, jnp.asarray(mu * normal), 0.0))
        np.testing.assert_allclose(np.asarray(k[on].slip)[contact], want[contact], rtol=1e-12,
                                   atol=1e-14)
    # lower pressure on the stretched area: a higher mu, so less slip force
    mu_d = np.asarray(LAWS["deformed"].mu(jnp.asarray(normal / (a0 * j))))[contact]
    mu_r = np.asarray(LAWS["reference"].mu(jnp.asarray(normal / a0)))[contact]
    np.testing.assert_allclose(mu_d / mu_r, j[contact] ** (1.0 / 3.0), rtol=1e-12)


@pytest.mark.parametrize("start_stretch", [1.0, 1.3])
def test_the_increment_reads_the_stretch_at_its_end_as_the_vector_field(start_stretch):
    """The load increment's node rates at its end state equal the vector field's there, for
    any areal stretch given at the increment's start (the Newton matrix's value): the residual
    takes the pressure at the end, as implicit Euler takes every force."""
    rho, z = _draped()
    law = LAWS["deformed"]
    q = jnp.stack([rho, z], axis=1)
    g, load = forces(MODEL, q, 0.0)
    args = _args(law)
    stretch0 = jnp.asarray(MODEL.areal_stretch(*_draped(start_stretch)))
    inc = ni.Increment(q0=q, zb0=jnp.asarray(0.0), delta0=None, t1=jnp.asarray(0.5),
                       h=jnp.asarray(0.1), args=args, areal_stretch=stretch0)
    u, _, _ = ni.increment_rates(MODEL, law, inc, q, jnp.asarray(0.0), g, load)
    k = MODEL.kinematics(rho, z, 0.0, law, 0.0, 0.1)
    u_field = np.asarray(k.u).T
    assert np.abs(np.asarray(k.slip)).max() > 0  # some node slips: the law is read
    np.testing.assert_allclose(np.asarray(u)[:-1], u_field[:-1], rtol=1e-12, atol=1e-13)


def test_the_schema_switch_reaches_the_law():
    """``pressure_on`` builds the law on the deformed area by default, on the reference area
    when asked."""
    from dynslip.schema.friction import PressureSpec

    for on, deformed in ((None, True), ("deformed", True), ("reference", False)):
        spec = PressureSpec() if on is None else PressureSpec(pressure_on=on)
        law = spec.build(20.0, 0.0, pressure_scale_kPa=10.0)
        assert law.deformed_area is deformed
        area = law.contact_area(jnp.asarray([2.0]), jnp.asarray([3.0]))
        assert float(area[0]) == (6.0 if deformed else 2.0)
