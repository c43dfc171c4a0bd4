r"""How close the sheet comes to bodies the run did not model: its clearance on a saved path.

For a held body $B$ (lab frame) and a body that moves with the clamp (the tube's wall, placed
at the clamp's height $z_c(t)$), the clearance of frame $t$ is
$c(t) = \min_i d_B(\rho_i(t), z_i(t))$ over the sheet's nodes, with $d_B$ the body's signed
distance (:mod:`dynslip.physics.bodies`). Where $c(t) > 0$ on the whole path, the body is never
touched and cannot have changed the run: adding it (with any friction) gives the same
trajectory, up to the penalty's reach (its width, ``physics.sheet``). Where $c < 0$ the real
sheet would have met the body and the run is not the experiment from that frame on.
Nodes are points: a chord between two nodes may come closer than its ends (the mesh check of
:mod:`dynslip.analysis.resolution` does this for the ball).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from dynslip.data.trajectory import body_shift
from dynslip.physics.bodies.base import AbstractProfileBody, padded_profile, project_profile

__all__ = ["body_contacts", "body_overlaps", "clearance", "contact_extent", "overlap_tolerance"]


@functools.lru_cache(maxsize=64)
def _distance_fn(body):
    """The jitted (time, node) distance to a body in closed form (the sphere): one per body
    (static and hashable), so summaries of many runs of one world compile it once."""
    return jax.jit(jax.vmap(jax.vmap(body.distance, in_axes=(0, None)), in_axes=(0, 0)))


@jax.jit
def _profile_distance(arrays, x, z):
    """One frame's (node,) distance to a profile body given by its padded arrays (traced), the
    body at ``z``: one compile for every profile body and mesh size, whatever the number of
    frames (:func:`~dynslip.physics.bodies.base.padded_profile`)."""
    return project_profile(arrays, x, z).distance


def _distance(bodies, x, z) -> np.ndarray:
    """The (time, node) distance to the nearest of ``bodies``: a profile body's frame by frame
    (one compiled function for any number of frames; a few hundred frames' calls cost less than
    a compile for their number), a closed-form one's at once."""
    def one(b):
        if isinstance(b, AbstractProfileBody):
            arrays = padded_profile(b)
            return np.stack([np.asarray(_profile_distance(arrays, xt, zt))
                             for xt, zt in zip(x, z, strict=True)])
        return np.asarray(_distance_fn(b)(jnp.asarray(x), jnp.asarray(z)))

    return np.min(np.stack([one(b) for b in bodies]), axis=0)


def clearance(ds: xr.Dataset, bodies, moves_with_clamp: bool = False) -> dict:
    """The sheet's clearance from ``bodies`` (a tuple, units of R) over the saved frames of a
    forming trajectory: ``{"per_frame": (time,) array, "min": value, "time": t, "rbar": node,
    "point": (rho, z), "touched": bool}``. ``moves_with_clamp``: the bodies are displaced by
    the clamp's height (``clamp_z``) at each frame."""
    x = np.stack([ds["rho"].values, ds["z"].values], axis=-1)  # (time, node, 2)
    shift = ds["clamp_z"].values if moves_with_clamp else np.zeros(ds.sizes["time"])
    d = _distance(tuple(bodies), x, np.asarray(shift, float))
    k = np.unravel_index(int(np.argmin(d)), d.shape)
    return {
        "per_frame": d.min(axis=1),
        "min": float(d[k]),
        "time": float(ds["time"].values[k[0]]),
        "rbar": float(ds["rbar"].values[k[1]]),
        "point": (float(x[k][0]), float(x[k][1])),
        "touched": bool(d[k] <= 0.0),
    }


def body_contacts(ds: xr.Dataset, entries, length_mm: float) -> list[dict]:
    """Per held body of a run, from its saved path: ``entries`` are ``(name, body,
    moves_with_ball)`` (a body that moves, with the ball, by the stages or free, is displaced by
    :func:`~dynslip.data.trajectory.body_shift` at each frame). For each: the closest approach
    of a sheet node over the path (``closest_R``, units of R, and ``closest_mm``; negative:
    inside), its time and material radius, and
    ``touched`` (a node reached the surface: the penalty, which acts only inside, pressed it).
    Nodes are points, as in :func:`clearance`. A trajectory with the per-body observables (its
    ``body`` dimension, in ``entries``' order) adds :func:`contact_extent`'s."""
    out = []
    for k, (name, body, with_ball) in enumerate(entries):
        shift = body_shift(ds, k, with_ball)
        d = ds if shift is None else ds.assign(clamp_z=("time", shift))
        c = clearance(d, (body,), moves_with_clamp=shift is not None)
        out.append({
            "name": name,
            "moves_with_ball": bool(with_ball),
            "touched": c["touched"],
            "closest_R": c["min"],
            "closest_mm": c["min"] * length_mm,
            "time_s": c["time"],
            "rbar": c["rbar"],
        })
        if "body" in ds.dims and k < ds.sizes["body"]:
            out[-1].update(contact_extent(ds, k, length_mm))
    return out


def _pair(lo, hi, scale=1.0):
    return None if not np.isfinite(lo) else [float(lo) * scale, float(hi) * scale]


