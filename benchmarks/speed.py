"""Speed of the whole let-go path: load stepping against Kvaerno5 and scipy BDF.

The path is ``benchmarks/method2_let_go.yaml`` (a frozen copy of
``scenarios/method2_let_go.yaml``: push-down past the held ball, hold, let go, release,
rest), run whole at N = 50, 100, 200, 400 nodes (``DYNSLIP_BENCH_SPEED_NODES=50,100``
picks sizes; ``DYNSLIP_BENCH_SPEED_SOLVERS=kvaerno5`` picks the solvers run beside load_step) by:

- ``load_step``: the default solver, implicit Euler load increments
  (:mod:`dynslip.physics.solver.loadstep`);
- ``load_step_law``: the same with Newton on the friction law's own form
  (``numerics.newton_weight=0``), the baseline of the weighted form (``speedup_vs_load_step_law``,
  the end states compared in its ``vs_load_step``);
- ``kvaerno5``: the reference, diffrax Kvaerno5 with the structured linear solver;
- ``scipy_bdf``: ``scipy.integrate.solve_ivp(method="BDF", jac_sparsity=...)`` on the same
  jitted vector field (:func:`dynslip.physics.field.vector_field`) with the same sparsity
  pattern, stage by stage over the *same* stage intervals the load_step run took
  (``Result.stage_end``), in the same save segments as
  :func:`dynslip.physics.driver.simulate.simulate`
  (a restart and the friction law's healing at every segment end, the ball's and clamp's
  force start values carried between stages), so no stop rule is evaluated. Capped at
  ``DYNSLIP_BENCH_SPEED_SCIPY_CAP`` s of wall time per N (default 300): past it the rhs
  callback raises and the row says "not finished, reached t = ...". scipy counts only
  accepted steps.

Reported per solver: steps (accepted + rejected), rejected, Newton iterations (load_step),
run_s, compile_s, ms per step, trapped, theta_max; the end-state agreement of load_step
(and scipy) with kvaerno5 (same trapped outcome, |theta_max difference|, max |dtheta| on the
common contact region, :mod:`dynslip.analysis.compare`); ratios in the same process
(kvaerno5 / load_step and scipy / load_step run time, load_step's run-time growth from
100 to 400 nodes) and the issue's targets, met or not.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from pathlib import Path

SCENARIO = Path(__file__).resolve().parent / "method2_let_go.yaml"
SCIPY_CAP_S = float(os.environ.get("DYNSLIP_BENCH_SPEED_SCIPY_CAP", "300"))
# the solvers run at every N (load_step always): DYNSLIP_BENCH_SPEED_SOLVERS=kvaerno5,scipy_bdf
# by default
SOLVERS = [
    v for v in os.environ.get("DYNSLIP_BENCH_SPEED_SOLVERS", "kvaerno5,scipy_bdf").split(",") if v
]

# the friction law: the frozen file's slip weakening, or DYNSLIP_BENCH_SPEED_LAW=coulomb (its mu, no
# healing restarts for kvaerno5: issue 23's like-for-like comparison)
LAW = os.environ.get("DYNSLIP_BENCH_SPEED_LAW", "")
# kvaerno5's step limit per save segment, raised so that the reference finishes at N = 200
KV_MAX_STEPS = int(os.environ.get("DYNSLIP_BENCH_SPEED_KV_MAX_STEPS", "200000"))

# the targets (issue 23)
MAX_STEPS = 1000  # whole path, every N
SPEEDUP_200 = 15.0  # load_step vs kvaerno5 at N = 200 (run time)
GROWTH_100_400 = 4.0  # load_step run time, N = 400 over N = 100
RUN_S_200 = 1.5  # load_step run time at N = 200, warm (the frozen slip-weakening path)
RUN_S_800 = 8.0  # load_step run time at N = 800
NEWTON_PER_STEP = 5.0  # Newton iterations per increment, on average
THETA_TOL = 0.01  # rad: |theta_max difference| and max |dtheta| vs kvaerno5


def _scenario(nodes: int, solver: str, *sets: str):
    from dynslip.schema.base import load

    law = [f"physics.friction.law={LAW}"] if LAW else []
    return load(SCENARIO, [f"numerics.nodes={nodes}", f"numerics.solver={solver}", *law, *sets])


def _end(sc, model, protocol, result):
    """(trajectory dataset, summary) of a result, as ``dynslip run`` makes them."""
    from dynslip.analysis.summary import summarize
    from dynslip.app.forming import to_dataset

    world = sc.world()  # the same mesh and stages as ``model`` and ``protocol``
    ds = to_dataset(world, result.frames, result.e0, result.failed is None)
    return ds, summarize(world, ds, result)


def _simulate(nodes: int, solver: str) -> tuple[dict, object, object, tuple]:
    """One whole run of the scenario with ``numerics.solver`` ``solver``; ``load_step_law``
    runs load_step with Newton on the friction law's own form (``numerics.newton_weight=0``; the
    default iterates on its weighted form); kvaerno5 with ``KV_MAX_STEPS``."""
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    if solver == "load_step_law":
        sc = _scenario(nodes, "load_step", "numerics.newton_weight=0")
    elif solver == "kvaerno5":
        sc = _scenario(nodes, solver, f"numerics.max_steps={KV_MAX_STEPS}")
    else:
        sc = _scenario(nodes, solver)
    model, protocol, kw = build_core(sc)
    w0 = time.perf_counter()
    res = simulate(model, protocol, **kw)
    wall = time.perf_counter() - w0
    ds, summ = _end(sc, model, protocol, res)
    st = res.stats
    row = {
        "ok": res.failed is None,
        "failed": res.failed or "",
        "steps": st["steps"],
        "accepted": st["accepted"],
        "rejected": st["rejected"],
        "newton_iterations": st["newton_iterations"],
        "newton_per_step": (st["newton_iterations"] / max(st["steps"], 1))
        if st["newton_iterations"] is not None
        else None,
        "run_s": st["run_s"],
        "compile_s": st["compile_s"],
        "wall_s": wall,
        # the driver's own time: the whole run less the compiled segment solves and the compile
        "host_s": wall - st["run_s"] - st["compile_s"],
        "segments": st["segments"],
        "ms_per_step": st["time_per_step_ms"],
        "simulated_s": float(res.frames[-1]["time"]),
        "trapped": summ["trapped"],
        "theta_max": summ["theta_max"],
    }
    return row, res, ds, (sc, model, protocol, kw)


class _Cap(Exception):
    """The wall-clock cap of the scipy baseline was passed."""


def _scipy(ref, core) -> tuple[dict, object]:
    """scipy BDF over the stage intervals of ``ref`` (the load_step Result).

    scipy's own failures (its LU "exactly singular" after its finite-difference Jacobian
    overflowed) are reported with the time reached, as the cap is.
    """
    import jax
    import numpy as np
    import scipy.sparse as sp
    from scipy.integrate import solve_ivp

    from dynslip.physics.driver.member import Result, stage_args
    from dynslip.physics.field import Layout, vector_field
    from dynslip.physics.frames import frame_record, initial_state, reset_internal
    from dynslip.physics.layout import f64 as _f
    from dynslip.physics.solver.linalg import sheet_structure, to_dense

    sc, model, protocol, kw = core
    settings = kw["settings"]
    layout = Layout(model.mesh.n, kw["friction"].n_internal())
    vf = jax.jit(vector_field(model, layout))
    s = sheet_structure(layout)
    n, b, m = s.n, s.b, s.m
    ones = np.ones((n, b, b))
    pattern = np.asarray(
        to_dense(ones, ones, ones, np.ones((n * b, m)), np.ones((m, n * b)), np.ones((m, m)), s)
    )
    sparsity = sp.csr_matrix(pattern != 0)

    def args_of(stage, t0, y, reaction, clamp_reaction):
        return stage_args(
            stage,
            t0,
            float(y[2 * layout.n - 1]),
            reaction,
            clamp_reaction,
            kw["friction"],
            kw["eps"],
            kw["drag"],
            kw["ball_drag"],
            kw["weight"],
            support_z=protocol.ball_z0,
            support_k=kw["support_stiffness"],
        )

    y = initial_state(model, layout, kw["pre_stretch"], kw["z_sheet"], protocol.ball_z0)
    args0 = args_of(protocol.stages[0], 0.0, y, 0.0, (0.0, 0.0))
    c0 = time.perf_counter()
    vf(_f(0.0), y, args0).block_until_ready()

    def rec_fn(t, yy, a):
        rec = frame_record(model, layout, _f(t), yy, a, settings.contact_threshold)
        return {k: np.asarray(v) for k, v in rec.items()}

    rec_fn(0.0, y, args0)
    reset_internal(model, layout, y, args0, _f(settings.solver.heal_rate)).block_until_ready()
    compile_s = time.perf_counter() - c0

    frames = []

    def record(t, yy, a, si):
        rec = rec_fn(t, yy, a)
        rec["time"], rec["stage"] = float(t), si
        frames.append(rec)
        return rec

    record(0.0, y, args0, 0)
    e0 = float(frames[0]["energy_elastic"] + frames[0]["energy_penalty"])
    counts = {"steps": 0, "nfev": 0, "njev": 0, "nlu": 0}
    t_now = [0.0]
    w0 = time.perf_counter()
    deadline = w0 + SCIPY_CAP_S
    reaction, clamp_reaction = 0.0, (0.0, 0.0)
    stage_end, failed = [], None
    caught = warnings.catch_warnings(record=True)
    seen = caught.__enter__()
    try:
        for si, (stage, end) in enumerate(zip(protocol.stages, ref.stage_end, strict=False)):
            t = end["t_start"]
            args = args_of(stage, t, y, reaction, clamp_reaction)
            n_seg = max(1, math.ceil(stage.max_duration / settings.save_interval - 1e-9))
            seg_ts = [
                float(v)
                for v in np.linspace(t, t + stage.max_duration, n_seg + 1)[1:]
                if v <= end["t_end"] + 1e-9
            ]

            def fun(tt, yy, args=args):
                if time.perf_counter() > deadline:
                    raise _Cap()
                t_now[0] = tt
                return np.asarray(vf(tt, yy, args))

            for t1 in seg_ts:
                sol = solve_ivp(
                    fun,
                    (t, t1),
                    np.asarray(y),
                    method="BDF",
                    rtol=settings.rtol,
                    atol=settings.atol,
                    jac_sparsity=sparsity,
                )
                counts["steps"] += int(sol.t.size - 1)
                counts["nfev"] += int(sol.nfev)
                counts["njev"] += int(sol.njev)
                counts["nlu"] += int(sol.nlu)
                if not sol.success:
                    failed = f"stage {stage.name!r}, t = {t:.6g} s: {sol.message}"
                    break
                y = jax.numpy.asarray(sol.y[:, -1])
                if layout.n_int:
                    y = reset_internal(model, layout, y, args, _f(settings.solver.heal_rate))
                t = t1
                record(t, y, args, si)
            reaction = float(frames[-1]["ball_reaction"])
            clamp_reaction = (
                float(frames[-1]["clamp_force_rho"]),
                float(frames[-1]["clamp_force"]),
            )
            stage_end.append(dict(end, t_end=t))
            if failed:
                break
    except _Cap:
        failed = f"not finished, reached t = {t_now[0]:.4g} s of {ref.stage_end[-1]['t_end']:.4g} s"
    except (RuntimeError, ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
        failed = (
            f"{type(err).__name__}: {err}, at t = {t_now[0]:.4g} s of "
            f"{ref.stage_end[-1]['t_end']:.4g} s "
            f"({time.perf_counter() - w0:.3g} s wall)"
        )
    finally:
        caught.__exit__(None, None, None)
    run_s = time.perf_counter() - w0
    row = {
        "ok": failed is None,
        "failed": failed or "",
        **counts,
        "rejected": None,
        "run_s": run_s,
        "compile_s": compile_s,
        "ms_per_step": 1e3 * run_s / max(counts["steps"], 1),
        "simulated_s": float(frames[-1]["time"]),
        "cap_s": SCIPY_CAP_S,
        "warnings": sorted({f"{w.category.__name__}: {w.message}" for w in seen}),
    }
    ds = None
    if failed is None:
        # the rest stop rule is not evaluated: the run follows load_step's intervals, whose last
        # stage met it (stage_end copies its condition_met)
        stats = {
            "accepted": counts["steps"],
            "rejected": 0,
            "segments": len(frames) - 1,
            "compile_s": compile_s,
            "run_s": run_s,
            "time_per_step_ms": row["ms_per_step"],
            "method": "scipy_bdf",
            **counts,
        }
        res = Result(frames=frames, stage_end=stage_end, stats=stats, e0=e0)
        ds, summ = _end(sc, model, protocol, res)
        row.update(trapped=summ["trapped"], theta_max=summ["theta_max"])
    else:
        row.update(trapped=None, theta_max=float(frames[-1]["theta_max"]))
    return row, ds


def _agreement(ds, ref_ds, row, ref_row) -> dict:
    """End state of ``row`` against the reference's; ``None`` figures where either did not finish
    (a partial trajectory's last frame is not an end state)."""
    from dynslip.analysis.compare import difference, end_state

    if not (row["ok"] and ref_row["ok"]):
        return {
            "same_trapped": None,
            "abs_dtheta_max": None,
            "max_abs_dtheta_contact": None,
            "common_rbar_max": None,
            "not_compared": ("reference " + (ref_row.get("failed") or "failed"))
            if not ref_row["ok"]
            else "run failed",
        }

    a, b = end_state(ref_ds), end_state(ds)
    d = difference(a, b)
    return {
        "same_trapped": row["trapped"] == ref_row["trapped"],
        "abs_dtheta_max": abs(row["theta_max"] - ref_row["theta_max"]),
        "max_abs_dtheta_contact": d["max_abs_dtheta"],
        "common_rbar_max": d["common_rbar_max"],
    }


def _one(nodes: int) -> dict:
    import numpy as np

    ls, ls_res, ls_ds, core = _simulate(nodes, "load_step")
    print(f"speed N={nodes} load_step: {ls}", flush=True)
    not_run = {
        "ok": False,
        "failed": "not run (DYNSLIP_BENCH_SPEED_SOLVERS)",
        "run_s": float("nan"),
        "simulated_s": float("nan"),
    }
    kv, kv_ds = not_run, None
    if "kvaerno5" in SOLVERS:
        kv, _, kv_ds, _ = _simulate(nodes, "kvaerno5")
        print(f"speed N={nodes} kvaerno5: {kv}", flush=True)
    full = not_run
    if "load_step_full" in SOLVERS:
        full, _, full_ds, _ = _simulate(nodes, "load_step_full")
        print(f"speed N={nodes} load_step_full: {full}", flush=True)
        full["vs_load_step"] = _agreement(full_ds, ls_ds, full, ls)
    law = not_run
    if "load_step_law" in SOLVERS:
        law, _, law_ds, _ = _simulate(nodes, "load_step_law")
        print(f"speed N={nodes} load_step_law: {law}", flush=True)
        law["vs_load_step"] = _agreement(law_ds, ls_ds, law, ls)
    sc_row, sc_ds = not_run, None
    if "scipy_bdf" in SOLVERS:
        try:
            sc_row, sc_ds = _scipy(ls_res, core)
        except (
            RuntimeError,
            ValueError,
            FloatingPointError,
            np.linalg.LinAlgError,
        ) as err:  # a failed baseline is reported
            sc_row, sc_ds = (
                {"ok": False, "failed": f"{type(err).__name__}: {err}", "run_s": float("nan")},
                None,
            )
        print(f"speed N={nodes} scipy_bdf: {sc_row}", flush=True)
    row = {
        "load_step": ls,
        "kvaerno5": kv,
        "scipy_bdf": sc_row,
        "load_step_full": full,
        "speedup_vs_load_step_full": full["run_s"] / ls["run_s"],
        "load_step_law": law,
        "speedup_vs_load_step_law": law["run_s"] / ls["run_s"],
        "load_step_vs_kvaerno5": _agreement(ls_ds, kv_ds, ls, kv),
    }
    if sc_ds is not None:
        row["scipy_bdf_vs_kvaerno5"] = _agreement(sc_ds, kv_ds, sc_row, kv)
    row["speedup_vs_kvaerno5"] = kv["run_s"] / ls["run_s"]
    row["speedup_vs_kvaerno5_means"] = (
        "not run"
        if kv is not_run
        else f"lower bound (kvaerno5 failed at t = {kv['simulated_s']:.4g} s)"
        if not kv["ok"]
        else "whole path"
    )
    row["speedup_vs_scipy"] = sc_row["run_s"] / ls["run_s"]
    row["speedup_vs_scipy_means"] = (
        "not run"
        if sc_row is not_run
        else "lower bound (scipy not finished)"
        if not sc_row["ok"]
        else "whole path"
    )
    return row


def _targets(out: dict, sizes: list[int]) -> dict:
    t: dict = {}
    worst = max(out[f"N{n}"]["load_step"]["steps"] for n in sizes)
    t["steps_at_most_1000"] = {
        "met": worst <= MAX_STEPS,
        "worst": worst,
        "per_N": {f"N{n}": out[f"N{n}"]["load_step"]["steps"] for n in sizes},
    }
    if 200 in sizes and "kvaerno5" in SOLVERS:
        s = out["N200"]["speedup_vs_kvaerno5"]
        t["speedup_vs_kvaerno5_N200_at_least_15x"] = {"met": s >= SPEEDUP_200, "value": s}
    if "load_step_run_s_growth_100_400" in out:
        g = out["load_step_run_s_growth_100_400"]
        t["growth_100_400_at_most_4x"] = {"met": g <= GROWTH_100_400, "value": g}
    if 200 in sizes:
        r = out["N200"]["load_step"]["run_s"]
        t["run_s_N200_at_most_1.5"] = {
            "met": r <= RUN_S_200,
            "value": r,
            "law": LAW or "slip_weakening",
        }
    if 800 in sizes:
        r = out["N800"]["load_step"]["run_s"]
        t["run_s_N800_at_most_8"] = {"met": r <= RUN_S_800, "value": r}
    per = {f"N{n}": out[f"N{n}"]["load_step"]["newton_per_step"] for n in sizes}
    t["newton_per_step_at_most_5"] = {"met": max(per.values()) <= NEWTON_PER_STEP, "per_N": per}
    ag = {f"N{n}": out[f"N{n}"]["load_step_vs_kvaerno5"] for n in sizes}
    done = {k: a for k, a in ag.items() if a["same_trapped"] is not None}
    skipped = sorted(set(ag) - set(done))
    if done:
        wt = max(a["abs_dtheta_max"] for a in done.values())
        wd = max(a["max_abs_dtheta_contact"] for a in done.values())
        t["theta_max_within_0.01"] = {"met": wt <= THETA_TOL, "worst": wt, "not_compared": skipped}
        t["max_dtheta_at_most_0.01"] = {
            "met": wd <= THETA_TOL,
            "worst": wd,
            "not_compared": skipped,
        }
        t["same_trapped"] = {
            "met": all(a["same_trapped"] for a in done.values()),
            "not_compared": skipped,
        }
    return t


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [
        int(v)
        for v in os.environ.get("DYNSLIP_BENCH_SPEED_NODES", "50,100,200,400").split(",")
        if v
    ]
    out: dict = {
        "path": "benchmarks/method2_let_go.yaml, whole (frozen copy of "
        "scenarios/method2_let_go.yaml)",
        "law": LAW or "slip_weakening (the file's)",
        "kvaerno5_max_steps": KV_MAX_STEPS,
        "tolerances": "the scenario's (rtol 1e-5, atol 1e-7)",
        "scipy_cap_s": SCIPY_CAP_S,
    }
    for n in sizes:
        out[f"N{n}"] = _one(n)
    if 100 in sizes and 400 in sizes:
        out["load_step_run_s_growth_100_400"] = (
            out["N400"]["load_step"]["run_s"] / out["N100"]["load_step"]["run_s"]
        )
    out["targets"] = _targets(out, sizes)
    return out


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    import json

    print(json.dumps(run(), indent=2, default=str))
