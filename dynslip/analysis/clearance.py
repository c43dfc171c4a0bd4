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

__all__ = ["body_contacts", "clearance", "contact_extent"]


@functools.lru_cache(maxsize=64)
def _distance_fn(bodies):
    """The jitted (time, node) distance to ``bodies``; one per body tuple (bodies are static
    and hashable), so summaries of many runs of one world compile it once."""

    def d(x, z):
        return jnp.min(jnp.stack([b.distance(x, z) for b in bodies]))

    return jax.jit(jax.vmap(jax.vmap(d, in_axes=(0, None)), in_axes=(0, 0)))


def clearance(ds: xr.Dataset, bodies, moves_with_clamp: bool = False) -> dict:
    """The sheet's clearance from ``bodies`` (a tuple, units of R) over the saved frames of a
    forming trajectory: ``{"per_frame": (time,) array, "min": value, "time": t, "rbar": node,
    "point": (rho, z), "touched": bool}``. ``moves_with_clamp``: the bodies are displaced by
    the clamp's height (``clamp_z``) at each frame."""
    x = np.stack([ds["rho"].values, ds["z"].values], axis=-1)  # (time, node, 2)
    shift = ds["clamp_z"].values if moves_with_clamp else np.zeros(ds.sizes["time"])
    d = np.asarray(_distance_fn(tuple(bodies))(jnp.asarray(x), jnp.asarray(shift)))
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
    moves_with_ball)`` (a body that moves with the ball is displaced by ``ball_z`` at each
    frame). For each: the closest approach of a sheet node over the path (``closest_R``, units
    of R, and ``closest_mm``; negative: inside), its time and material radius, and
    ``touched`` (a node reached the surface: the penalty, which acts only inside, pressed it).
    Nodes are points, as in :func:`clearance`. A trajectory with the per-body observables (its
    ``body`` dimension, in ``entries``' order) adds :func:`contact_extent`'s."""
    out = []
    for k, (name, body, with_ball) in enumerate(entries):
        d = ds.assign(clamp_z=ds["ball_z"]) if with_ball else ds
        c = clearance(d, (body,), moves_with_clamp=with_ball)
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

