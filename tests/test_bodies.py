"""Rigid bodies by profile (issue 21): the signed distance, normal, tangent and surface
coordinate of every kind against closed forms, at and across segment joints; the distance's
gradient is the normal; the profile's validation; overlap and inside; the trapped criteria."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynslip.physics.bodies import (
    Arc,
    BodyGeometryError,
    Cone,
    Cylinder,
    Disc,
    Line,
    PastEdgeMidHeight,
    PastEquator,
    PastWidest,
    Profile,
    Sphere,
    Torus,
    inside,
    overlap,
    penetration,
)
from dynslip.physics.bodies.base import project_profile
from dynslip.physics.bodies.segments import padded_arrays, segment_arrays

# the coin of issue 21 in units of a 20 mm ball radius: 24.26 mm across, 1.75 mm thick
COIN = Disc(radius=12.13 / 20, thickness=1.75 / 20, edge_radius=0.3 / 20, centre_z=0.2)
BALL = Sphere(radius=1.0, centre_z=0.0)
BODIES = {
    "sphere": Sphere(radius=0.7, centre_z=0.3),
    "coin": COIN,
    "disc_round": Disc(radius=1.0, thickness=0.4, edge_radius=0.2),  # fully rounded edge
    "cylinder": Cylinder(radius=0.8, z_bottom=-1.0, z_top=0.5),
    "cylinder_round": Cylinder(radius=0.8, z_bottom=-1.0, z_top=0.5, edge_radius=0.1),
    "tube": Cylinder(radius=2.7, z_bottom=-5.0, z_top=-1.0, inner_radius=2.5, edge_radius=0.1),
    "cone": Cone(radius=1.0, z_base=-0.5, z_apex=1.0),
    "cone_down": Cone(radius=0.6, z_base=0.5, z_apex=-0.4),
    "torus": Torus(ring_radius=1.5, minor_radius=0.3, centre_z=-0.2),
    "profile": Profile(
        [
            Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0),
            Line((1.0, 0.0), (1.0, -1.0)),
            Arc((0.0, -1.0), 1.0, 0.0, -math.pi / 2),
        ]
    ),
}


@eqx.filter_jit
def project(body, x, z):
    p = body.project(x, z)
    return p.distance, p.normal, p.s, p.tangent


@eqx.filter_jit
def grad_distance(body, x, z):
    """(d distance / dx, d distance / dz) per point, by jax.grad."""
    return jax.vmap(
        jax.grad(lambda xi, zi: body.distance(xi, zi), argnums=(0, 1)), in_axes=(0, None)
    )(x, z)


def proj(body, x, z=0.0):
    return tuple(np.asarray(a) for a in project(body, jnp.asarray(x, float), jnp.asarray(z, float)))


def _rng_points(n, lo, hi, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(lo, hi, size=(n, 2))


# ---------------------------------------------------------------- sphere and its mapping


def test_sphere_is_todays_ball_exactly():
    """d = |x - x_c| - a, the same floating-point operations as sheet.py's penetration
    1 - |x - x_b| (equal to the last bit up to XLA's fusion: 1 ulp), n = (sin th, cos th),
    t = (cos th, -sin th) (SheetModel.frame), s = a th with th = atan2(rho, z - z_b)."""
    x = _rng_points(200, [0.0, -2.0], [2.0, 2.0])
    zb = 0.37
    d, n, s, t = proj(BALL, x, zb)
    rho, z = x[:, 0], x[:, 1]
    r = np.asarray(jnp.sqrt(jnp.asarray(rho) ** 2 + (jnp.asarray(z) - zb) ** 2))
    np.testing.assert_allclose(-d, 1.0 - r, rtol=0, atol=5e-16)
    th = np.arctan2(rho, z - zb)
    np.testing.assert_allclose(n, np.stack([np.sin(th), np.cos(th)], -1), rtol=0, atol=1e-15)
    np.testing.assert_allclose(t, np.stack([np.cos(th), -np.sin(th)], -1), rtol=0, atol=1e-15)
    np.testing.assert_allclose(s, th, rtol=0, atol=1e-15)
    b = BODIES["sphere"]
    d2, _, s2, _ = proj(b, x, 0.1)
    r2 = np.hypot(rho, z - 0.4)
    np.testing.assert_allclose(d2, r2 - 0.7, rtol=0, atol=1e-15)
    np.testing.assert_allclose(s2, 0.7 * np.arctan2(rho, z - 0.4), rtol=0, atol=1e-15)


def test_profile_kernel_reproduces_the_closed_form_sphere():
    """The generic line/arc projection, given the sphere's one arc, gives the closed form."""
    arc = Profile([Arc((0.0, 0.3), 0.7, math.pi / 2, -math.pi / 2)])
    x = _rng_points(300, [0.0, -1.5], [1.8, 2.0], seed=1)
    for a, b in zip(proj(arc, x, 0.2), proj(BODIES["sphere"], x, 0.2), strict=False):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)


