"""``summary.json`` of a forming run: the end state, whether the ball is trapped, the
friction the end state mobilises, the energy balance and the solver's statistics, from
the trajectory dataset and the driver's result.

Trapped (the criterion): the run ended at rest in its last stage (``until: rest`` met),
the contact edge lies past the equator ($\\theta_{max} > \\pi/2$), the ball's reaction is
below ``numerics.trap_reaction_tol``, and the mesh resolved the contact
(:func:`dynslip.analysis.resolution.chord_check`); a failed run or an unresolved contact
has no answer (``None``).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from dynslip.analysis.paper import ROUGH_END_STATE
from dynslip.analysis.resolution import body_chord_check, chord_check


def summarize(sc, ds: xr.Dataset, result) -> dict:
    """summary.json: the end state, the friction it needs, energy balance, solver statistics."""
    p = sc.physics
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
    stage_names = [s.name for s in p.stages]
    slack = next(
        (s for s in result.stage_end if _stage_until(p, s["name"]) == "clamp_force_below"), None
    )
    work = np.abs(ds["work_clamp"].values) + np.abs(ds["work_ball"].values)
    work_scale = float(np.max(work)) if work.size else float("nan")
    resid = ds["energy_residual"].values
    last = result.stage_end[-1] if result.stage_end else None
    at_rest = bool(last and last["condition_met"] and _stage_until(p, last["name"]) == "rest"
                   and len(result.stage_end) == len(stage_names))
    reaction = float(end["ball_reaction"])
    ball = p.ball_body()
    mesh_check = chord_check(ds, sc.numerics.max_chord_depth, ball)
    if p.named_bodies():  # every held body at its height in each frame (analysis.resolution)
        mesh_check["bodies"] = body_chord_check(ds, p.named_bodies(), sc.numerics.max_chord_depth,
                                                p.ball_radius_mm)
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
    if failed or not mesh_check["resolved"]:
        trapped = None  # a failed run, or sheet through the ball: no answer (analysis.resolution)
    else:
        trapped = bool(at_rest and trap["past"] and abs(reaction) < sc.numerics.trap_reaction_tol)
    st = result.stats
    summary = {
        "status": "failed" if failed else "ok",
        "message": result.failed or "",
        "trapped": trapped,
        "mesh_check": mesh_check,
        "trap_criterion": trap,
        "theta_max": theta_max,
        "rbar_max": rbar_max,
        "opening_radius": math.sin(theta_max) if np.isfinite(theta_max) else float("nan"),
        "rest_state_check": {
            "sin_theta_max": math.sin(theta_max) if np.isfinite(theta_max) else float("nan"),
            "rbar_max": rbar_max,
            "holds": bool(np.isfinite(theta_max) and math.sin(theta_max) <= rbar_max),
            "hoop_stretch_at_lift_off": (math.sin(theta_max) / rbar_max)
            if rbar_max > 0
            else float("nan"),
            "paper_rough": dict(ROUGH_END_STATE),
        },
        "largest_stretch": {
            "lambda_theta": float(lt[i_t]),
            "rbar": float(ds["rbar"].values[i_t]),
            "theta": float(end["theta"].values[i_t]),
            "in_contact": bool(contact[i_t]),
            "lambda_phi_max": float(np.nanmax(lp)),
            "path_max_lambda_theta": float(np.nanmax(ds["lambda_theta"].values)),
        },
        "friction_law": p.friction.law,
        "mu": p.friction.nominal_mu,
        **(
            {"mu_s": p.friction.mu_s, "mu_k": p.friction.mu_k, "d_c_mm": p.friction.d_c_mm}
            if p.friction.law == "slip_weakening"
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
            "z_mm": slack["clamp_z"] * p.ball_radius_mm if slack else None,
        },
        "end_at_rest": at_rest,
        "end_at_rest_says": rest_words(p, ds, result, at_rest),
        "ball_reaction_end": reaction,
        "ball_z_end": float(end["ball_z"]),
        "clamp_force_end": float(end["clamp_force"]),
        "energy_balance": {
            "residual_end": float(resid[-1]),
            "residual_max_abs": float(np.max(np.abs(resid))),
            "work_scale": work_scale,
            "relative_residual": float(np.max(np.abs(resid)) / work_scale)
            if work_scale > 0
            else float("nan"),
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
        "nodes": sc.numerics.nodes,
    }
    entries = p.named_bodies()
    if entries:
        from dynslip.analysis.clearance import body_contacts

        summary["bodies"] = body_contacts(ds, entries, p.ball_radius_mm)
        summary["bodies_means"] = (
            "per held body: the sheet's closest approach over the saved path (closest_R, "
            "closest_mm; negative: inside it) and whether it touched the body; the contact's "
            "extent in the body's surface coordinate s (arc length along its profile, from "
            "the profile's start) at the end and its longest over the path, and the fraction "
            "of the nodes in contact at the end stuck relative to the body (frictional bodies)"
        )
        from dynslip.analysis.clearance import body_overlaps, overlap_tolerance

        tol = overlap_tolerance(p.thickness_um * 1e-3 / p.ball_radius_mm,
                                sc.numerics.penalty_width)
        overlaps = body_overlaps(ds, entries, p.ball_body(), p.ball_radius_mm, tol)
        if overlaps:
            # the model has no contact between rigid bodies: no answer from such a path
            summary["bodies_overlap"] = overlaps
            summary["bodies_overlap_means"] = (
                "a body moved by the stages or free passes into the ball or another body "
                "(into) deeper than the sheet's thickness plus twice the penalty's width "
                f"({tol * p.ball_radius_mm:.3g} mm): the model has no contact between rigid "
                "bodies, so the path is not a world of solids and trapped has no answer")
            summary["trapped"] = None
    summary["outcome"] = outcome_words(summary)
    return summary


def trap_criterion(ball):
    """The ball's trapped criterion (:mod:`dynslip.physics.bodies.trap`): past the equator for
    a sphere, past the edge's mid-height for a disc, past the widest part for any other body."""
    from dynslip.physics.bodies import Disc, PastEdgeMidHeight, PastEquator, PastWidest, Sphere

    if isinstance(ball, Sphere):
        return PastEquator(radius=ball.radius)
    if isinstance(ball, Disc):
        return PastEdgeMidHeight(disc=ball)
    return PastWidest(body=ball)


