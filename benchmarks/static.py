"""Benchmark of the static model: ``run() -> dict`` (imported by benchmarks/run.py).

Measures in one process, at the paper's grid (N = 100, rbar_max = 0.9, theta_max = 1.8):

- the selected fully mobilised member (boundary-value solve) per model, cold (compilation
  included) and warm;
- the paper's mu search from that member per model (explicit march), cold and warm, and the
  three models together warm;
- the same search with the diffrax march (Euler at the same step) for neo-Hookean, against
  the explicit loop and the boundary-value solve, with the mu each returns (equal accuracy:
  the same F_v tolerance and relative mu tolerance 1e-4);
- a cold ``dynslip run scenarios/paper_neohookean.yaml`` in a fresh process.

Run alone: ``python benchmarks/static.py``.
"""

from __future__ import annotations

import json
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
    from dynslip.physics import sphere as S
    from dynslip.physics.materials import make_material

    r = S.grid(N, RMAX)
    h = float(r[1])
    fv_tol = 1e-3
    res: dict = {"n_nodes": N, "models": {}}
    search_warm_total = 0.0
    for model in ("hookean", "neo_hookean", "gent"):
        mat = make_material(model, jm=50.0)
        m, t_bvp_cold = _timed(lambda: S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius"))
        _, t_bvp_warm = _timed(lambda: S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius"))
        (th, _), t_sample = _timed(lambda: S.sample_member(mat, m, RMAX, r))
        sr, t_cold = _timed(lambda: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol))
        sr2, t_warm = _timed(lambda: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol))
        search_warm_total += t_warm
        res["models"][model] = {
            "mu_bvp": m.mu, "mu_search": sr.mu, "mu_search_vs_bvp": sr.mu / m.mu - 1,
            "bvp_cold_s": t_bvp_cold, "bvp_warm_s": t_bvp_warm, "sample_s": t_sample,
            "search_cold_s": t_cold, "search_warm_s": t_warm, "search_evaluations": sr.evaluations,
        }
    res["search_warm_three_models_s"] = search_warm_total
    # diffrax against the explicit loop and the boundary-value solve (neo-Hookean)
    mat = make_material("neo_hookean")
    m = S.solve_member(mat, SEL, TMAX, RMAX, GUESS, by="switch_radius")
    th, _ = S.sample_member(mat, m, RMAX, r)
    d, t_d_cold = _timed(lambda: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="diffrax"))
    d2, t_d_warm = _timed(lambda: S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="diffrax"))
    e = res["models"]["neo_hookean"]
    res["march_comparison_neo_hookean"] = {
        "explicit": {"mu": e["mu_search"], "warm_s": e["search_warm_s"], "cold_s": e["search_cold_s"]},
        "diffrax_euler": {"mu": d.mu, "warm_s": t_d_warm, "cold_s": t_d_cold},
        "bvp": {"mu": e["mu_bvp"], "warm_s": e["bvp_warm_s"], "cold_s": e["bvp_cold_s"]},
    }
    if cli:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [sys.executable, "-m", "dynslip.cli", "run", str(ROOT / "scenarios" / "paper_neohookean.yaml"),
                   "--out", str(Path(tmp) / "out")]
            t = time.perf_counter()
            p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env={**os.environ, "MPLBACKEND": "Agg"})
            res["cli_cold_run_s"] = time.perf_counter() - t
            res["cli_returncode"] = p.returncode
    return res


if __name__ == "__main__":
    print(json.dumps(run(), indent=2))