# ---------------------------------------------------------------- closed forms per kind


def test_coin_faces_corner_and_edge():
    c = COIN
    a, h, e, zc = c.radius, c.thickness, c.edge_radius, c.centre_z
    zt, zbot = zc + h / 2, zc - h / 2
    # above the top face: d = z - z_top, n = e_z, s = rho, t = e_rho
    x = np.array([[0.0, zt + 0.3], [0.2, zt + 0.01], [a - e - 1e-3, zt - 0.01]])
    d, n, s, t = proj(c, x)
    np.testing.assert_allclose(d, x[:, 1] - zt, atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1]] * 3, atol=1e-15)
    np.testing.assert_allclose(s, x[:, 0], atol=1e-15)
    np.testing.assert_allclose(t, [[1, 0]] * 3, atol=1e-15)
    # beside the vertical edge: d = rho - a, n = e_rho, t = -e_z
    z = np.array([zc, zc + 0.3 * (h / 2 - e), zc - 0.9 * (h / 2 - e)])
    x = np.stack([np.full(3, a + 0.05), z], -1)
    d, n, s, t = proj(c, x)
    np.testing.assert_allclose(d, 0.05, atol=1e-15)
    np.testing.assert_allclose(n, [[1, 0]] * 3, atol=1e-15)
    np.testing.assert_allclose(t, [[0, -1]] * 3, atol=1e-15)
    np.testing.assert_allclose(s, (a - e) + math.pi * e / 2 + (zt - e - z), atol=1e-14)
    # off the top corner at angle phi from the vertical: d = |x - c| - e, s = a - e + e phi
    phi = np.array([0.1, 0.7, 1.4])
    cc = np.array([a - e, zt - e])
    x = cc + 1.5 * e * np.stack([np.sin(phi), np.cos(phi)], -1)
    d, n, s, t = proj(c, x)
    np.testing.assert_allclose(d, 0.5 * e, atol=1e-15)
    np.testing.assert_allclose(n, np.stack([np.sin(phi), np.cos(phi)], -1), atol=1e-13)
    np.testing.assert_allclose(s, a - e + e * phi, atol=1e-14)
    # below the bottom face: d = z_bottom - z, n = -e_z, s = L - rho, t = -e_rho
    x = np.array([[0.1, zbot - 0.2], [0.4, zbot - 1e-4]])
    d, n, s, t = proj(c, x)
    np.testing.assert_allclose(d, zbot - x[:, 1], atol=1e-15)
    np.testing.assert_allclose(n, [[0, -1]] * 2, atol=1e-15)
    np.testing.assert_allclose(s, c.length - x[:, 0], atol=1e-14)
    np.testing.assert_allclose(t, [[-1, 0]] * 2, atol=1e-15)
    assert c.length == pytest.approx(2 * (a - e) + math.pi * e + (h - 2 * e), abs=1e-14)
    # inside, away from the corners: minus the distance to the nearest face
    x = np.array([[0.1, zc + 0.01], [a - 0.01, zc]])
    d, _, _, _ = proj(c, x)
    np.testing.assert_allclose(d, [-(h / 2 - 0.01), -0.01], atol=1e-15)


def test_fully_rounded_disc_edge_is_a_half_circle():
    c = BODIES["disc_round"]
    phi = np.linspace(0.05, math.pi - 0.05, 7)  # from the top, over the edge, to the bottom
    x = np.array([0.8, 0.0]) + 0.35 * np.stack([np.sin(phi), np.cos(phi)], -1)
    d, n, s, _ = proj(c, x)
    np.testing.assert_allclose(d, 0.15, atol=1e-15)
    np.testing.assert_allclose(n, np.stack([np.sin(phi), np.cos(phi)], -1), atol=1e-13)
    np.testing.assert_allclose(s, 0.8 + 0.2 * phi, atol=1e-14)


