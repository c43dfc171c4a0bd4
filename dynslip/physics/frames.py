"""What a saved frame records, and the states a run starts from (the flat sheet, a saved end
state), with the friction law's restart at a save segment's end."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.held import held_entries
from dynslip.physics.bodies.observe import body_observables
from dynslip.physics.field import (
    N_ACC,
    Layout,
    StageArgs,
    evaluate,
    heal,
    place_free_moving,
    place_state,
)
from dynslip.physics.layout import f64
from dynslip.physics.observables import (
    OBS_RBAR,
    contact_function,
    located_edge,
    theta_at,
    theta_key,
)
from dynslip.physics.sheet import SheetModel

__all__ = ["frame_record", "initial_state", "reset_internal", "state_from"]


@eqx.filter_jit
def frame_record(model: SheetModel, layout: Layout, t, y, args: StageArgs, contact_threshold,
                 forces=None, vb=None):
    """Everything saved per frame: per-node fields and per-time scalars (jnp), and per held
    body (:mod:`dynslip.physics.bodies.observe`). ``forces``, ``vb``: the energy gradient, held
    load and held bodies' projections at ``y``, and the ball's velocity, where the solver has them
    (:class:`~dynslip.physics.solver.newton.SegmentOutput`), else computed here. ``vb`` is taken
    only
    where the state has no held slip distances and no free bodies: there the solver's velocity
    is the state's (load stepping takes it at the increment's start slip distances, and at the
    free bodies' velocity over the increment, where the frame solves the state's own)."""
    model = place_free_moving(model, layout, t, y, args)  # a frictional free body's velocity
    if layout.n_held_int or layout.n_free:
        vb = None
    dy, aux = evaluate(model, layout, t, y, args, vb=vb, forces=forces)
    ps = None if forces is None else forces[2]
    model = place_state(model, layout, y, args, t)
    rho, z, zb = aux.rho, aux.z, aux.zb
    d = model.diagnostics(
        rho, z, zb, args.friction, args.eps, args.drag, contact_threshold, layout.internal(y),
        kin=aux.kin,
    )
    acc = layout.unpack(y)[3]
    contact = d["contact"]
    idx = jnp.arange(layout.n)
    any_c = jnp.any(contact)
    last = jnp.max(jnp.where(contact, idx, -1))
    theta_all = jnp.arctan2(rho, z - zb)
    theta_max = jnp.where(any_c, jnp.max(jnp.where(contact, theta_all, -jnp.inf)), jnp.nan)
    rbar_max = jnp.where(any_c, model.mesh.rbar[jnp.maximum(last, 0)], jnp.nan)
    slip_max = jnp.max(jnp.abs(d["slip_velocity"]))
    # the smooth observables (physics.observables): the edge located between nodes, theta at
    # fixed material radii
    edge = located_edge(model.mesh.rbar, theta_all,
                        contact_function(model, rho, z, zb, contact_threshold), contact)
    # per held body (none without held bodies: the ball's fields alone)
    g_rho, g_z, _ = aux.kin.grads
    per_body = body_observables(model, rho, z, zb, -jnp.stack([g_rho, g_z]), aux.ball_v,
                                args.drag, args.eps, contact_threshold,
                                layout.held_internal(y), hf=aux.held_frame, projections=ps)
    return {
        "rho": rho,
        "z": z,
        **{k: v for k, v in d.items() if k != "contact"},
        "clamp_z": aux.z[-1],
        "clamp_rho": aux.rho[-1],
        "clamp_force": aux.clamp_force,
        "clamp_force_rho": aux.clamp_force_rho,
        "ball_z": zb,
        "ball_reaction": aux.ball_reaction,
        "ball_reaction_static": aux.ball_reaction_static,
        "clamp_force_static": aux.clamp_force_static,
        "ball_velocity": aux.ball_v,
        "theta_max": theta_max,
        "rbar_max": rbar_max,
        "theta_edge": edge.theta,
        "rbar_edge": edge.rbar,
        **dict(zip((theta_key(r) for r in OBS_RBAR), theta_at(model.mesh.rbar, theta_all),
                   strict=True)),
        "work_clamp": acc[0],
        "work_ball": acc[1],
        "dissipation_drag": acc[2],
        "dissipation_friction": acc[3],
        "work_bodies": acc[4] if layout.n_acc > N_ACC else jnp.zeros(()),
        "energy_elastic": model.elastic_energy(rho, z),
        "energy_penalty": model.penalty_energy(rho, z, zb, ps),
        "slip_max": slip_max,
        # each held body's axial displacement from its reference placement (R): the ball's height
        # for one moving with it, the stages' or the state's for a moved or free one, else 0
        "body_z": jnp.stack([jnp.asarray(e.shift(zb), float) for e in held_entries(model.bodies)])
        if model.bodies
        else jnp.zeros(0),
        "n_contact": jnp.sum(contact),
        **per_body,
    }


def initial_state(model: SheetModel, layout: Layout, pre_stretch: float, z_sheet: float, zb: float):
    """Flat sheet at height ``z_sheet``, uniformly pre-stretched radially (rho = lambda rbar)."""
    rho = pre_stretch * model.mesh.rbar
    z = jnp.full(layout.n, f64(z_sheet))
    return layout.pack(rho, z, f64(zb), jnp.zeros(layout.n_acc))


def state_from(layout: Layout, start: dict):
    """State vector from a saved end state: ``rho``, ``z`` (n,), ``zb``, and optionally
    ``slip_distance`` (n,); the accumulators start at zero."""
    internal = None
    if layout.n_int:
        internal = jnp.asarray(start.get("slip_distance", np.zeros(layout.n)), dtype=jnp.float64)
        internal = jnp.where(jnp.isfinite(internal), internal, 0.0)
    return layout.pack(
        f64(start["rho"]), f64(start["z"]), f64(start["zb"]), jnp.zeros(layout.n_acc), internal
    )


@eqx.filter_jit
def reset_internal(model: SheetModel, layout: Layout, y, args: StageArgs, heal_rate=0.0):
    """The friction law's restart at a save-segment end (time-stepped solvers):
    :func:`dynslip.physics.field.heal`. Load stepping applies the same reset after every
    increment."""
    return heal(model, layout, y, args, heal_rate)
