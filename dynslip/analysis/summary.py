"""``summary.json`` of a forming run: the end state, whether the ball is trapped, the
friction the end state mobilises, the energy balance and the solver's statistics, from
the trajectory dataset and the driver's result.

Trapped (the criterion): the run ended at rest in its last stage (``until: rest`` met),
the contact edge lies past the equator ($\\theta_{max} > \\pi/2$), the ball's reaction is
below ``numerics.trap_reaction_tol``, and the mesh resolved the contact
(:func:`dynslip.analysis.resolution.chord_check`). Trapped is unknown (``None``), each reason
in ``trapped_unknown_reasons`` (:func:`unknown_reasons`), where the run failed, the mesh does
not resolve the ball or a held body (the relative check too), the energy residual exceeds
``numerics.energy_bound`` of the work (every body's work counted), the ball or a free body ran
away, a stage ended at its time limit before its condition, the sheet let go of the tube (its
edge slid past the rim), or moving bodies passed into each other.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from dynslip.analysis.clearance import body_contacts, body_overlaps, overlap_tolerance
from dynslip.analysis.paper import ROUGH_END_STATE
from dynslip.analysis.resolution import body_chord_check, chord_check
from dynslip.physics.bodies import Disc, PastEdgeMidHeight, PastEquator, PastWidest, Sphere


def summarize(world, ds: xr.Dataset, result) -> dict:
    """summary.json: the end state, the friction it needs, energy balance, solver statistics,
    of the run of ``world`` (:class:`~dynslip.schema.world.World`: its bodies, stages, scales
    and limits) whose trajectory is ``ds``."""
    lim = world.limits
    r = world.scales.R_mm
    end = ds.isel(time=-1)
    failed = result.failed is not None
    contact = np.asarray(end["state"]) > 0
    theta_max = float(end["theta_max"])
    rbar_max = float(end["rbar_max"])
    lt = np.asarray(end["lambda_theta"])
    lp = np.asarray(end["lambda_phi"])
    i_t = int(np.nanargmax(lt))
    mu_mob = np.asarray(end["mu_mobilised"])
    mu_mobilised_max = float(np.nanmax(mu_mob[contact])) if contact.any() else float("nan")
    stage_names = world.stage_names
    slack = next(
        (s for s in result.stage_end if world.until(s["name"]) == "clamp_force_below"), None
    )
    # the energy that flowed: the work done on the sheet and ball (every body's counted), or
    # the stored energy released where a start state unloads (a release): the residual is
    # judged against the larger
    work = (np.abs(ds["work_clamp"].values) + np.abs(ds["work_ball"].values)
            + np.abs(ds["work_bodies"].values))
    stored = ds["energy_elastic"].values + ds["energy_penalty"].values
    released = np.abs(stored - stored[0]) if stored.size else stored
    work_scale = float(max(np.max(work), np.max(released))) if work.size else float("nan")
    resid = ds["energy_residual"].values
    last = result.stage_end[-1] if result.stage_end else None
    at_rest = bool(last and last["condition_met"] and world.until(last["name"]) == "rest"
                   and len(result.stage_end) == len(stage_names))
    reaction = float(end["ball_reaction"])
    ball = world.ball
    mesh_check = chord_check(ds, lim.max_chord_depth, ball)
    entries = list(world.bodies)
    if entries:  # every held body at its height in each frame (analysis.resolution)
        mesh_check["bodies"] = body_chord_check(ds, entries, lim.max_chord_depth, r)
        mesh_check["bodies_means"] = (
            "per held body (name): the largest depth (R, and mm) that a straight element between "
            "two nodes reaches inside the body placed where it is in each saved frame, when and on "
            "which element; negative: every chord outside it by that much; the run stops as failed "
            "past the limit, as for the ball (no pole crossing: that is the ball's). "
            "max_relative_chord_depth: the largest depth relative to the local radius of curvature "
            "(radius_R, radius_mm) of the part of the body's profile the chord cuts off (on the "
            "unit ball the same number), the arc one element spans on it (span_rad), when and on "
            "which element; resolved: every relative depth at most the limit. The relative test "
            "is reported, not enforced (the run stops on the absolute depth)"
        )
    trap = trap_check(ball, end, theta_max)
    rel_resid = float(np.max(np.abs(resid)) / work_scale) if work_scale > 0 else float("nan")
    events = let_go_events(world, ds)
    reasons = unknown_reasons(world, ds, result, mesh_check, rel_resid, events)
    trapped = None if reasons else bool(
        at_rest and trap["past"] and abs(reaction) < lim.trap_reaction_tol)
    lip = (math.sin(theta_max) / rbar_max) if np.isfinite(theta_max) and rbar_max > 0 else None
    path_lt = float(np.nanmax(ds["lambda_theta"].values))
    path_lp = float(np.nanmax(ds["lambda_phi"].values))
    path_i1 = uniaxial_equivalent(ds)
    st = result.stats
    summary = {
        "status": "failed" if failed else "ok",
        "message": result.failed or "",
        "trapped": trapped,
        "trapped_unknown_reasons": reasons,
        "events": events,
        "mesh_check": mesh_check,
        "trap_criterion": trap,
        "theta_max": theta_max,
        "rbar_max": rbar_max,
        "node_based_means": ("theta_max, rbar_max: the last node in contact's (largest polar "
                             "angle in contact, its material radius): piecewise constant in the "
                             "parameters, jumping where the contact set changes; the edge "
                             "located between nodes is in smooth"),
        "smooth": smooth_observables(end),
        "opening_radius": math.sin(theta_max) if np.isfinite(theta_max) else float("nan"),
        "lip": {
            "sin_theta_max": math.sin(theta_max) if np.isfinite(theta_max) else None,
            "rbar_max": rbar_max if np.isfinite(rbar_max) else None,
            "hoop_stretch": lip,
            "paper_rough": dict(ROUGH_END_STATE),
            "means": ("the lip's hoop stretch sin(theta_max) / rbar_max at the contact's edge: "
                      "above 1 the lip is hoop-stretched (a taut span leaving the lip "
                      "horizontally is a rest state too), below 1 hoop-compressed; reported, "
                      "not a test of rest"),
        },
        "largest_stretch": {
            "lambda_theta": float(lt[i_t]),
            "rbar": float(ds["rbar"].values[i_t]),
            "theta": float(end["theta"].values[i_t]),
            "in_contact": bool(contact[i_t]),
            "lambda_phi_max": float(np.nanmax(lp)),
            "path_max_lambda_theta": path_lt,
            "path_max_lambda_phi": path_lp,
            "path_max": max(path_lt, path_lp),
            "path_max_i1_uniaxial": path_i1,
            "latex_damage_stretch": LATEX_DAMAGE_STRETCH,
            "past_damage": bool(max(path_lt, path_lp, path_i1)
                                > LATEX_DAMAGE_STRETCH),
            "means": ("the largest principal stretch on the path (meridional and hoop), and the "
                      "uniaxial stretch with the same I1 as the path's largest I1 "
                      "(lambda^2 + 2/lambda = I1, incompressible), against latex's damage "
                      "stretch of about 6 (the paper, Section 2.1)"),
        },
        "friction_law": world.friction["friction_law"],
        "mu": world.friction["mu"],
        **(
            {k: world.friction[k] for k in ("mu_s", "mu_k", "d_c_mm")}
            if world.friction["d_c_mm"] > 0  # a law that weakens (slip weakening, adhesive)
            else {}
        ),
        "mu_mobilised_max": mu_mobilised_max,
        "mu_mobilised_max_means": (
            "largest |friction| / normal force over the contact of the end state: the "
            "friction this state mobilises, not the least friction the path needs (a "
            "fully mobilised end state returns the input mu); the path's critical mu is "
            "found by `dynslip window` (window.json)"
        ),
        "contact_nodes": int(contact.sum()),
        "slack_rim_height": {
            "reached": bool(slack["condition_met"]) if slack else None,
            "z_R": slack["clamp_z"] if slack else None,
            "z_mm": slack["clamp_z"] * r if slack else None,
        },
        "end_at_rest": at_rest,
        "end_at_rest_says": rest_words(world, ds, result, at_rest),
        "ball_reaction_end": reaction,
        "ball_z_end": float(end["ball_z"]),
        "clamp_force_end": float(end["clamp_force"]),
        "energy_balance": {
            "residual_end": float(resid[-1]),
            "residual_max_abs": float(np.max(np.abs(resid))),
            "work_scale": work_scale,
            "work_scale_means": ("the largest over the path of the work done (clamp, ball and "
                                 "every moving body) and of the stored energy released since "
                                 "the start; relative_residual is the largest residual over it"),
            "relative_residual": rel_resid,
            "bound": lim.energy_bound,
            "initial_energy": float(ds.attrs["energy_initial"]),
        },
        "stages": result.stage_end,
        "solver": {
            "steps": st["steps"],
            "accepted": st["accepted"],
            "rejected": st["rejected"],
            "segments": st["segments"],
            "compile_s": st["compile_s"],
            "run_s": st["run_s"],
            "time_per_step_ms": st["time_per_step_ms"],
            "wall_s": st.get("wall_s"),
            "method": st.get("method"),
            "newton_iterations": st.get("newton_iterations"),
        },
        "nodes": lim.nodes,
    }
    if entries:

        summary["bodies"] = body_contacts(ds, entries, r)
        summary["bodies_means"] = (
            "per held body: the sheet's closest approach over the saved path (closest_R, "
            "closest_mm; negative: inside it) and whether it touched the body; the contact's "
            "extent in the body's surface coordinate s (arc length along its profile, from "
            "the profile's start) at the end and its longest over the path, and the fraction "
            "of the nodes in contact at the end stuck relative to the body (frictional bodies)"
        )

        tol = overlap_tolerance(world.thickness_R, lim.penalty_width)
        overlaps = body_overlaps(ds, entries, ball, r, tol)
        if overlaps:
            # the model has no contact between rigid bodies: no answer from such a path
            summary["bodies_overlap"] = overlaps
            summary["bodies_overlap_means"] = (
                "a body moved by the stages or free passes into the ball or another body "
                "(into) deeper than the sheet's thickness plus twice the penalty's width "
                f"({tol * r:.3g} mm): the model has no contact between rigid "
                "bodies, so the path is not a world of solids and trapped has no answer")
            summary["trapped"] = None
            summary["trapped_unknown_reasons"].append(
                f"body {overlaps[0]['name']!r} passes into the {overlaps[0]['into']} (the model "
                "has no contact between rigid bodies)")
    summary["outcome"] = outcome_words(summary)
    return summary


def smooth_observables(end) -> dict:
    """The end state's observables that are continuous in the parameters
    (:mod:`dynslip.physics.observables`): the located contact edge and theta at fixed material
    radii. Files written before them give None."""
    def val(k):
        return float(end[k]) if k in end and np.isfinite(float(end[k])) else None

    at = (dict(zip((f"{r:.2f}" for r in end["rbar_at"].values),
                   (float(v) if np.isfinite(v) else None for v in end["theta_at_rbar"].values),
                   strict=True)) if "theta_at_rbar" in end else None)
    return {
        "theta_edge": val("theta_edge"),
        "rbar_edge": val("rbar_edge"),
        "theta_at_rbar": at,
        "means": ("the contact edge located between the last node in contact and the next, where "
                  "the contact function (the node's penetration into the ball past the one at "
                  "which its pressure equals the contact threshold) crosses zero, by linear "
                  "interpolation: theta_edge (rad) and rbar_edge (R) move continuously through a "
                  "change of the contact set (theta_max, rbar_max: the node-based values). "
                  "theta_at_rbar: the polar angle (rad) of the material circle of each radius "
                  "rbar (R), linear in the material coordinate; on the contact for rbar <= "
                  "rbar_edge, the circle's angle off the ball beyond it"),
    }


#: latex is damaged past about this stretch in one direction (the paper, Section 2.1)
LATEX_DAMAGE_STRETCH = 6.0


def uniaxial_equivalent(ds: xr.Dataset) -> float:
    r"""The uniaxial stretch with the path's largest first invariant: $\lambda^2 + 2/\lambda =
    I_1$ (incompressible), $I_1 = \lambda_\theta^2 + \lambda_\phi^2 +
    (\lambda_\theta\lambda_\phi)^{-2}$ at every node and frame; the root >= 1."""
    lt = np.asarray(ds["lambda_theta"].values, float)
    lp = np.asarray(ds["lambda_phi"].values, float)
    i1 = lt**2 + lp**2 + 1.0 / (lt * lp) ** 2
    i1_max = float(np.nanmax(i1))
    roots = np.roots([1.0, 0.0, -i1_max, 2.0])
    return float(max(r.real for r in roots if abs(r.imag) < 1e-9))


def let_go_events(world, ds: xr.Dataset) -> list:
    """The sheet let go of the tube: over a stage whose band holds the edge, the edge slid
    past the tube's rim (below the rim's lowest point, where the band's wall ends): the first
    frame where it did, as ``[{name, stage, time_s, edge_z_mm, rim_z_mm}]`` (empty: never)."""
    if world.tube_rim_z is None:
        return []
    band = list(world.band_stages)
    stage = np.asarray(ds["stage"].values)
    rim = np.full(stage.shape, world.tube_rim_z)
    names = world.body_names
    if "body_z" in ds and "tube wall" in names:
        rim = rim + np.asarray(ds["body_z"].values[:, names.index("tube wall")], float)
    edge = np.asarray(ds["z"].values[:, -1], float)
    past = np.isin(stage, band) & (edge < rim)
    if not past.any():
        return []
    i = int(np.argmax(past))
    r = world.scales.R_mm
    return [{"name": "sheet let go", "stage": world.stage_names[int(stage[i])],
             "time_s": float(ds["time"].values[i]), "edge_z_mm": float(edge[i] * r),
             "rim_z_mm": float(rim[i] * r),
             "means": "the sheet's edge slid along the tube's outer wall past its rim: the band "
                      "no longer holds it on the tube (the model's band has no wall there)"}]


def unknown_reasons(world, ds: xr.Dataset, result, mesh_check: dict, rel_resid: float,
                    events: list) -> list:
    """Why trapped has no answer, one line each (empty: it has one)."""
    nu = world.limits
    r = world.scales.R_mm
    out = []
    if result.failed is not None:
        out.append(f"the run failed: {result.failed}")
    if not mesh_check["resolved"]:
        out.append("the mesh does not resolve the contact with the ball (a chord "
                   f"{mesh_check['max_chord_depth']:.3g} R deep, limit {mesh_check['limit']:g})")
    for name, b in mesh_check.get("bodies", {}).items():
        if not b["resolved"]:
            out.append(f"the mesh does not resolve the {name} (a chord "
                       f"{b['max_relative_chord_depth']:.3g} of its radius "
                       f"{b['radius_mm']:.3g} mm deep at t = {b['relative_time_s']:.4g} s; "
                       f"limit {mesh_check['limit']:g}): more nodes")
    if np.isfinite(rel_resid) and rel_resid > nu.energy_bound:
        out.append(f"the energy residual is {rel_resid:.3g} of the work, above the bound "
                   f"{nu.energy_bound:g} (numerics.energy_bound)")
    moved = abs(float(ds["ball_z"].values[-1]) - float(ds["ball_z"].values[0])) * r
    if moved > nu.runaway_mm:
        out.append(f"the ball ran away: {moved:.4g} mm from where it started (numerics."
                   f"runaway_mm = {nu.runaway_mm:g})")
    if "body_z" in ds:
        names = world.body_names
        for name in world.free:
            k = names.index(name)
            d = abs(float(ds["body_z"].values[-1, k]) - float(ds["body_z"].values[0, k])) * r
            if d > nu.runaway_mm:
                out.append(f"body {name!r} ran away: {d:.4g} mm from where it started")
    for s in result.stage_end:
        if not s["condition_met"] and world.until(s["name"]) != "duration":
            out.append(f"stage {s['name']!r} ended at its time limit (t = {s['t_end']:.4g} s) "
                       f"before its condition (until: {world.until(s['name'])})")
    done = len(result.stage_end)
    if result.failed is None and done < len(world.stage_names):
        out.append(f"the run ended after {done} of {len(world.stage_names)} stages")
    for e in events:
        out.append(f"the sheet let go of the tube at t = {e['time_s']:.4g} s (stage "
                   f"{e['stage']!r}): its edge slid past the rim")
    return out


def trap_criterion(ball):
    """The ball's trapped criterion (:mod:`dynslip.physics.bodies.trap`): past the equator for
    a sphere, past the edge's mid-height for a disc, past the widest part for any other body."""

    if isinstance(ball, Sphere):
        return PastEquator(radius=ball.radius)
    if isinstance(ball, Disc):
        return PastEdgeMidHeight(disc=ball)
    return PastWidest(body=ball)