def test_cylinder_sharp_corner_and_faces():
    c = BODIES["cylinder"]
    x = np.array([[0.3, 0.9], [1.1, -0.2], [0.5, -1.3], [0.8 + 0.3, 0.5 + 0.4]])
    d, n, s, _ = proj(c, x)
    np.testing.assert_allclose(d, [0.4, 0.3, 0.3, 0.5], atol=1e-15)
    np.testing.assert_allclose(n, [[0, 1], [1, 0], [0, -1], [0.6, 0.8]], atol=1e-15)
    np.testing.assert_allclose(s, [0.3, 0.8 + 0.7, 0.8 + 1.5 + 0.3, 0.8], atol=1e-14)
    d, _, _, _ = proj(c, np.array([[0.2, 0.0], [0.7, -0.5]]))
    np.testing.assert_allclose(d, [-0.5, -0.1], atol=1e-15)


def test_tube_wall_rim_is_a_torus_and_the_bore_is_outside():
    """A tube wall 2.5 <= rho <= 2.7 with fully rounded ends: its top is the torus of minor
    radius 0.1 about (2.6, -1.1); a point in the bore (rho < 2.5) is outside the solid at
    distance 2.5 - rho, normal -e_rho (the sheet drawn into the tube meets the inner wall)."""
    tube = BODIES["tube"]
    rim = Torus(ring_radius=2.6, minor_radius=0.1, centre_z=-1.1)
    phi = np.linspace(-math.pi / 2 + 0.01, math.pi / 2 - 0.01, 9)
    x = np.array([2.6, -1.1]) + 0.25 * np.stack([np.sin(phi), np.cos(phi)], -1)
    d_tube, n_tube, _, _ = proj(tube, x)
    d_rim, n_rim, _, _ = proj(rim, x)
    np.testing.assert_allclose(d_tube, 0.15, atol=1e-14)
    np.testing.assert_allclose(d_rim, 0.15, atol=1e-14)
    np.testing.assert_allclose(n_tube, n_rim, atol=1e-13)
    x = np.array([[0.0, -3.0], [2.0, -2.0], [2.49, -4.0]])
    d, n, _, _ = proj(tube, x, 0.0)
    np.testing.assert_allclose(d, 2.5 - x[:, 0], atol=1e-14)
    np.testing.assert_allclose(n, [[-1, 0]] * 3, atol=1e-15)
    assert tube.closed and not COIN.closed


def test_cone_flank_apex_and_rim():
    c = BODIES["cone"]  # apex (0, 1), rim (1, -0.5): flank normal (1.5, 1)/|.|
    nf = np.array([1.5, 1.0]) / math.hypot(1.5, 1.0)
    tf = np.array([1.0, -1.5]) / math.hypot(1.5, 1.0)
    u = np.array([0.2, 0.9, 1.6])  # along the flank
    x = np.array([0.0, 1.0]) + u[:, None] * tf + 0.2 * nf
    d, n, s, t = proj(c, x)
    np.testing.assert_allclose(d, 0.2, atol=1e-14)
    np.testing.assert_allclose(n, [nf] * 3, atol=1e-14)
    np.testing.assert_allclose(t, [tf] * 3, atol=1e-14)
    np.testing.assert_allclose(s, u, atol=1e-14)
    # above the apex (its normal cone): the distance to the apex point
    d, n, s, _ = proj(c, np.array([[0.0, 1.7], [0.1, 2.0]]))
    np.testing.assert_allclose(d, [0.7, math.hypot(0.1, 1.0)], atol=1e-14)
    np.testing.assert_allclose(n[1], np.array([0.1, 1.0]) / math.hypot(0.1, 1.0), atol=1e-14)
    np.testing.assert_allclose(s, 0.0, atol=1e-15)
    # an upside-down cone: the base on top, apex below
    cd = BODIES["cone_down"]
    d, n, _, _ = proj(cd, np.array([[0.3, 0.8], [0.0, -0.9]]))
    np.testing.assert_allclose(d, [0.3, 0.5], atol=1e-14)
    np.testing.assert_allclose(n, [[0, 1], [0, -1]], atol=1e-14)


