"""Members in lockstep (dynslip.physics.driver.batch.simulate_batch) against the same members run
one
after another: the driver's results, and a sweep's member records in ``--mode batched``.

Small on purpose (20 nodes, 2 members, short paths): the batched solve is compiled once per
(shape, B) and the sequential one once per shape.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
import yaml

from dynslip.physics.driver.batch import simulate_batch
from dynslip.physics.driver.simulate import simulate, stack
from dynslip.physics.friction import SlipWeakening
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import (
    BALL_FORCE,
    CLAMP_FORCE,
    ClampForceBelow,
    Duration,
    Protocol,
    Rest,
    Stage,
    ThetaMaxBelow,
)
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.solver.methods import Settings
from numerics import named_solver

NODES = 20
RIM = 2.54
PRE = 1.05
Z0 = 1.02
MODEL = SheetModel(
    make_mesh(NODES, RIM / PRE),
    make_material("gent", jm=50.0),
    Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)),
)
SETTINGS = Settings(solver=named_solver(), save_interval=1.0)
ROOT = Path(__file__).resolve().parents[1]


def kwargs(mu_s, mu_k, settings=SETTINGS):
    return dict(
        # arrays, not floats: members of one batch share the law's compiled structure
        friction=SlipWeakening(**{k: jnp.asarray(v, dtype=float) for k, v in
                                  {"mu_s": mu_s, "mu_k": mu_k, "d_c": 0.02, "eps": 1e-3}.items()}),
        eps=1e-3,
        drag=0.1,
        ball_drag=0.1 * 4 * math.pi,
        pre_stretch=PRE,
        z_sheet=Z0,
        settings=settings,
    )


def protocol(first_stop, push=4.0):
    """Push down at 0.5 R/s for ``push`` s, a stage ended by ``first_stop``, a let-go and a
    release."""
    return Protocol(
        (
            Stage("push_down", Duration(duration=push), clamp_vz=-0.5),
            Stage("check", first_stop),
            Stage("let_go", Duration(duration=2.0), clamp_mode=CLAMP_FORCE),
            Stage(
                "release",
                Duration(duration=2.0),
                clamp_mode=CLAMP_FORCE,
                clamp_force_start=(0.0, 0.0),
                ball_mode=BALL_FORCE,
                ball_force_end=0.0,
            ),
        ),
        clamp_rho0=RIM,
        clamp_z0=Z0,
    )


def assert_same(alone, batched, tol=1e-8):
    assert batched.failed == alone.failed
    assert [(s["name"], s["condition_met"]) for s in batched.stage_end] == [
        (s["name"], s["condition_met"]) for s in alone.stage_end
    ]
    np.testing.assert_allclose(
        [s["t_end"] for s in batched.stage_end], [s["t_end"] for s in alone.stage_end], atol=1e-12
    )
    assert len(batched.frames) == len(alone.frames)
    for fa, fb in zip(alone.frames, batched.frames, strict=True):
        assert fa["stage"] == fb["stage"] and fa["time"] == fb["time"]
        for k in ("rho", "z", "ball_z", "clamp_force", "ball_reaction", "slip_distance"):
            if k in fa:
                np.testing.assert_allclose(fb[k], fa[k], atol=tol, rtol=0, err_msg=k)
    for k in ("steps", "accepted", "rejected", "segments", "newton_iterations"):
        assert batched.stats[k] == alone.stats[k], k
    assert batched.e0 == pytest.approx(alone.e0, abs=tol)


def test_members_in_different_stages_at_the_same_tick():
    """Member 0's condition stage ends at its first frame (|clamp force| < a huge threshold),
    member 1's runs its whole duration (a rest rule that does not hold), and member 2 pushes
    longer: in the same ticks the members are in different stages, each with its own loads,
    stop rule and time; each result is what it is alone."""
    prots = [
        protocol(ClampForceBelow(force=1e6, duration=3.0)),
        protocol(Rest(rate=1e-12, hold=1.0, duration=3.0)),
        protocol(ThetaMaxBelow(angle=1e-3, duration=2.0), push=6.0),
    ]
    kws = [kwargs(1.5, 1.25), kwargs(1.8, 1.5), kwargs(1.6, 1.3)]
    batched = simulate_batch([MODEL] * 3, prots, kws)
    alone = [simulate(MODEL, p, **kw) for p, kw in zip(prots, kws, strict=True)]
    for a, b in zip(alone, batched, strict=True):
        assert_same(a, b)
    check = [next(s for s in r.stage_end if s["name"] == "check") for r in batched]
    assert check[0]["condition_met"] and check[0]["t_end"] == pytest.approx(5.0)  # one segment
    assert not check[1]["condition_met"] and check[1]["t_end"] == pytest.approx(7.0)  # duration
    assert [s["name"] for s in batched[0].stage_end] == ["push_down", "check", "let_go", "release"]
    # at t = 5 s member 0 is letting go, member 1 is in its check stage, member 2 still pushes
    stage_at = [{f["time"]: f["stage"] for f in r.frames}[6.0] for r in batched]
    assert stage_at == [2, 1, 0]
    # finished members waited (zero-length segments): their segment counts are their own
    assert batched[0].stats["segments"] < batched[2].stats["segments"]


def test_members_that_cannot_share_a_compiled_solve_are_refused():
    kws = [kwargs(1.5, 1.25), kwargs(1.5, 1.25, Settings(solver=named_solver(max_increment=10.0)))]
    with pytest.raises(ValueError, match="different compiled solves"):
        simulate_batch([MODEL] * 2, [protocol(Duration(duration=1.0))] * 2, kws)
    with pytest.raises(ValueError, match="non-array part"):
        stack([make_material("gent", jm=50.0), make_material("gent", jm=40.0)])


SHORT = {  # the let-go path of scenarios/method2_let_go.yaml, shortened (20 nodes)
    "numerics.nodes": 20,
    "physics.stages.hold.duration_s": 4.0,
    "physics.stages.let_go.duration_s": 6.0,
    "physics.stages.release.duration_s": 6.0,
    "physics.stages.rest.until.hold_s": 4.0,
    "physics.stages.rest.duration_s": 40.0,
}
MEMBERS = [
    {"physics.friction.mu_s": 1.5, "physics.friction.mu_k": 1.25},
    {"physics.friction.mu_s": 0.8, "physics.friction.mu_k": 0.66},
]


def _sweep_file(tmp: Path, members: list[dict]) -> Path:
    sweep = tmp / "study.yaml"
    sweep.write_text(
        yaml.safe_dump(
            {
                "base": str(ROOT / "scenarios" / "method2_let_go.yaml"),
                "overrides": SHORT,
                "list": members,
            }
        )
    )
    return sweep


def _records(out: Path) -> dict:
    recs = [json.loads(p.read_text()) for p in sorted((out / "members").glob("*.json"))]
    return {r["fingerprint"]: r for r in recs}


def _assert_same_records(rs: dict, rb: dict) -> list:
    """Member records of ``rb`` equal those of ``rs`` (same fingerprints): outcome, end state,
    solver counts and stages; returns the trapped outcomes."""
    outcomes = []
    for k, a in rs.items():
        b = rb[k]
        assert a["status"] == b["status"] == "ok"
        sa, sb = a["summary"], b["summary"]
        assert sa["trapped"] == sb["trapped"]
        outcomes.append(sa["trapped"])
        for name in (
            "theta_max",
            "rbar_max",
            "ball_z_end",
            "ball_reaction_end",
            "clamp_force_end",
            "mu_mobilised_max",
        ):
            assert sb[name] == pytest.approx(sa[name], abs=1e-8, nan_ok=True), name
        for name in ("steps", "accepted", "rejected", "segments", "newton_iterations"):
            assert sb["solver"][name] == sa["solver"][name], name
        assert [s["name"] for s in sb["stages"]] == [s["name"] for s in sa["stages"]]
    return outcomes


@pytest.fixture(scope="module")
def sequential(tmp_path_factory):
    """The two members of ``MEMBERS`` run one after another: ``(summary, records)``."""
    from dynslip.app.sweep import run_sweep

    tmp = tmp_path_factory.mktemp("seq")
    seq = run_sweep(_sweep_file(tmp, MEMBERS), out=tmp / "seq", mode="sequential", plot=False)
    return seq, _records(tmp / "seq")


@pytest.mark.slow  # 14 s; the quick loop compares batched and sequential sweeps in
# test_sweep.py::test_sequential_batched_and_dask_give_identical_datasets
def test_batched_sweep_equals_sequential(tmp_path, sequential, monkeypatch):
    """``--mode batched`` on forming members differing in mu_s, mu_k, in this process: the same
    outcome, end state and solver counts as ``sequential``, member by member; the summary
    says what ran."""
    from dynslip.app import sweep as sweep_app
    from dynslip.app import sweep_runners

    monkeypatch.setattr(sweep_runners, "BATCH_WORKERS", 1)
    monkeypatch.setattr(sweep_runners, "BATCH_SIZE", None)  # both members in one lockstep batch
    seq, rs = sequential
    bat = sweep_app.run_sweep(
        _sweep_file(tmp_path, MEMBERS), out=tmp_path / "bat", mode="batched", plot=False
    )
    assert bat["batched"].startswith("batched: lockstep batches"), bat["batched"]
    assert "worker processes" not in bat["batched"] and "per batch" not in bat["batched"]
    assert seq["n_ok"] == bat["n_ok"] == 2
    rb = _records(tmp_path / "bat")
    assert rs.keys() == rb.keys()
    print("trapped:", _assert_same_records(rs, rb))


@pytest.mark.slow
def test_batched_sweep_in_two_worker_processes(tmp_path, sequential, monkeypatch):
    """The default batched runner on 2 cores: 4 forming members split over two spawned worker
    processes (2 each, one after another in each worker: the CPU default BATCH_SIZE = 1);
    every member ok, and the two members also run sequentially (in this process) have the
    same records."""
    from dynslip.app import sweep as sweep_app
    from dynslip.app import sweep_runners

    monkeypatch.setattr(sweep_runners, "BATCH_WORKERS", 2)
    _, rs = sequential
    more = MEMBERS + [
        {"physics.friction.mu_s": 1.2, "physics.friction.mu_k": 1.0},
        {"physics.friction.mu_s": 1.0, "physics.friction.mu_k": 0.83},
    ]
    bat = sweep_app.run_sweep(
        _sweep_file(tmp_path, more), out=tmp_path / "bat", mode="batched", plot=False
    )
    assert (
        "2+2 forming members" in bat["batched"] and "on up to 2 worker processes" in bat["batched"]
    ), bat["batched"]
    assert "at most 1 per batch" in bat["batched"], bat["batched"]
    assert bat["n_ok"] == 4
    rb = _records(tmp_path / "bat")
    assert set(rs) < set(rb) and len(rb) == 4
    _assert_same_records(rs, {k: rb[k] for k in rs})
