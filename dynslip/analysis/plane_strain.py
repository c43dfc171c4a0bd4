r"""The 2D check of the paper's Section 5 (:mod:`dynslip.physics.static.plane_strain`):
random admissible tension profiles on a cylinder at each lift-off angle $\theta_{max}$, their
vertical force $F_v$ against the closed form $T(\theta_{max})\sin\theta_{max}$ and the capstan
bounds $T_0 e^{\mp\mu\theta}$, and the conclusion (no invagination in 2D when every $F_v > 0$).
Tensions by $T_0$, forces per unit length by $T_0$.
"""

from __future__ import annotations

import numpy as np

from dynslip.physics.static import plane_strain as C


def cylinder_study(mu: float, angles, n_profiles: int, n_nodes: int, seed: int) -> dict:
    """``F_v`` and its closed form (angle, profile), the largest relative excess over the
    capstan bounds, and profiles at the largest angle for the figure (at most 50)."""
    import jax
    import jax.numpy as jnp


    key = jax.random.PRNGKey(seed)
    fv = np.zeros((len(angles), n_profiles))
    fv_closed = np.zeros_like(fv)
    excess = 0.0
    for k, tmax in enumerate(angles):
        key, sub = jax.random.split(key)
        th, t, ff = C.random_admissible(sub, mu, float(tmax), n_profiles, n_nodes)
        fv[k] = np.asarray(jax.vmap(lambda tt, f: C.vertical_force(tt, f, th))(t, ff))  # noqa: B023 - called here
        fv_closed[k] = np.asarray(C.vertical_force_closed(t[:, -1], tmax))
        lo, hi = C.capstan_bounds(mu, th)
        excess = max(excess, float(jnp.max(jnp.maximum(lo - t, t - hi) / hi)))
    # Profiles at the largest angle for the figure.
    th, t, ff = C.random_admissible(jax.random.PRNGKey(seed + 1), mu, float(angles[-1]),
                                    min(n_profiles, 50), n_nodes)
    lo, hi = C.capstan_bounds(mu, th)
    return {"fv": fv, "fv_closed": fv_closed, "excess": excess, "theta": np.asarray(th),
            "T": np.asarray(t), "T_lower": np.asarray(lo), "T_upper": np.asarray(hi)}


def cylinder_summary(mu: float, angles, study: dict) -> dict:
    """``summary.json`` of ``kind: cylinder``."""
    fv, fv_closed = study["fv"], study["fv_closed"]
    rel = np.max(np.abs(fv - fv_closed) / np.abs(fv_closed))
    return {
        "status": "ok",
        "mu": mu,
        "capstan_ratio_at_pi": float(np.exp(mu * np.pi)),
        "min_F_v": float(fv.min()),
        "min_F_v_over_lower_bound": float(
            np.min(fv / (np.exp(-mu * angles) * np.sin(angles))[:, None])
        ),
        "all_F_v_positive": bool((fv > 0).all()),
        "max_rel_diff_F_v_vs_closed_form": float(rel),
        "max_capstan_bound_violation": study["excess"],
        "n_states": int(fv.size),
        "conclusion": "F_v > 0 for every admissible state: no invagination in 2D"
        if (fv > 0).all()
        else "some admissible state has F_v <= 0",
    }