def test_torus_closed_form():
    t = BODIES["torus"]
    x = _rng_points(200, [0.2, -1.5], [3.0, 1.2], seed=2)
    d, n, s, tan = proj(t, x)
    rel = x - np.array([1.5, -0.2])
    r = np.hypot(rel[:, 0], rel[:, 1])
    np.testing.assert_allclose(d, r - 0.3, atol=1e-14)
    np.testing.assert_allclose(n, rel / r[:, None], atol=1e-13)
    phi = np.mod(np.arctan2(rel[:, 0], rel[:, 1]), 2 * math.pi)  # clockwise from the top
    np.testing.assert_allclose(s, 0.3 * phi, atol=1e-13)
    np.testing.assert_allclose(tan, np.stack([n[:, 1], -n[:, 0]], -1), atol=1e-13)


def test_position_is_a_shift_along_the_axis():
    x = _rng_points(50, [0.0, -2.0], [2.0, 2.0], seed=3)
    for body in (COIN, BODIES["cone"], BODIES["tube"]):
        moved = proj(body, x, 0.45)
        shifted = proj(body, x - np.array([0.0, 0.45]), 0.0)
        for a, b in zip(moved, shifted, strict=False):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)


def test_across_the_axis_is_the_mirror_image():
    x = _rng_points(40, [0.0, -1.5], [2.0, 1.5], seed=5)
    xm = x * np.array([-1.0, 1.0])
    for name, body in BODIES.items():
        d, n, s, t = proj(body, x, 0.1)
        dm, nm, sm, tm = proj(body, xm, 0.1)
        np.testing.assert_allclose(dm, d, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(sm, s, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(nm, n * np.array([-1.0, 1.0]), atol=1e-14, err_msg=name)
        np.testing.assert_allclose(tm, t * np.array([-1.0, 1.0]), atol=1e-14, err_msg=name)


# ---------------------------------------------------------------- joints and gradients


@pytest.mark.parametrize("name", ["coin", "cylinder_round", "tube", "profile", "disc_round"])
def test_normals_continuous_across_every_joint(name):
    """C1 profiles: at each joint the distance and normal seen from the two sides agree (off
    the surface by +-0.02 R, 1e-7 R either side of the joint along the profile)."""
    body = BODIES[name]
    acc, joints = 0.0, []
    for seg in body.segments[:-1]:
        acc += seg.length
        joints.append(acc)
    joints = np.array(joints)
    for off in (0.02, -0.005):
        sides = []
        for ds in (-1e-7, 1e-7):
            p = body.point_at(joints + ds)
            _, n0, _, _ = proj(body, p)
            sides.append(proj(body, p + off * n0))
        (d1, n1, s1, t1), (d2, n2, s2, t2) = sides
        np.testing.assert_allclose(d1, off, atol=1e-12)
        np.testing.assert_allclose(d2, off, atol=1e-12)
        np.testing.assert_allclose(n1, n2, atol=1e-5)
        np.testing.assert_allclose(t1, t2, atol=1e-5)
        np.testing.assert_allclose(s2 - s1, 2e-7, atol=1e-9)


@pytest.mark.parametrize("name", sorted(BODIES))
def test_gradient_of_distance_is_the_normal(name):
    """jax.grad of the distance in x is the returned normal, a unit vector; in the body's
    position z it is -n_z; off the surface by up to 0.05 R on both sides (within the reach of
    the normals, off the medial axis)."""
    body = BODIES[name]
    rng = np.random.default_rng(4)
    s = rng.uniform(0, body.length, 60)
    p = body.point_at(s)
    _, n0, _, _ = proj(body, p)
    h = rng.uniform(-0.02, 0.05, 60)[:, None]
    x = p + h * n0
    x = x[x[:, 0] > 1e-3]
    zpos = 0.13
    x = x + np.array([0.0, zpos])
    gx, gz = (np.asarray(g) for g in grad_distance(body, jnp.asarray(x), jnp.asarray(zpos)))
    d, n, _, _ = proj(body, x, zpos)
    assert (d < 0).sum() >= 5 and (d > 0).sum() >= 20  # both sides of the surface sampled
    np.testing.assert_allclose(gx, n, atol=1e-12)
    np.testing.assert_allclose(gz, -n[:, 1], atol=1e-12)
    np.testing.assert_allclose(np.hypot(n[:, 0], n[:, 1]), 1.0, atol=1e-14)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(BODIES)), st.floats(0.0, 1.0), st.floats(-0.03, 0.3))