def contact_reach(ball, frame, theta_max: float) -> float:
    """How far the contact reaches along the ball's profile, s_max (units of R; NaN without
    contact): for a sphere about the origin its radius times theta_max (s = a theta, so for the
    unit ball exactly theta_max), else the largest surface coordinate of a node in contact."""

    if isinstance(ball, Sphere) and ball.centre_z == 0.0:
        return ball.radius * theta_max
    contact = np.asarray(frame["state"]) > 0
    if not contact.any():
        return float("nan")
    x = np.stack([np.asarray(frame["rho"]), np.asarray(frame["z"])], -1)[contact]
    return float(np.max(np.asarray(ball.project(x, float(frame["ball_z"])).s)))


def trap_check(ball, frame, theta_max: float) -> dict:
    """Whether the end state's contact reaches past the ball's trapped threshold
    (:func:`trap_criterion`): for the unit ball exactly theta_max > pi/2."""
    crit = trap_criterion(ball)
    s_max = contact_reach(ball, frame, theta_max)
    thr = float(crit.threshold())
    return {
        "criterion": type(crit).__name__,
        "ball": type(ball).__name__,
        "s_max": s_max,
        "threshold": thr,
        "margin": s_max - thr,
        "past": bool(np.isfinite(s_max) and s_max > thr),
        "means": ("the contact's extent s_max along the ball's profile (arc length from its top "
                  "pole, units of R) against the kind's threshold: a sphere's equator (s = "
                  "radius pi/2: for the unit ball theta_max > pi/2), a disc's edge at "
                  "mid-height; trapped needs past, at rest, and the ball's reaction gone"),
    }


