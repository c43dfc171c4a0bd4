r"""The whole axisymmetric sheet: discrete energy, forces by autodiff, contact, friction.

Nondimensional: lengths by the ball radius $R$, energies by $G h_0 R^2$, forces by
$G h_0 R$, tensions by $G h_0$, force densities by $G h_0/R$ (physics.md Section 1).

**Mesh.** Nodes at material radii $\bar r_0 = 0 < \bar r_1 < \dots < \bar r_{N-1} = \bar r_e$
(node 0 the pole, node $N-1$ held by the clamp), deformed positions $(\rho_i, z_i)$ in
the meridian plane, $\rho_0 = 0$. Element $e$ joins nodes $e$ and $e+1$:

$$\lambda_{\theta,e} = \frac{|x_{e+1}-x_e|}{\bar r_{e+1}-\bar r_e},\qquad
  \lambda_{\phi,e} = \frac{\rho_e+\rho_{e+1}}{\bar r_e+\bar r_{e+1}}$$

(the hoop stretch at the element midpoint: no pole singularity).

**Energy** (units $G h_0 R^2$): relaxed elastic energy (tension-field theory,
:func:`dynslip.physics.materials.relaxed_energy`) plus a contact penalty

$$E = \sum_e 2\pi \bar r_{e+1/2}\Delta\bar r_e\, W_{rel}(\lambda_{\theta,e},\lambda_{\phi,e})
  + \sum_i A_i\,\phi(1 - |x_i - x_b|),$$

$A_i$ the lumped reference area of node $i$, $x_b = (0, z_b)$ the ball centre. The
penalty is $C^2$ in the penetration $d$: $\phi = 0$ for $d \le 0$,
$k d^3/(6w)$ for $0 < d < w$, $k(d^2/2 - wd/2 + w^2/6)$ beyond; its pressure per
reference area $\phi'(d)$ is *exactly zero* at a positive gap, so contact is detected by
pressure, never by a gap threshold (prototype pitfall: a smooth penalty floats).
The ball's penalty may carry a cohesive well (normal adhesion, :attr:`SheetModel.ball_penalty`,
:mod:`dynslip.physics.penalty`, docs/adhesion.md): a tension across a gap up to its range, of
area $w$; the held bodies' never does.

**Forces** are $-\nabla E$ by :func:`jax.grad` of the total (exact gradient, so the
energy balance is a sound test). Per node, with $n$ the ball's outward normal at the
node and $t$ the tangent toward increasing polar angle $\theta$ (toward the equator),
the driving force $F$ splits into $F_n$, $F_t$; the normal force is the penalty force
$N_i = A_i\phi'(d_i)$ and the friction law gives the slip force $S(F_t, \mu N_i)$
(:mod:`dynslip.physics.friction`). Overdamped dynamics with one drag $\eta$ per reference
area, *relative to the ball*:

$$\eta A_i (\dot x_i - \dot z_b e_z) = F_n n + S t .$$

(The drag is a regularisation; taking it relative to the ball makes the sheet on a
moving ball behave as on a held one and keeps the energy balance exact.)
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.base import AbstractBody
from dynslip.physics.bodies.chords import chord_depths as body_chord_depths
from dynslip.physics.bodies.corners import corner_energy, corner_normal
from dynslip.physics.bodies.held import held_corner_normal, held_entries, held_frame
from dynslip.physics.bodies.sphere import Sphere
from dynslip.physics.friction import AbstractFriction, soft_threshold
from dynslip.physics.materials import AbstractMaterial, relaxed_energy, relaxed_tensions
from dynslip.physics.mesh import (
    Mesh,
    element_stretches,
    make_mesh,
    mesh_from_radii,
    node_stretches,
)
from dynslip.physics.penalty import (
    Penalty,
    cohesive_fraction,
    penalty_energy,
    penalty_pressure,
)

__all__ = [
    "Kinematics",
    "Mesh",
    "Penalty",
    "SheetModel",
    "ball_chord_depths",
    "deepest_chord",
    "make_mesh",
    "mesh_from_radii",
    "penalty_energy",
    "penalty_pressure",
]


def ball_chord_depths(rho, z, zb) -> np.ndarray:
    """Depth inside the unit ball about ``(0, zb)`` of each element chord (positive inside),
    for node positions ``rho, z`` of shape (..., N) and ball heights ``zb`` of shape (...);
    returns shape (..., N-1). The penalty acts at nodes only, so nothing keeps a chord out of
    the ball: a deep one means the mesh does not resolve the contact
    (:mod:`dynslip.analysis.resolution`).

    Example::

        >>> import numpy as np
        >>> th = np.array([0.0, 0.3])  # two nodes on the ball, 0.3 rad apart
        >>> d = ball_chord_depths(np.sin(th), np.cos(th), 0.0)[0]
        >>> bool(abs(d - (1 - np.cos(0.15))) < 1e-12)
        True
    """
    rho, z = np.asarray(rho, float), np.asarray(z, float)
    zb = np.asarray(zb, float)[..., None]
    p = np.stack(
        [rho[..., :-1], z[..., :-1] - zb], axis=-1
    )  # element start, relative to the centre
    d = np.stack([np.diff(rho, axis=-1), np.diff(z, axis=-1)], axis=-1)
    dd = np.sum(d * d, axis=-1)
    t = np.clip(-np.sum(p * d, axis=-1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    closest = p + t[..., None] * d
    return 1.0 - np.sqrt(np.sum(closest * closest, axis=-1))


def deepest_chord(rho, z, zb, pole_side: float, body=None) -> tuple[np.ndarray, ...]:
    """Per frame (frames leading) ``(depth, element, pole crossed)`` of the deepest chord in the
    ball ``body`` (None: the unit ball); a pole on its other side from ``pole_side`` crossed."""
    unit = body is None or isinstance(body, Sphere) and body.is_unit
    depth = ball_chord_depths(rho, z, zb) if unit else body_chord_depths(body, rho, z, zb)
    depth = np.where(np.isfinite(depth), depth, -np.inf)
    k = np.argmax(depth, axis=-1)
    worst = np.take_along_axis(depth, k[..., None], axis=-1)[..., 0]
    crossed = (pole_side != 0) & (
        np.sign(np.asarray(z, float)[..., 0] - np.asarray(zb, float)) == -pole_side
    )
    through = crossed & (worst < 1.0)
    return np.where(through, 1.0, worst), np.where(through, 0, k), crossed


class Kinematics(NamedTuple):
    """Each node's motion relative to the ball under the ball's friction law and the force
    split behind it (:meth:`SheetModel.kinematics`), arrays over the nodes."""

    u: jax.Array  # (2, N) velocity relative to the ball (node N-1, the clamp, set by its mode)
    ft: jax.Array  # driving force along the ball's tangent (G h0 R)
    fn: jax.Array  # driving force along its normal
    normal: jax.Array  # the penalty's normal force N
    slip: jax.Array  # the friction law's slip force S
    grads: tuple  # (dE/drho, dE/dz, dE/dzb)
    eta_a: jax.Array  # the drag coefficient eta A
    tangent: jax.Array  # (2, N) the ball's tangent t (toward the equator)


class SheetModel(eqx.Module):
    """Material, mesh and contact penalty of the whole sheet: energies and forces.

    Arrays are full node arrays ``rho``, ``z`` of shape (N,), with ``rho[0] = 0`` and the
    last node at the clamp. ``zb`` is the ball centre height.

    ``ball`` is the moving body (an :class:`~dynslip.physics.bodies.base.AbstractBody` in its
    reference placement, displaced by ``zb``; the unit sphere by default, in closed form);
    ``bodies`` the held obstacles (a tuple, at their reference placements): a bare body
    (frictionless) or a :class:`~dynslip.physics.bodies.held.Held` carrying its own friction
    law. A node feels every body it penetrates with the same penalty; the run's friction law
    acts on the ball's tangent, each held body's on its own (:meth:`held_friction`,
    docs/bodies.md).
    """

    mesh: Mesh
    material: AbstractMaterial
    penalty: Penalty
    ball: AbstractBody = eqx.field(default_factory=Sphere)
    bodies: tuple = ()
    band_grip: float | jnp.ndarray = 0.0
    #: the ball's own penalty where it differs from ``penalty`` (its cohesive well: normal
    #: adhesion, docs/adhesion.md); None: ``penalty``. The held bodies keep ``penalty``.
    ball_penalty: Penalty | None = None

    @property
    def ball_contact(self) -> Penalty:
        """The penalty between the sheet and the ball (:attr:`ball_penalty`, else
        :attr:`penalty`)."""
        return self.penalty if self.ball_penalty is None else self.ball_penalty

    def band_slip(self, pull, rho_edge, eps_density=0.0):
        r"""The band's slip force on the edge (clamp mode ``CLAMP_BAND``): the soft threshold
        $S(F_z, g\,2\pi\rho_c)$ of the sheet's pull along the wall $F_z$ against the grip
        ``band_grip`` $g$ (force per length of the band's circle, units G h0), smoothed as the
        friction law (``eps_density`` times the edge's reference area)."""
        thr = self.band_grip * 2 * jnp.pi * jnp.abs(rho_edge)
        return soft_threshold(pull, thr, eps_density * self.mesh.area[-1])

    def elastic_energy(self, rho, z):
        """Relaxed elastic energy (G h0 R^2); NaN/inf outside the material's range."""
        lt, lp = element_stretches(self.mesh, rho, z)
        return jnp.sum(self.mesh.area_el * relaxed_energy(self.material, lt, lp))

    def penetration(self, rho, z, zb):
        """Penetration of each node into the ball, minus its signed distance (R)."""
        return -self.ball.distance(jnp.stack([rho, z], axis=-1), zb)

    def held_penalty_energy(self, rho, z, zb=0.0, projections=None):
        """Penalty energy of the nodes against the held bodies (G h0 R^2; 0 without any), each
        displaced by :meth:`~dynslip.physics.bodies.held.Held.shift` (``zb``, or its offset);
        ``projections`` the bodies' of the nodes where the caller has them
        (:func:`dynslip.physics.terms.held_projections`; None: projected here)."""
        x, a, pen = jnp.stack([rho, z], axis=-1), self.mesh.area, self.penalty
        entries = held_entries(self.bodies)
        ds = ([e.body.distance(x, e.shift(zb)) for e in entries]
              if projections is None else [p.distance for p in projections])
        # the held bodies' corners against the segments (physics/bodies/corners.py; 0 without)
        corners = sum((corner_energy(e.body, x, pen, e.shift(zb)) for e in entries),
                      jnp.zeros(()))
        return sum((jnp.sum(a * penalty_energy(pen, -d)) for d in ds), corners)

    def held_load(self, rho, z, zb=0.0):
        """Axial force of the sheet on the held bodies by contact pressure,
        $\\sum_i \\partial E_h/\\partial z_i$ (G h0 R, + upward): the part of the clamp's pull they
        carry instead of the ball (their friction's share: :meth:`held_friction`)."""
        if not self.bodies:
            return jnp.zeros(())
        return jnp.sum(jax.grad(self.held_penalty_energy, argnums=1)(rho, z, zb))

    def held_friction(self, rho, z, f, drag=1.0, eps_density=0.0, zb=0.0, delta=None,
                      projections=None):
        """The friction of the held bodies at the nodes (:mod:`dynslip.physics.bodies.held`): a
        :class:`~dynslip.physics.bodies.held.HeldFrame` for node positions ``rho, z`` (N,) and
        driving forces ``f`` (2, N) (``zb``: the ball's height), or None when no held body has
        friction. Not on the pole node nor the clamped edge. ``delta`` (K_mem, N): the held
        slip distances; ``projections``: the held bodies' of the nodes (None: projected
        here)."""

        idx = jnp.arange(rho.shape[0])
        live = (idx > 0) & (idx < rho.shape[0] - 1)
        x, area, pen = jnp.stack([rho, z], axis=-1), self.mesh.area, self.penalty
        return held_frame(self.bodies, x, f.T, lambda d: penalty_pressure(pen, -d), area, drag,
                          eps_density, live, zb, delta, projections,
                          held_corner_normal(self.bodies, x, pen, zb))  # fmt: skip

    def penalty_energy(self, rho, z, zb, projections=None):
        d = self.penetration(rho, z, zb)
        held = self.held_penalty_energy(rho, z, zb, projections)
        corners = corner_energy(self.ball, jnp.stack([rho, z], axis=-1), self.penalty, zb)
        return jnp.sum(self.mesh.area * penalty_energy(self.ball_contact, d)) + held + corners

    def adhesion_energy(self, rho, z, zb):
        """The cohesive part of the ball's penalty energy, $-\\sum_i A_i w\\,s(d_i) \\le 0$
        (G h0 R^2; 0 without normal adhesion): minus the work it would take to part every node
        from the ball (docs/adhesion.md). Already inside :meth:`penalty_energy`."""
        pen = self.ball_contact
        s = cohesive_fraction(pen.reach, self.penetration(rho, z, zb))
        return -jnp.sum(self.mesh.area * pen.adhesion * s)

    def energy(self, rho, z, zb):
        return self.elastic_energy(rho, z) + self.penalty_energy(rho, z, zb)

    def gradients(self, rho, z, zb):
        """(dE/drho, dE/dz, dE/dzb) by automatic differentiation of the total energy; NaN where
        the energy is not finite (a stretch past the material's range, e.g. Gent's pole, where
        the energy's derivative would otherwise read 0: a spurious force-free state that a
        Newton iterate can land on). A solver step that reaches such a state therefore fails
        and is cut back rather than accepted."""
        e, g = jax.value_and_grad(self.energy, argnums=(0, 1, 2))(rho, z, zb)
        bad = ~jnp.isfinite(e)
        return tuple(jnp.where(bad, jnp.nan, gi) for gi in g)

    def frame(self, rho, z, zb):
        """Outward unit normal n and tangent t (toward the equator) of the ball at each node.

        From the ball's projection: for the sphere n = (sin theta, cos theta) in (rho, z),
        t = (cos theta, -sin theta). At the pole node (rho = 0) the tangent is radial and
        carries no motion.
        """
        p = self.ball.project(jnp.stack([rho, z], axis=-1), zb)
        return p.normal.T, p.tangent.T

    def areal_stretch(self, rho, z):
        """Each node's areal stretch $\\lambda_t\\lambda_\\phi$ (deformed over reference area)."""
        lt, lp = node_stretches(self.mesh, rho, z)
        return lt * lp

    def contact_area(self, friction: AbstractFriction, rho, z, zb=0.0):
        """Each node's area as ``friction`` reads its pressure (its reference area, or the
        deformed one, :meth:`dynslip.physics.friction.AbstractFriction.contact_area`; the
        ball at ``zb`` for a law that reads the node's gap)."""
        return friction.contact_area(self.mesh.area, self.areal_stretch(rho, z),
                                     self.penetration(rho, z, zb))

    def normal_force(self, rho, z, zb):
        """Penalty (normal) force per node, N_i = A_i phi'(d_i) >= 0 (units G h0 R), plus the
        node's share of the ball's corners' normal force (physics/bodies/corners.py; none
        without corners)."""
        nodes = self.mesh.area * penalty_pressure(self.ball_contact, self.penetration(rho, z, zb))
        return nodes + corner_normal(self.ball, jnp.stack([rho, z], axis=-1), self.penalty, zb)

    def kinematics(
        self, rho, z, zb, friction: AbstractFriction, eps_density=0.0, drag=1.0, internal=None,
        grads=None,
    ):
        """Node velocities relative to the ball and the force split, for the driver.

        Returns :class:`Kinematics`. ``drag`` is eta (per reference area); time units follow
        from it. ``internal`` is the friction law's per-node state (slip distance), None for
        memoryless laws.
        ``grads``: :meth:`gradients` where the caller has them at this state (None: computed).
        """
        g_rho, g_z, g_zb = self.gradients(rho, z, zb) if grads is None else grads
        f = -jnp.stack([g_rho, g_z])  # (2, N) driving force
        n, t = self.frame(rho, z, zb)
        fn = jnp.sum(f * n, axis=0)
        ft = jnp.sum(f * t, axis=0)
        pole = jnp.arange(rho.shape[0]) == 0
        ft = jnp.where(pole, 0.0, ft)
        fn = jnp.where(pole, f[1] * jnp.sign(n[1]), fn)
        normal = self.normal_force(rho, z, zb)
        eps = eps_density * self.mesh.area
        s = friction.slip_force(ft, normal, internal, eps=eps,
                                area=self.contact_area(friction, rho, z, zb))
        eta_a = drag * self.mesh.area
        u = (fn * n + s * t) / eta_a
        u = u.at[0, 0].set(0.0)
        return Kinematics(u, ft, fn, normal, s, (g_rho, g_z, g_zb), eta_a, t)

    def in_contact(self, pressure, rho, z, zb, contact_threshold=1e-2):
        """The contact flag per node (not the clamped edge): the penalty presses
        (``pressure`` per deformed area above ``contact_threshold``), or, with normal adhesion,
        the node is held within half the cohesive range (gap below ``reach / 2``, the
        cohesive traction's peak: adhered nodes under tension count as in contact, nodes past
        the peak are peeling)."""
        pen = self.ball_contact
        contact = pressure > contact_threshold
        if not (isinstance(pen.adhesion, (int, float)) and pen.adhesion == 0.0):
            held = (pen.adhesion > 0) & (self.penetration(rho, z, zb) > -0.5 * pen.reach)
            contact = contact | held
        return contact.at[-1].set(False)

    def diagnostics(self, rho, z, zb, friction: AbstractFriction, eps_density=0.0, drag=1.0,
                    contact_threshold=1e-2, internal=None, kin=None):
        """Per-node fields of the trajectory contract (see docs/trajectory-contract.md).
        ``kin``: :meth:`kinematics` at this state where the caller has it (None: computed)."""
        k = kin
        if k is None:
            k = self.kinematics(rho, z, zb, friction, eps_density, drag, internal)
        delta = jnp.zeros_like(rho) if internal is None else internal
        lt, lp = node_stretches(self.mesh, rho, z)
        tt, tp = relaxed_tensions(self.material, lt, lp)
        def_area = self.mesh.area * lt * lp
        pressure = k.normal / def_area
        contact = self.in_contact(pressure, rho, z, zb, contact_threshold)
        friction_force = (k.slip - k.ft) / def_area  # density, + toward the equator
        slip = k.slip / k.eta_a
        pressed = contact & (pressure > 0)
        mu_mob = jnp.where(
            pressed, jnp.abs(friction_force) / jnp.where(pressed, pressure, 1.0), jnp.nan
        )
        theta = jnp.where(contact, jnp.arctan2(rho, z - zb), jnp.nan)
        slipping = k.slip != 0.0
        state = jnp.where(~contact, 0, jnp.where(~slipping, 1, jnp.where(slip < 0, 2, 3))).astype(
            jnp.int8
        )
        return {
            "lambda_theta": lt,
            "lambda_phi": lp,
            "T_theta": tt,
            "T_phi": tp,
            "pressure": jnp.where(contact, pressure, 0.0),
            "friction": jnp.where(contact, friction_force, 0.0),
            "slip_velocity": jnp.where(contact, slip, 0.0),
            "mu_mobilised": mu_mob,
            "theta": theta,
            "state": state,
            "contact": contact,
            "mu_current": jnp.where(contact, friction.coefficient(delta, rho.shape[0]), jnp.nan),
            "slip_distance": delta,
        }

    def free_span_axial_force(self, rho, z):
        """Axial force 2 pi rho T_theta sin(psi) carried by each element (N-1,), G h0 R.

        Positive when the sheet pulls the outer node upward (toward +z of the inner node)."""
        lt, lp = element_stretches(self.mesh, rho, z)
        tt, _ = relaxed_tensions(self.material, lt, lp)
        ds = lt * self.mesh.dr
        sin_psi = (z[1:] - z[:-1]) / ds
        rmid = 0.5 * (rho[1:] + rho[:-1])
        return 2 * jnp.pi * rmid * tt * sin_psi