def test_closest_point_identity(name, frac, h):
    """For a point x at signed distance d: x - d n is the surface point at arc length s,
    whose own distance is 0, and the tangent there is n turned clockwise."""
    body = BODIES[name]
    p = body.point_at(np.array([frac * body.length]))
    _, n0, _, _ = proj(body, p)
    x = p + h * n0
    if x[0, 0] < 0:
        return
    d, n, s, t = proj(body, x)
    q = x - d[:, None] * n
    np.testing.assert_allclose(q, body.point_at(s), atol=1e-12)
    np.testing.assert_allclose(proj(body, q)[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(t, np.stack([n[:, 1], -n[:, 0]], -1), atol=1e-12)


def test_meridian_points_lie_on_the_surface():
    for name, body in BODIES.items():
        pts = body.meridian_points(100, z=0.2)
        d = proj(body, pts, 0.2)[0]
        assert np.max(np.abs(d)) < 1e-12, name
        out = body.outline()
        assert np.array_equal(out[0], out[-1])


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: Sphere(radius=0.0), "radius 0"),
        (lambda: Sphere(radius=-1.0), "must be > 0"),
        (lambda: Disc(radius=1.0, thickness=0.0, edge_radius=0.1), "thickness"),
        (lambda: Disc(radius=1.0, thickness=0.2, edge_radius=-0.1), "edge radius"),
        (lambda: Disc(radius=1.0, thickness=0.2, edge_radius=0.15), "at most half the thickness"),
        (lambda: Torus(ring_radius=0.2, minor_radius=0.3), "must exceed"),
        (lambda: Torus(ring_radius=1.0, minor_radius=0.0), "minor radius"),
        (lambda: Cylinder(radius=1.0, z_bottom=0.0, z_top=0.0), "height"),
        (lambda: Cylinder(radius=1.0, z_bottom=0.0, z_top=1.0, inner_radius=1.2), "inner radius"),
        (lambda: Cone(radius=-1.0, z_base=0.0, z_apex=1.0), "cone radius"),
        (lambda: Profile([Arc((0.0, 0.0), -1.0, math.pi / 2, -math.pi / 2)]), "arc radius"),
        (lambda: Profile([Line((0.0, 1.0), (0.0, 1.0))]), "zero length"),
        (
            lambda: Profile(
                [Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0), Line((1.0, -0.1), (1.0, -1.0))]
            ),
            "not connected",
        ),
        (
            lambda: Profile(
                [Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0), Line((1.0, 0.0), (0.0, -1.0))]
            ),
            "not smooth",
        ),
        (lambda: Profile([Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0)]), "not closed"),
        (lambda: Profile([Arc((0.0, 0.0), 1.0, -math.pi / 2, math.pi / 2)]), "solid on its left"),
        (lambda: Profile([Arc((-0.5, 0.0), 1.0, math.pi / 2, -math.pi / 2)]), "crosses the axis"),
    ],
)
def test_bad_geometry_is_refused_in_words(make, words):
    with pytest.raises(BodyGeometryError, match=words):
        make()
    assert issubclass(BodyGeometryError, ValueError)


def test_self_crossing_profile_is_refused():
    """A smooth profile from the axis to the axis that runs out along z = 1, three quarters
    round a circle, and straight up through its own first line to the axis at z = 2."""
    segs = [
        Line((0.0, 1.0), (1.0, 1.0)),
        Arc((1.0, 0.5), 0.5, math.pi / 2, -math.pi),  # ends at (0.5, 0.5) heading up
        Line((0.5, 0.5), (0.5, 1.5)),  # crosses the first line at (0.5, 1)
        Arc((0.0, 1.5), 0.5, 0.0, math.pi / 2),
    ]  # to the axis at (0, 2)
    with pytest.raises(BodyGeometryError, match="crosses itself"):
        Profile(segs)


