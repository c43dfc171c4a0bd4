"""Benchmark of the static model: ``run() -> dict`` (imported by benchmarks/run.py).

Measures in one process, at the paper's grid (N = 100, rbar_max = 0.9, theta_max = 1.8):

- the selected fully mobilised member (boundary-value solve) per model, cold (compilation
  included) and warm;
- the paper's mu search from that member per model with the explicit march (the baseline:
  forward Euler at the stable step) and with the implicit march (backward Euler, semi-smooth
  Newton, growing steps), cold and warm, the three models together warm, the speed-up
  ``explicit / implicit`` and the mu difference between the two;
- the two selection rules of the fully mobilised family (F_m changes sign at rbar_s = 0.25 R,
  and at theta = pi/4 as the paper states it): mu of both members per model, Mooney-Rivlin
  (C1 = 0.4, C2 = 0.1) included, and the march-and-search mu of the switch_angle member;
- the same search with the diffrax march (Euler at the same step) for neo-Hookean, against
  the explicit loop and the boundary-value solve, with the mu each returns (equal accuracy:
  the same F_v tolerance and relative mu tolerance 1e-4);
- a cold ``dynslip run scenarios/paper_neohookean.yaml`` in a fresh process.

Run alone: ``python benchmarks/static.py``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
N, RMAX, TMAX, SEL = 100, 0.9, 1.8, 0.25
GUESS = (2.2, 1.0, 0.25)


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def run(cli: bool = True) -> dict:
    import dynslip  # noqa: F401
    from dynslip.physics import static as S
    from dynslip.physics.materials import make_material

    r = S.grid(N, RMAX)
    h = float(r[1])
    fv_tol = 1e-3
    res: dict = {"n_nodes": N, "models": {}}
    search_warm_total = 0.0
    implicit_warm_total = 0.0
    for model in ("hookean", "neo_hookean", "gent"):
        mat = make_material(model, jm=50.0)
        m, t_bvp_cold = _timed(
            lambda mat=mat: S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius")
        )
        _, t_bvp_warm = _timed(
            lambda mat=mat: S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius")
        )
        (th, _), t_sample = _timed(lambda mat=mat, m=m: S.sample_member(mat, m, RMAX, r))
        sr, t_cold = _timed(
            lambda mat=mat, th=th: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol)
        )
        sr2, t_warm = _timed(
            lambda mat=mat, th=th: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol)
        )
        si, t_i_cold = _timed(
            lambda mat=mat, th=th: S.search_mu(
                mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="implicit"
            )
        )
        _, t_i_warm = _timed(
            lambda mat=mat, th=th: S.search_mu(
                mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="implicit"
            )
        )
        search_warm_total += t_warm
        implicit_warm_total += t_i_warm
        res["models"][model] = {
            "mu_bvp": m.mu,
            "mu_search": sr.mu,
            "mu_search_vs_bvp": sr.mu / m.mu - 1,
            "bvp_cold_s": t_bvp_cold,
            "bvp_warm_s": t_bvp_warm,
            "sample_s": t_sample,
            "search_cold_s": t_cold,
            "search_warm_s": t_warm,
            "search_evaluations": sr.evaluations,
            "explicit_steps_last": int(sr.march.steps),
            "mu_search_implicit": si.mu,
            "mu_implicit_minus_explicit": si.mu - sr.mu,
            "search_implicit_cold_s": t_i_cold,
            "search_implicit_warm_s": t_i_warm,
            "implicit_speedup_warm": t_warm / t_i_warm,
        }
    res["search_warm_three_models_s"] = search_warm_total
    res["search_warm_three_models_implicit_s"] = implicit_warm_total
    res["implicit_speedup_three_models_warm"] = search_warm_total / implicit_warm_total
    res["mu_implicit_minus_explicit_max_abs"] = max(
        abs(v["mu_implicit_minus_explicit"]) for v in res["models"].values()
    )
    # the two selection rules (rbar_s = 0.25 R, theta_s = pi/4), BVP, plus the implicit search
    # from the switch_angle member
    rules: dict = {}
    for model in ("hookean", "neo_hookean", "gent", "mooney_rivlin"):
        mat = make_material(model, jm=50.0, c1=0.4, c2=0.1)
        mr = S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius")
        ma = S.solve_member(
            mat, math.pi / 4, TMAX, RMAX, (mr.lam0, mr.mu, mr.rbar_s), by="switch_angle"
        )
        tha, _ = S.sample_member(mat, ma, RMAX, r)
        sa = S.search_mu(mat, tha, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="implicit")
        rules[model] = {
            "mu_bvp_switch_radius_0.25": mr.mu,
            "theta_s_switch_radius": mr.theta_s,
            "mu_bvp_switch_angle_pi/4": ma.mu,
            "rbar_s_switch_angle": ma.rbar_s,
            "mu_search_switch_angle_pi/4": sa.mu,
        }
    res["selection_rules"] = rules
    # diffrax against the explicit loop and the boundary-value solve (neo-Hookean)
    mat = make_material("neo_hookean")
    m = S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius")
    th, _ = S.sample_member(mat, m, RMAX, r)
    d, t_d_cold = _timed(
        lambda mat=mat, th=th: S.search_mu(
            mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="diffrax"
        )
    )
    d2, t_d_warm = _timed(
        lambda mat=mat, th=th: S.search_mu(
            mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="diffrax"
        )
    )
    e = res["models"]["neo_hookean"]
    res["march_comparison_neo_hookean"] = {
        "explicit": {
            "mu": e["mu_search"],
            "warm_s": e["search_warm_s"],
            "cold_s": e["search_cold_s"],
        },
        "diffrax_euler": {"mu": d.mu, "warm_s": t_d_warm, "cold_s": t_d_cold},
        "implicit": {
            "mu": e["mu_search_implicit"],
            "warm_s": e["search_implicit_warm_s"],
            "cold_s": e["search_implicit_cold_s"],
        },
        "bvp": {"mu": e["mu_bvp"], "warm_s": e["bvp_warm_s"], "cold_s": e["bvp_cold_s"]},
    }
    if cli:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [
                sys.executable,
                "-m",
                "dynslip.cli",
                "run",
                str(ROOT / "scenarios" / "paper_neohookean.yaml"),
                "--out",
                str(Path(tmp) / "out"),
            ]
            t = time.perf_counter()
            p = subprocess.run(
                cmd,
                capture_output=True,
                text=True,
                cwd=ROOT,
                env={**os.environ, "MPLBACKEND": "Agg"},
            )
            res["cli_cold_run_s"] = time.perf_counter() - t
            res["cli_returncode"] = p.returncode
    return res


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    print(json.dumps(run(), indent=2))