def contact_extent(ball, frame, theta_max: float) -> float:
    """How far the contact reaches along the ball's profile, s_max (units of R; NaN without
    contact): for a sphere about the origin its radius times theta_max (s = a theta, so for the
    unit ball exactly theta_max), else the largest surface coordinate of a node in contact."""
    from dynslip.physics.bodies import Sphere

    if isinstance(ball, Sphere) and ball.centre_z == 0.0:
        return ball.radius * theta_max
    contact = np.asarray(frame["state"]) > 0
    if not contact.any():
        return float("nan")
    x = np.stack([np.asarray(frame["rho"]), np.asarray(frame["z"])], -1)[contact]
    return float(np.max(np.asarray(ball.project(x, float(frame["ball_z"])).s)))


def trap_check(ball, frame, theta_max: float) -> dict:
    """Whether the end state's contact reaches past the ball's trapped threshold
    (:func:`trap_criterion`): for the unit ball exactly today's theta_max > pi/2."""
    crit = trap_criterion(ball)
    s_max = contact_extent(ball, frame, theta_max)
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


def rest_words(p, ds: xr.Dataset, result, at_rest: bool) -> str:
    """Whether the run ended at rest, in words: a run whose last stage ended at its time limit
    is flagged, with how far the ball moved over that stage (its end state is where the run
    stopped, not a rest state)."""
    last = result.stage_end[-1] if result.stage_end else None
    if at_rest:
        return (f"at rest: stage {last['name']!r} met its rest condition at "
                f"t = {last['t_end']:.4g} s")
    if last is None:
        return "not at rest: the run ended before its first stage did"
    if _stage_until(p, last["name"]) != "rest":
        return (f"no rest stage: the run ends with stage {last['name']!r} at "
                f"t = {last['t_end']:.4g} s (its end state is not checked for rest)")
    z = ds["ball_z"].values
    in_stage = np.flatnonzero(ds["stage"].values == len(result.stage_end) - 1)
    moved = (f"; the ball moved from z = {z[in_stage[0]]:.3g} to {z[in_stage[-1]]:.3g} R over "
             "the stage" if in_stage.size else "")
    limit = len(result.stage_end) == len(p.stages) and not last["condition_met"]
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
        return f"no answer: the mesh does not resolve the contact ({contact})"
    if s["trapped"]:
        return f"trapped; {contact}"
    if not s["end_at_rest"] and s["end_at_rest_says"].startswith("NOT AT REST"):
        return f"not trapped (not at rest at the end); {contact}"
    return f"not trapped; {contact}"


def _stage_until(p, name):
    return next(s.until for s in p.stages if s.name == name)