def test_valid_profile_ring_and_pin():
    """A closed ring (a stadium, not touching the axis) and a push pin's head and point pass."""
    ring = Profile(
        [
            Line((1.0, 0.2), (1.5, 0.2)),
            Arc((1.5, 0.0), 0.2, math.pi / 2, -math.pi / 2),
            Line((1.5, -0.2), (1.0, -0.2)),
            Arc((1.0, 0.0), 0.2, -math.pi / 2, -3 * math.pi / 2),
        ]
    )
    assert ring.closed
    assert ring.length == pytest.approx(1.0 + 2 * math.pi * 0.2, abs=1e-14)
    d, n, _, _ = proj(ring, np.array([[1.25, 0.5], [0.7, 0.0], [1.25, 0.0]]))
    np.testing.assert_allclose(d, [0.3, 0.1, -0.2], atol=1e-14)
    np.testing.assert_allclose(n[:2], [[0, 1], [-1, 0]], atol=1e-14)


# ---------------------------------------------------------------- overlap, inside


def test_overlap_and_penetration_depths():
    assert not overlap(BALL, Sphere(centre_z=2.0))  # touching
    assert overlap(BALL, Sphere(centre_z=1.9))
    assert penetration(BALL, Sphere(radius=0.5, centre_z=1.3)) == pytest.approx(0.2, abs=1e-12)
    # the ball resting on the bottle neck's ring (rho 0.635 R, rounded lip 0.05 R): it touches
    # at centre height h with h^2 + 0.635^2 = 1.05^2
    neck = Torus(ring_radius=0.635, minor_radius=0.05, centre_z=0.0)
    h = math.sqrt(1.05**2 - 0.635**2)
    assert not overlap(BALL, neck, za=h)
    assert penetration(BALL, neck, za=h - 0.01) == pytest.approx(
        1.05 - math.hypot(0.635, h - 0.01), abs=1e-12
    )
    # one inside the other overlaps; moving the coin off the ball clears it
    big = Cylinder(radius=3.0, z_bottom=-3.0, z_top=3.0)
    assert overlap(BALL, big) and overlap(big, BALL)
    assert overlap(COIN, BALL, za=0.75) and not overlap(COIN, BALL, za=1.0)


def test_inside():
    pts = np.array([[0.0, 0.0], [0.5, 0.5], [0.0, 1.0], [0.0, 1.0 - 1e-6], [2.0, 0.0]])
    assert inside(BALL, pts).tolist() == [True, True, False, True, False]
    assert inside(BALL, pts, z=3.0).tolist() == [False] * 5
    tube = BODIES["tube"]
    assert inside(tube, np.array([[2.6, -3.0], [2.0, -3.0], [2.6, -0.5]])).tolist() == [
        True,
        False,
        False,
    ]


# ---------------------------------------------------------------- trapped criteria


def test_trap_criteria():
    """The ball's criterion is today's theta_max > pi/2 (s = theta on the unit ball); the
    coin's threshold is the surface coordinate of its edge's mid-height; both are the generic
    'past the widest part' criterion."""
    th = np.array([1.0, math.pi / 2 - 1e-9, math.pi / 2 + 1e-9, 1.8, np.nan])
    s = proj(BALL, np.stack([np.sin(th), np.cos(th)], -1))[2]
    np.testing.assert_array_equal(np.asarray(PastEquator().trapped(s)), th > math.pi / 2)
    assert PastEquator(radius=0.7).threshold() == pytest.approx(0.35 * math.pi)
    coin = PastEdgeMidHeight(COIN)
    s_mid = proj(COIN, np.array([[COIN.radius + 0.1, COIN.centre_z]]))[2][0]
    assert coin.threshold() == pytest.approx(s_mid, abs=1e-14)
    assert PastWidest(COIN).threshold() == pytest.approx(s_mid, abs=1e-12)
    assert PastWidest(BALL).threshold() == pytest.approx(math.pi / 2, abs=1e-12)
    assert bool(coin.trapped(s_mid + 1e-6)) and not bool(coin.trapped(s_mid - 1e-6))
    assert float(coin.margin(s_mid + 0.01)) == pytest.approx(0.01)


