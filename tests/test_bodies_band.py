"""The band's frictional hold and the rim's capstan (issue 22 item 1, docs/bodies.md).

A sheet folded over a held rounded rim (a tube's wall: a half torus of radius a, the outer wall
a cylinder) and held on the outer wall by a band of grip g (force per length of the band's
circle); a ball pushed up from below draws the sheet over the rim. The band holds the edge
exactly while the pull along the wall is below g 2 pi rho, and slides beyond it at the grip;
while it slides, the sheet slides over the frictional rim and the meridional force
P = 2 pi rho T_t falls from the inner side to the band as the axisymmetric capstan says. On the
rim the sheet is wrinkled in hoop (T_phi = 0, the fold's hoop compression), and there the
axisymmetric balance dP/dphi = -mu P + 2 pi a T_phi (d rho/ds - mu n_rho) is the belt formula
in P: P_in = P_band exp(mu phi), phi the wrap angle. N = 32, one compiled model.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Cylinder
from dynslip.physics.bodies.held import Held
from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import make_material, relaxed_tensions
from dynslip.physics.protocols import CLAMP_BAND, Duration, Protocol, Stage
from dynslip.physics.sheet import Penalty, SheetModel, element_stretches, make_mesh
from dynslip.physics.solver.methods import Settings
from helpers import run_sheet
from numerics import named_solver
from test_forming import residual

N = 32
R0, A, ZR = 2.0, 0.4, 0.05  # the rim: torus ring radius, minor radius, lowest point
PRE, GRIP, MU, TAU, EPS = 0.8, 0.05, 0.3, 0.02, 1e-3
BALL_V, PUSH_S = 0.02, 66.0  # slow: the drag (relative to the ball) on the rim is eta v
Z_BAND = ZR + A + 0.3
WALL = Cylinder(radius=R0 + A, inner_radius=R0 - A, z_bottom=ZR, z_top=ZR + 4.0, edge_radius=A)
MAT = make_material("gent", jm=50.0)
MODEL = SheetModel(
    make_mesh(N, (R0 + A) / PRE),
    MAT,
    Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)),
    bodies=(Held(WALL, Coulomb(mu=jnp.asarray(MU), eps=jnp.asarray(EPS))),),
    band_grip=jnp.asarray(GRIP),
)
THRESHOLD = GRIP * 2 * math.pi * (R0 + A)


def _run(solver="load_step"):
    stages = (
        Stage("fold", Duration(duration=Z_BAND / 0.2), clamp_vz=0.2),
        Stage("push", Duration(duration=PUSH_S), clamp_mode=CLAMP_BAND, ball_vz=BALL_V),
    )
    protocol = Protocol(stages, clamp_rho0=R0 + A, clamp_z0=0.0, ball_z0=-1.05)
    friction = Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(EPS))
    settings = Settings(solver=named_solver(solver), save_interval=0.25)
    return run_sheet(MODEL, protocol, friction, settings, pre=PRE, z_sheet=0.0, tau=TAU, eps=EPS)


@pytest.fixture(scope="module")
def band_run():
    return _run()


def capstan(frame):
    """(P_in, P_band, wrap angle, largest T_phi on the rim) of a frame: the meridional force
    2 pi rho T_t of the free elements on either side of the rim's contact, and the angle the
    sheet turns between them."""
    rho, z = jnp.asarray(frame["rho"]), jnp.asarray(frame["z"])
    lt, lp = element_stretches(MODEL.mesh, rho, z)
    tt, _ = relaxed_tensions(MAT, lt, lp)
    rho, z = np.asarray(rho), np.asarray(z)
    d = np.asarray(WALL.distance(jnp.stack([jnp.asarray(rho), jnp.asarray(z)], -1)))
    on = np.flatnonzero(d < 0)
    first, last = on[0], on[-1]
    p = 2 * np.pi * 0.5 * (rho[1:] + rho[:-1]) * np.asarray(tt)
    e_in, e_out = first - 1, last  # the free elements into and out of the contact
    t_in = np.array([rho[first] - rho[first - 1], z[first] - z[first - 1]])
    t_out = np.array([rho[last + 1] - rho[last], z[last + 1] - z[last]])
    cross = t_in[0] * t_out[1] - t_in[1] * t_out[0]
    phi = math.atan2(cross, float(t_in @ t_out))
    return p[e_in], p[e_out], phi, float(np.max(np.asarray(frame["T_phi"])[first : last + 1]))


def test_band_holds_below_its_grip_and_slides_at_it(band_run):
    """The edge stays put on the wall (to rounding) while the pull along it is below the grip
    g 2 pi rho; once it slides (downward, toward the rim), the band's force is the grip (plus
    the smoothing and the slip's drag, under 1%)."""
    push = [f for f in band_run.frames if f["stage"] == 1]
    held = [f for f in push if abs(float(f["clamp_force"])) < 0.98 * THRESHOLD]
    assert len(held) >= 10
    for f in held:
        assert abs(float(f["clamp_z"]) - Z_BAND) < 1e-12
    end = push[-1]
    assert float(end["clamp_z"]) < Z_BAND - 0.03  # it has slid toward the rim
    np.testing.assert_allclose(abs(float(end["clamp_force"])), THRESHOLD, rtol=1e-2)


def test_rim_capstan_in_the_meridional_force(band_run):
    """While the band slides, the sheet slides over the rim (mu 0.3) and, wrinkled in hoop
    there (T_phi = 0), its meridional force follows the belt formula P_in = P_band exp(mu phi)
    over the wrap angle phi (about 2.2 rad). Measured (N = 32, about 10 nodes on the rim):
    1.979 against exp(mu phi) = 1.958 (1.1%) at drag time 0.02 s and ball speed 0.02 R/s; at
    0.1 s and 0.1 R/s the ratio is 2.35 against 1.93 (+22%): the sheet's drag, relative to the
    moving ball, pulls the nodes at rest on the rim with eta v, and its share vanishes with
    eta v. The frictionless ratio would be 1, and the tension T_t (not P) differs by the radius
    ratio (1.6 / 2.4), so a wrong law fails."""
    end = [f for f in band_run.frames if f["stage"] == 1][-1]
    p_in, p_out, phi, tp = capstan(end)
    assert tp == 0.0  # the fold's hoop compression: wrinkled on the rim
    assert 1.5 < phi < 2.6, phi
    np.testing.assert_allclose(p_out, THRESHOLD, rtol=2e-2)
    ratio = p_in / p_out
    assert ratio > 1.5
    np.testing.assert_allclose(ratio, math.exp(MU * phi), rtol=3e-2)


@pytest.mark.slow
def test_energy_balance_with_the_band_and_a_frictional_rim():
    """The reference solver (Kvaerno5) closes the energy balance with the band's slip (its
    friction and drag) and the rim's friction counted, to 1e-6 of the work."""
    ref = _run(solver="kvaerno5")
    r, work = residual(ref)
    # measured (python over _run(solver="kvaerno5")): work 0.405 G h0 R^2, residual 1.8e-7 of it;
    # the first bound only says the run did work (the band slid), the second is the physics
    assert work > 0.3, work
    assert r < 1e-6, r
