"""The end table a forming run prints on the terminal (:func:`print_end_table`): the end
state, the held bodies, the mesh's warnings and the solver's times, from the run's summary
(:func:`dynslip.analysis.summary.summarize`)."""

from __future__ import annotations

import math

__all__ = ["print_end_table", "touched_words", "unresolved_body_words"]


def touched_words(bodies: list) -> str:
    """The end table's line on the held bodies: which the sheet touched, else the nearest."""
    hit = [b["name"] for b in bodies if b["touched"]]
    if hit:
        return ", ".join(hit)
    near = min(bodies, key=lambda b: b["closest_R"])
    return f"none (nearest: {near['name']}, {near['closest_mm']:.3g} mm)"


def print_end_table(console, s: dict) -> None:
    """The end state and the solver's times on the terminal (compile and run separately)."""
    from rich.table import Table

    t = Table(title="end state")
    t.add_column("quantity")
    t.add_column("value", justify="right")
    fmt = lambda v: "-" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))  # noqa: E731
    rows = [
        ("trapped", s["trapped"]),
        ("ended at rest", s["end_at_rest"]),
        ("deepest chord in the ball (R)", s["mesh_check"]["max_chord_depth"]),
        ("theta_max (rad)", s["theta_max"]),
        ("rbar_max (R)", s["rbar_max"]),
        ("lip hoop stretch sin(theta_max) / rbar_max", s["lip"]["hoop_stretch"]),
        ("mu_mobilised_max", s["mu_mobilised_max"]),
        ("largest lambda_theta", s["largest_stretch"]["lambda_theta"]),
        ("largest stretch on the path (I1-uniaxial; latex: 6)",
         f"{s['largest_stretch']['path_max']:.3g} "
         f"({s['largest_stretch']['path_max_i1_uniaxial']:.3g})"),
        ("energy residual / work", s["energy_balance"]["relative_residual"]),
    ]
    if s["mesh_check"].get("bodies"):
        name, c = max(s["mesh_check"]["bodies"].items(), key=lambda kv: kv[1]["max_chord_depth"])
        rows.append((f"deepest chord in a held body ({name}, R)", c["max_chord_depth"]))
    if "bodies" in s:
        rows.append(("held bodies touched", touched_words(s["bodies"])))
    for o in s.get("bodies_overlap", ()):  # the model has no contact between rigid bodies
        rows.append((f"{o['name']} passes into", f"{o['into']}: {o['depth_mm']:.3g} mm at "
                                                 f"t = {o['time_s']:.4g} s"))
    if "release" in s:
        rows += [("release: peak force (N)", s["release"]["peak_force_N"]),
                 ("release: opening reached R", s["release"]["opening_reached_R"])]
    sv = s["solver"]
    rows += [
        ("steps (rejected)", f"{sv['steps']} ({sv['rejected']})"),
        ("compile (s)", sv["compile_s"]),
        ("run (s)", sv["run_s"]),
        ("ms per step", sv["time_per_step_ms"]),
    ]
    for k, v in rows:
        t.add_row(k, fmt(v))
    console.print(t)
    console.print(f"outcome: {s['outcome']}", highlight=False)
    for e in s.get("events", ()):
        console.print(f"[bold]event: {e['name']} at t = {e['time_s']:.4g} s (stage "
                      f"{e['stage']!r})[/bold]", highlight=False)
    for why in s.get("trapped_unknown_reasons", ())[1:]:
        console.print(f"trapped unknown also because {why}", highlight=False)
    if not s["end_at_rest"]:
        console.print(f"[bold]{s['end_at_rest_says']}[/bold]", highlight=False)
    limit = s["mesh_check"].get("limit")
    for name, c in s["mesh_check"].get("bodies", {}).items():
        line = unresolved_body_words(name, c, limit, s.get("nodes"))
        if line:
            console.print(f"[yellow]warning: {line}[/yellow]", highlight=False)


def unresolved_body_words(name: str, c: dict, limit, nodes) -> str | None:
    """The end table's warning for a held body the mesh does not resolve (``resolved`` false:
    a chord deeper than ``limit`` relative to the radius it cuts off;
    :func:`~dynslip.analysis.resolution.body_chord_check`), or None. A warning, not a failure:
    the run's stop rule is on the absolute depth. The mesh needed is estimated from the elements'
    length falling as 1/N: N times the arc spanned over the largest one allowed,
    2 arccos(1 - limit)."""
    if c.get("resolved", True) or limit is None:
        return None
    r_mm, span = c.get("radius_mm"), c.get("span_rad")
    rel = c["max_relative_chord_depth"]
    if not r_mm or span is None:  # a sharp corner: judged on the absolute depth
        return (f"{name}: a sharp corner not resolved by the mesh: a chord {rel:.3g} R deep "
                f"(limit {limit:g} R)")
    allowed = 2.0 * math.acos(1.0 - limit)
    at_least = "at least " if rel >= 1.0 - 1e-9 else ""
    need = f"; N >= about {math.ceil(nodes * span / allowed)} needed" if nodes else ""
    return (f"{name}: profile not resolved by the mesh where it curves to {r_mm:.3g} mm: an "
            f"element spans {at_least}{span:.2f} rad of it (chord {rel:.2f} of the radius deep, "
            f"limit {limit:g}: {allowed:.2f} rad) at t = {c['relative_time_s']:.4g} s{need}")