def rest_words(world, ds: xr.Dataset, result, at_rest: bool) -> str:
    """Whether the run ended at rest, in words: a run whose last stage ended at its time limit
    is flagged, with how far the ball moved over that stage (its end state is where the run
    stopped, not a rest state)."""
    last = result.stage_end[-1] if result.stage_end else None
    if at_rest:
        assert last is not None  # at rest: a stage met its rest condition
        return (f"at rest: stage {last['name']!r} met its rest condition at "
                f"t = {last['t_end']:.4g} s")
    if last is None:
        return "not at rest: the run ended before its first stage did"
    if world.until(last["name"]) != "rest":
        return (f"no rest stage: the run ends with stage {last['name']!r} at "
                f"t = {last['t_end']:.4g} s (its end state is not checked for rest)")
    z = ds["ball_z"].values
    in_stage = np.flatnonzero(ds["stage"].values == len(result.stage_end) - 1)
    moved = (f"; the ball moved from z = {z[in_stage[0]]:.3g} to {z[in_stage[-1]]:.3g} R over "
             "the stage" if in_stage.size else "")
    limit = len(result.stage_end) == len(world.stage_names) and not last["condition_met"]
    why = "ended at its time limit" if limit else "did not finish"
    return (f"NOT AT REST: stage {last['name']!r} {why} (t = {last['t_end']:.4g} s) before the "
            f"sheet and ball came to rest{moved}; the end state is where the run stopped, not a "
            "rest state")


def outcome_words(s: dict) -> str:
    """The run's answer in one line (figures' titles and the terminal): trapped or not, where
    the contact ends, and why there is no answer when there is none."""
    theta = s["theta_max"]
    contact = (f"contact ends at theta_max = {theta:.3g} rad (rbar_max {s['rbar_max']:.3g} R)"
               if np.isfinite(theta) else "no contact at the end")
    if s["status"] != "ok":
        return f"failed: no answer ({contact})"
    if s.get("bodies_overlap"):
        o = s["bodies_overlap"][0]
        return (f"no answer: body {o['name']!r} passes into the {o['into']} by "
                f"{o['depth_mm']:.3g} mm at t = {o['time_s']:.4g} s (the model has no contact "
                f"between rigid bodies; {contact})")
    if s["trapped"] is None:
        why = s.get("trapped_unknown_reasons") or ["no answer"]
        more = f" (and {len(why) - 1} more reasons: summary.json)" if len(why) > 1 else ""
        return f"trapped unknown: {why[0]}{more}; {contact}"
    if s["trapped"]:
        return f"trapped; {contact}"
    return f"not trapped; {contact}"