@eqx.filter_jit
def _jvp_projection(body, x, dx):
    """The projection's outputs and their closed-form derivatives along dx, per point."""
    def one(xi, di):
        return jax.jvp(lambda y: tuple(project(body, y, 0.0)), (xi,), (di,))

    return jax.vmap(one)(x, dx)


@pytest.mark.parametrize("name", ["coin", "tube", "cone", "cylinder", "torus", "profile"])
def test_projection_derivatives_match_finite_differences(name):
    """The profile projection's closed-form derivative rule (segments.project_onto_segments:
    the normal's turn by the foot's curvature, the tangent's with it, ds) against central
    differences of the projection itself, for every output, along random directions, off the
    surface on both sides near lines, arcs and corners, and across the axis (the mirror); the
    distance's Hessian (jax.hessian, through the rule twice) against differences of the
    normal."""
    body = BODIES[name]
    rng = np.random.default_rng(11)
    s = rng.uniform(0, body.length, 80)
    p = body.point_at(s)
    _, n0, _, _ = proj(body, p)
    x = p + rng.uniform(-0.02, 0.08, 80)[:, None] * n0
    x[:8, 0] = -x[:8, 0]  # mirror images across the axis
    cv, _, bis = segment_arrays(body.segments)[2]  # and off each corner, along its bisector
    x = np.concatenate([x, cv + 0.05 * bis, cv + 0.05 * (bis + 0.3 * bis[:, ::-1])])
    d_ = rng.normal(size=x.shape)
    d_ /= np.linalg.norm(d_, axis=1, keepdims=True)
    eps = 1e-6
    plus, minus = proj(body, x + eps * d_), proj(body, x - eps * d_)
    (_, tangents) = _jvp_projection(body, jnp.asarray(x), jnp.asarray(d_))
    # the nearest foot is the same candidate at x +- eps d (else the difference is a jump), off
    # the axis (where the mirror turns the tangent over)
    same = (np.abs(plus[2] - minus[2]) < 1e-3) & (np.abs(x[:, 0]) > 1e-4)
    assert same.sum() >= 0.75 * len(x)
    for k, (a, b, t) in enumerate(zip(plus, minus, tangents, strict=True)):
        fd = (a - b) / (2 * eps)
        np.testing.assert_allclose(np.asarray(t)[same], fd[same], atol=2e-6, err_msg=f"output {k}")
    # the normal turns where the profile curves: the rule's curvature term is exercised
    turn = np.linalg.norm(np.asarray(tangents[1])[same], axis=1)
    assert turn.max() > 0.5
    hess = jax.vmap(jax.hessian(lambda y: body.distance(y)))(jnp.asarray(x))
    fd_h = (plus[1] - minus[1]) / (2 * eps)  # the normal is the distance's gradient
    np.testing.assert_allclose(np.einsum("pij,pj->pi", np.asarray(hess), d_)[same], fd_h[same],
                               atol=2e-6)


@pytest.mark.parametrize("name", [k for k in sorted(BODIES) if k != "sphere"])
def test_padded_arrays_project_the_same(name):
    """segments.padded_arrays (inert candidates far away, so that profiles share one shape and
    one compiled chord check) leaves every projection as it was, on points near the surface on
    both sides and across the axis, to rounding (the arcs' cosines and the lines' lengths are
    then computed by XLA, not numpy: 1 ulp); the shapes are multiples of 4."""
    body = BODIES[name]
    rng = np.random.default_rng(5)
    p = body.point_at(rng.uniform(0, body.length, 50))
    x = p + rng.uniform(-0.3, 0.6, (50, 2))
    x[:5, 0] = -x[:5, 0]
    arrays = segment_arrays(body.segments)
    padded = padded_arrays(arrays)
    for kind, kind_padded in zip(arrays, padded, strict=True):
        assert kind_padded[0].shape[0] % 4 == 0 and kind_padded[0].shape[0] >= kind[0].shape[0]
    got = jax.jit(project_profile)(padded, jnp.asarray(x), 0.2)
    want = body.project(jnp.asarray(x), 0.2)
    for g, w in zip(jax.tree_util.tree_leaves(got), jax.tree_util.tree_leaves(want), strict=True):
        np.testing.assert_allclose(np.asarray(g), np.asarray(w), rtol=0, atol=1e-14)
