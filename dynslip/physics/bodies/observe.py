r"""Observables per held body: what a saved frame records of each entry of
:attr:`dynslip.physics.sheet.SheetModel.bodies` (in order), besides the ball's own fields.

Per body $k$ and node $i$, from the frame's positions, driving forces $F$ and ball velocity
$v_b$:

- ``body_s``: the body's surface coordinate of the node's closest point (arc length along its
  profile, units of R; :meth:`~.base.AbstractBody.project`);
- ``body_contact``: the node touches the body: its penalty pressure against the body,
  $A_i\phi'(-d_{ik})/a_i$ with $a_i$ the deformed area, exceeds the contact threshold (the
  ball's test, :meth:`~dynslip.physics.sheet.SheetModel.diagnostics`; the clamped edge never);
- ``body_state``: :data:`FREE`; for a frictional body :data:`STUCK` where the return map's slip
  force $S(G, \mu_k N_{ik})$ is exactly zero (:meth:`~.held.HeldFrame.slip`: the node at rest
  on the body, $|G| \le \mu N$ less the smoothing's band) and the pole node in contact (no
  tangential motion), else :data:`SLIP_BACK` / :data:`SLIP_ON` by the sign of $S$ (slip toward
  decreasing / increasing ``s``); :data:`TOUCHING` on a frictionless body.

- ``body_slip_distance`` (only where a held body's law has memory, slip weakening): the
  node's slip distance relative to the body (R; NaN for a body without memory); not written
  to the trajectory file.

Per body and frame: the extent of the contact in ``s`` (``body_s_min``, ``body_s_max``; NaN
without contact) and ``body_n_contact``. Without held bodies :func:`body_observables` returns
``{}``, so a frame holds exactly the ball's fields.

Example::

    >>> import jax.numpy as jnp
    >>> from dynslip.physics.bodies.cylinder import Cylinder
    >>> from dynslip.physics.materials import NeoHookean
    >>> from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
    >>> m = SheetModel(make_mesh(5, 2.0), NeoHookean(), Penalty(), bodies=(Cylinder(3.0, -1, 0),))
    >>> rho = m.mesh.rbar
    >>> obs = body_observables(m, rho, jnp.full(5, 5.0), 0.0, jnp.zeros((2, 5)), 0.0, 1.0, 0.0,
    ...                        1e-2)
    >>> int(obs["body_n_contact"][0]), bool(jnp.isnan(obs["body_s_min"][0]))
    (0, True)
"""

from __future__ import annotations

import jax.numpy as jnp

from dynslip.physics.bodies.held import held_entries, projected
from dynslip.physics.mesh import node_stretches
from dynslip.physics.penalty import penalty_pressure

__all__ = ["FREE", "SLIP_BACK", "SLIP_ON", "STATE_MEANINGS", "STUCK", "TOUCHING",
           "body_observables"]

FREE, STUCK, SLIP_BACK, SLIP_ON, TOUCHING = 0, 1, 2, 3, 4
"""The ``body_state`` flags."""
STATE_MEANINGS = ("free", "stuck", "slipping_toward_decreasing_s",
                  "slipping_toward_increasing_s", "touching_frictionless")


def body_observables(model, rho, z, zb, f, vb, drag, eps, contact_threshold,
                     delta=None, hf=None, projections=None) -> dict:
    """Per held body (leading axis K, :attr:`SheetModel.bodies` order) the fields of the module
    docstring, for node positions ``rho, z`` (N,), ball height ``zb``, driving forces ``f``
    (2, N), ball velocity ``vb``, the drag ``eta``, the smoothing ``eps`` (force density) and
    ``contact_threshold`` (pressure, G h0 / R), ``delta`` (K_mem, N) the slip distances of the
    held bodies whose law has memory (None: none has); ``hf`` the held friction's frame at this
    state where the caller has it (:meth:`SheetModel.held_friction`; None: computed here), and
    ``projections`` the bodies' of the nodes (:func:`dynslip.physics.terms.held_projections`;
    None: projected here). ``{}`` without held bodies."""
    entries = held_entries(model.bodies)
    if not entries:
        return {}
    n = rho.shape[0]
    idx = jnp.arange(n)
    x = jnp.stack([rho, z], axis=-1)
    lt, lp = node_stretches(model.mesh, rho, z)
    def_area = model.mesh.area * lt * lp
    if hf is None:
        hf = model.held_friction(rho, z, f, drag, eps, zb, delta, projections)
    slip = None if hf is None else hf.slip(vb)[1]  # (K_frictional, N)
    out: dict[str, list] = {"s": [], "contact": [], "state": []}
    j = 0
    for k, e in enumerate(entries):
        p = projected(e, k, x, zb, projections)
        pressure = model.mesh.area * penalty_pressure(model.penalty, -p.distance) / def_area
        contact = (pressure > contact_threshold) & (idx < n - 1)
        if e.friction is None:
            state = jnp.where(contact, TOUCHING, FREE)
        else:
            assert slip is not None  # a body with friction: hf is a frame
            s = jnp.where(idx == 0, 0.0, slip[j])
            j += 1
            moving = jnp.where(s < 0, SLIP_BACK, SLIP_ON)
            state = jnp.where(contact, jnp.where(s == 0.0, STUCK, moving), FREE)
        out["s"].append(p.s)
        out["contact"].append(contact)
        out["state"].append(state.astype(jnp.int8))
    s, contact = jnp.stack(out["s"]), jnp.stack(out["contact"])
    some = jnp.any(contact, axis=1)
    lo = jnp.min(jnp.where(contact, s, jnp.inf), axis=1)
    hi = jnp.max(jnp.where(contact, s, -jnp.inf), axis=1)
    extra = {}
    if delta is not None:
        # the slip distance relative to each body whose law has memory (NaN for the others)
        rows, j = [], 0
        for e in entries:
            if e.friction is not None and e.friction.n_internal() == 1:
                rows.append(delta[j])
                j += 1
            else:
                rows.append(jnp.full(n, jnp.nan))
        extra["body_slip_distance"] = jnp.stack(rows)
    return {
        **extra,
        "body_s": s,
        "body_contact": contact.astype(jnp.int8),
        "body_state": jnp.stack(out["state"]),
        "body_s_min": jnp.where(some, lo, jnp.nan),
        "body_s_max": jnp.where(some, hi, jnp.nan),
        "body_n_contact": jnp.sum(contact, axis=1),
    }
