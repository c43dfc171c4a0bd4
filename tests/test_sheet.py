"""The whole-sheet kernels: exact gradients, closed-form states, penalty, friction law."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynslip.physics.friction import Coulomb, soft_threshold
from dynslip.physics.materials import make_material, relaxed_tensions
from dynslip.physics.sheet import (
    Penalty,
    SheetModel,
    element_stretches,
    make_mesh,
    penalty_energy,
    penalty_pressure,
)

MAT = make_material("gent", jm=50.0)


def _model(n=12, r_edge=2.0, material=MAT):
    return SheetModel(make_mesh(n, r_edge), material, Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)))


def test_forces_are_the_exact_gradient_of_the_energy():
    """Autodiff forces agree with central finite differences of the total energy."""
    m = _model()
    rng = np.random.default_rng(0)
    rbar = np.asarray(m.mesh.rbar)
    theta = 1.4 * rbar / rbar[-1] + 0.02 * rng.standard_normal(rbar.size)
    rho = np.sin(np.clip(theta, 0, None)) * (1 + 0.01 * rbar)
    rho[0] = 0.0
    z = np.cos(theta) - 0.002 - 0.3 * rbar**2  # partly inside the ball (penalty active)
    zb = 0.01
    g_rho, g_z, g_zb = m.gradients(jnp.asarray(rho), jnp.asarray(z), zb)
    h = 1e-6
    for i in (1, 4, 7, 11):
        for arr, g in ((rho, g_rho), (z, g_z)):
            p, q = arr.copy(), arr.copy()
            p[i] += h
            q[i] -= h
            args_p = (p, z) if arr is rho else (rho, p)
            args_q = (q, z) if arr is rho else (rho, q)
            fd = (
                m.energy(*map(jnp.asarray, args_p), zb) - m.energy(*map(jnp.asarray, args_q), zb)
            ) / (2 * h)
            assert float(g[i]) == pytest.approx(float(fd), rel=1e-6, abs=1e-6)
    fd_b = (
        m.energy(jnp.asarray(rho), jnp.asarray(z), zb + h)
        - m.energy(jnp.asarray(rho), jnp.asarray(z), zb - h)
    ) / (2 * h)
    assert float(g_zb) == pytest.approx(float(fd_b), rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("grading", [1.0, 2.5])
@pytest.mark.parametrize("lam", [0.8, 1.0, 1.05, 1.4])
def test_uniform_radial_stretch_is_a_discrete_equilibrium_with_the_closed_form_edge_force(
    lam, grading
):
    """rho = lambda rbar, flat: no force on any free node; the clamp's radial force is
    2 pi r_edge lambda T(lambda) with T the equibiaxial tension (zero at lambda = 1). A slack
    disc (lambda < 1, the schema's `pre_stretch` below 1) is wrinkled both ways: zero energy
    and zero force everywhere (tension-field theory). The same on a mesh graded toward the
    pole (`numerics.mesh_grading`)."""
    m = SheetModel(make_mesh(15, 2.4, grading), MAT, Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)))
    rho = lam * m.mesh.rbar
    z = jnp.full_like(rho, 5.0)  # far above the ball
    g_rho, g_z, g_zb = m.gradients(rho, z, 0.0)
    scale = 1.0 + float(jnp.max(jnp.abs(g_rho)))
    assert float(jnp.max(jnp.abs(g_rho[1:-1]))) < 1e-12 * scale
    assert float(jnp.max(jnp.abs(g_z))) == 0.0 and float(g_zb) == 0.0
    t_eq, _ = relaxed_tensions(MAT, jnp.asarray(lam), jnp.asarray(lam))
    expected = 2 * np.pi * 2.4 * lam * float(t_eq)
    assert float(g_rho[-1]) == pytest.approx(expected, rel=1e-12, abs=1e-14)
    if lam < 1.0:
        assert float(m.elastic_energy(rho, z)) == 0.0 and float(jnp.max(jnp.abs(g_rho))) == 0.0
    else:
        assert float(g_rho[-1]) > 0.0 or lam == 1.0


def test_forces_past_the_gent_pole_are_nan_not_zero():
    """Equibiaxial stretch lambda: I1 = 2 lambda^2 + lambda^-4 reaches J_m + 3 = 53 at
    lambda = 5.14. Inside (5.0) the forces are finite and are the energy's gradient; past the
    pole (5.3) the energy is infinite and the bare derivative reads zero force on every node
    (a spurious equilibrium), so SheetModel.gradients returns NaN there instead."""
    m = _model(n=15, r_edge=2.4)
    z = jnp.full(m.mesh.rbar.shape, 5.0)
    g_in = m.gradients(5.0 * m.mesh.rbar, z, 0.0)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in g_in) and float(g_in[0][-1]) > 0
    rho = 5.3 * m.mesh.rbar
    assert not np.isfinite(float(m.energy(rho, z, 0.0)))
    bare = jax.grad(m.energy, argnums=(0, 1))(rho, z, 0.0)
    assert float(jnp.max(jnp.abs(bare[0]))) == 0.0  # what gradients() guards against
    assert all(bool(jnp.all(jnp.isnan(g))) for g in m.gradients(rho, z, 0.0))


def test_element_stretches_of_a_spherical_cap():
    """A sheet laid on the unit sphere at theta = a rbar: lambda_theta is the chord
    stretch exactly, and the midpoint hoop stretch converges to sin(theta)/rbar at second
    order (measured)."""
    a = 1.5
    errs = []
    for n in (21, 41, 81):
        m = _model(n=n, r_edge=1.0)
        th = a * m.mesh.rbar
        lt, lp = element_stretches(m.mesh, jnp.sin(th), jnp.cos(th))
        chord = 2 * np.sin(a * np.asarray(m.mesh.dr) / 2) / np.asarray(m.mesh.dr)
        assert np.allclose(np.asarray(lt), chord, rtol=1e-13)
        rmid = np.asarray(m.mesh.rmid)
        errs.append(np.max(np.abs(np.asarray(lp) - np.sin(a * rmid) / rmid)))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(order - 2.0) < 0.1), order


def test_penalty_pressure_is_zero_off_the_ball_and_is_the_energy_derivative():
    pen = Penalty(jnp.asarray(1e4), jnp.asarray(1e-3))
    d = jnp.linspace(-2e-3, 4e-3, 601)
    p = penalty_pressure(pen, d)
    assert float(jnp.max(jnp.abs(jnp.where(d <= 0, p, 0.0)))) == 0.0
    dphi = jax.vmap(jax.grad(lambda x: penalty_energy(pen, x)))(d)
    assert np.allclose(np.asarray(dphi), np.asarray(p), rtol=1e-12, atol=1e-12)
    # C^1 at the ends of the smoothing band, linear (stiffness k) beyond it
    dp = jax.vmap(jax.grad(lambda x: penalty_pressure(pen, x)))(
        jnp.asarray([1e-3 - 1e-12, 1e-3 + 1e-12])
    )
    assert np.allclose(np.asarray(dp), 1e4, rtol=1e-6)


def test_soft_threshold_ideal_law_and_force_space_smoothing():
    f = jnp.linspace(-3.0, 3.0, 6001)
    c = 1.0
    ideal = soft_threshold(f, c)
    assert np.allclose(np.asarray(ideal), np.sign(f) * np.maximum(np.abs(f) - c, 0), atol=0)
    errs = []
    for eps in (1e-1, 1e-2, 1e-3):
        s = soft_threshold(f, c, jnp.asarray(eps))
        e = eps * c / (c + eps)
        # exactly zero below c - e, exact beyond c + e
        assert float(jnp.max(jnp.abs(jnp.where(jnp.abs(f) <= c - e, s, 0.0)))) == 0.0
        assert np.allclose(
            np.asarray(jnp.where(jnp.abs(f) >= c + e, s - ideal, 0.0)), 0.0, atol=1e-14
        )
        errs.append(float(jnp.max(jnp.abs(s - ideal))))
    rates = np.log10(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(rates - 1.0) < 0.05), (errs, rates)  # error = e/4: first order in eps


@settings(max_examples=60, deadline=None)
@given(st.floats(-5, 5), st.floats(0, 3), st.floats(0, 0.5))
def test_soft_threshold_dissipates_and_never_exceeds_the_force(f, c, eps):
    s = float(soft_threshold(jnp.asarray(f), jnp.asarray(c), jnp.asarray(eps)))
    assert abs(s) <= abs(f) + 1e-15
    assert (f - s) * s >= -1e-15  # friction power is dissipative
    if c == 0.0:
        assert s == pytest.approx(f, abs=1e-15)  # no normal force: free motion


def test_kinematics_stuck_and_free_nodes():
    """A node pressed on the ball with a tangential load below mu N does not move along
    the ball; off the ball a node moves with force / (eta A)."""
    m = _model(n=12, r_edge=1.0)
    th = 1.2 * m.mesh.rbar**1.3  # non-uniform stretch: tangential loads on the nodes
    rho = 0.995 * jnp.sin(th)  # pressed 0.005 R into the ball
    z = 0.995 * jnp.cos(th)
    k = m.kinematics(rho, z, 0.0, Coulomb(mu=jnp.asarray(50.0)), 0.0, 0.3)
    assert float(jnp.min(k.normal[:-1])) > 0
    assert float(jnp.max(jnp.abs(k.ft[1:-1]))) > 1e-3  # loaded ...
    assert float(jnp.max(jnp.abs(k.slip))) == 0.0  # ... but stuck
    t_dir = k.tangent
    u_scale = float(jnp.max(jnp.abs(k.u)))
    assert float(jnp.max(jnp.abs(jnp.sum(k.u * t_dir, axis=0)[:-1]))) < 1e-13 * u_scale
    k0 = m.kinematics(
        rho + 0.0, z + 3.0, 0.0, Coulomb(mu=jnp.asarray(50.0)), 0.0, 0.3
    )  # lifted off
    g_rho, g_z, _ = k0.grads
    u_expect = -jnp.stack([g_rho, g_z]) / (0.3 * m.mesh.area)
    assert np.allclose(
        np.asarray(k0.u[:, 1:-1]), np.asarray(u_expect[:, 1:-1]), rtol=1e-12, atol=1e-14
    )


@pytest.mark.parametrize("grading", [1.0, 1.5, 3.0])
def test_graded_mesh_radii_and_areas(grading):
    """rbar_i = r_edge (i/(n-1))^g; the lumped node areas and the element areas each add up to
    the disc's area pi r_edge^2 exactly (areas 2 pi rmid dr telescope); grading below 1 is
    refused."""
    n, r_edge = 21, 2.8
    mesh = make_mesh(n, r_edge, grading)
    assert np.allclose(
        np.asarray(mesh.rbar), r_edge * (np.arange(n) / (n - 1)) ** grading, rtol=0, atol=1e-15
    )
    assert float(mesh.dr[0]) == pytest.approx(r_edge / (n - 1) ** grading, rel=1e-12)
    for a in (mesh.area, mesh.area_el):
        assert float(jnp.sum(a)) == pytest.approx(np.pi * r_edge**2, rel=1e-13)
    with pytest.raises(ValueError, match="grading"):
        make_mesh(n, r_edge, 0.9)