def contact_extent(ds: xr.Dataset, k: int, length_mm: float) -> dict:
    """The contact with held body ``k`` of a trajectory's ``body`` dimension, in its surface
    coordinate s (arc length along its profile, :mod:`dynslip.physics.bodies.observe`): the
    extent ``[s_min, s_max]`` at the end (``contact_s_end_R``, ``_mm``; None without contact),
    the longest extent over the path (``contact_length_max_R``, ``_mm``, 0 if never touched; its
    time and extent) and the envelope of every frame's extents (``contact_s_range_R``), the nodes
    in contact at the end and at most, and ``stuck_fraction_end``: of the nodes in contact at
    the end, the fraction stuck relative to the body (None without contact or on a frictionless
    body)."""
    lo = np.asarray(ds["body_s_min"].values[:, k], float)
    hi = np.asarray(ds["body_s_max"].values[:, k], float)
    state = np.asarray(ds["body_state"].values[-1, k])
    n = np.asarray(ds["body_n_contact"].values[:, k])
    length = np.where(np.isfinite(lo), hi - lo, -1.0)
    j = int(np.argmax(length))
    touching = state != 0
    frictional = touching.any() and not (state[touching] == 4).any()
    some = np.isfinite(lo).any()
    return {
        "contact_s_end_R": _pair(lo[-1], hi[-1]),
        "contact_s_end_mm": _pair(lo[-1], hi[-1], length_mm),
        "contact_length_max_R": max(float(length[j]), 0.0),
        "contact_length_max_mm": max(float(length[j]), 0.0) * length_mm,
        "contact_length_max_time_s": float(ds["time"].values[j]) if some else None,
        "contact_s_at_length_max_R": _pair(lo[j], hi[j]),
        "contact_s_range_R": [float(np.nanmin(lo)), float(np.nanmax(hi))] if some else None,
        "n_contact_end": int(n[-1]),
        "n_contact_max": int(n.max()),
        "stuck_fraction_end": float(np.mean(state[touching] == 1)) if frictional else None,
    }



@functools.lru_cache(maxsize=64)
def _depth_fn(a, b, n: int = 2001):
    """The jitted depth by which solids ``a`` and ``b``, displaced by ``za`` and ``zb`` (arrays
    of frames), intersect: the deepest of ``n`` points along either profile inside the other
    (:func:`~dynslip.physics.bodies.penetration` without its local refinement: to about the
    sampling's sagitta), 0 when apart."""
    pa = jnp.asarray(a.point_at(np.linspace(0.0, a.length, n), 0.0))
    pb = jnp.asarray(b.point_at(np.linspace(0.0, b.length, n), 0.0))
    up = jnp.array([0.0, 1.0])

    def depth(za, zb):
        da = jnp.min(b.distance(pa + za * up, zb))
        db = jnp.min(a.distance(pb + zb * up, za))
        return jnp.maximum(0.0, -jnp.minimum(da, db))

    return jax.jit(jax.vmap(depth))


#: default depth (R) above which a moving body is said to pass into another solid (the test's
#: sampling resolves about 1e-7 R); a run's summary passes its own (:func:`overlap_tolerance`)
OVERLAP_TOL = 1e-6


def overlap_tolerance(h0_over_r: float, penalty_width: float) -> float:
    """The depth (R) two bodies pressing the sheet between them reach without passing into each
    other: the real sheet's thickness ``h0_over_r`` keeps them apart, the model's sheet (a
    surface) lets each press it in by about its penalty's ``penalty_width``."""
    return h0_over_r + 2.0 * penalty_width


def body_overlaps(ds: xr.Dataset, entries, ball, length_mm: float, tol: float = OVERLAP_TOL,
                  max_frames: int = 200):
    """Where a body that moves on its own (by the stages, or free along the axis) passes into
    the ball or another held body on a saved path: the model has no contact between rigid
    bodies (only between each and the sheet), so from such a frame on the run is not a world
    of solids. ``entries``: ``(name, body, moves_with_ball)`` (:func:`body_contacts`'); ``ball``
    the ball's body (displaced by ``ball_z``). Returns one dict per moving body with an overlap
    deeper than ``tol`` (R): ``name``, ``into`` (``"ball"`` or the body's name), the
    largest depth over at most ``max_frames`` evenly spread frames (``depth_R``, ``depth_mm``)
    and its time (``time_s``); empty when none overlaps (bodies carried with the ball keep
    their start's clearance from it and are not checked)."""
    nt = ds.sizes["time"]
    frames = np.unique(np.linspace(0, nt - 1, min(nt, max_frames)).round().astype(int))
    zb = np.asarray(ds["ball_z"].values, float)
    shifts = [body_shift(ds, k, w) for k, (_, _, w) in enumerate(entries)]
    shifts = [np.zeros(nt) if s is None else s for s in shifts]
    out = []
    for k, (name, body, with_ball) in enumerate(entries):
        if with_ball or not np.any(shifts[k] != 0.0):
            continue
        others = [("ball", ball, zb)] + [(f"body {n!r}", b, shifts[j]) for j, (n, b, _) in
                                         enumerate(entries) if j != k]
        depth, into, when = 0.0, None, None
        for other, b, z in others:
            d = np.asarray(_depth_fn(body, b)(jnp.asarray(shifts[k][frames]),
                                              jnp.asarray(z[frames])))
            i = int(np.argmax(d))
            if d[i] > depth:
                depth, into, when = float(d[i]), other, float(ds["time"].values[frames[i]])
        if depth > tol:
            out.append({"name": name, "into": into, "depth_R": depth,
                        "depth_mm": depth * length_mm, "time_s": when})
    return out
