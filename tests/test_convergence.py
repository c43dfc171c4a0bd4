"""Richardson extrapolation of the critical mu (dynslip.analysis.convergence)."""

import math

import pytest

from dynslip.analysis.convergence import critical_edge, richardson


@pytest.mark.parametrize("p", [1.0, 2.0, 1.37])
def test_richardson_recovers_order_and_limit(p):
    ns = [25, 50, 100]
    vals = [0.9 + 3.0 * n**-p for n in ns]
    r = richardson(ns, vals, [0.001] * 3)
    assert r["extrapolable"]
    assert abs(r["order"] - p) < 1e-10
    assert abs(r["value"] - 0.9) < 1e-10
    assert abs(r["err"] - (abs(r["value"] - vals[-1]) + 0.001)) < 1e-12


def test_non_monotone_or_growing_changes_are_not_extrapolated():
    assert not richardson([50, 100, 200], [1.2, 1.3, 1.25])["extrapolable"]
    assert not richardson([50, 100, 200], [1.2, 1.21, 1.25])["extrapolable"]  # changes grow
    assert not richardson([50, 100, 300], [1.2, 1.3, 1.32])["extrapolable"]  # ratios differ


def test_converged_means_two_refinements_within_tol():
    assert richardson([50, 100, 200], [1.25, 1.262, 1.266])["converged"]
    assert not richardson([50, 100, 200], [1.20, 1.25, 1.26])["converged"]


def test_critical_edge_is_the_lowest_window_lower_edge():
    detail = [
        {
            "lo": {"value": 1.6, "err": 0.01, "open": False, "unresolved": False},
            "hi": {"value": 2.0, "err": 0.01},
        },
        {
            "lo": {"value": 1.25, "err": 0.005, "open": False, "unresolved": False},
            "hi": {"value": 1.4, "err": 0.01},
        },
    ]
    assert critical_edge(detail)["value"] == 1.25
    assert critical_edge([]) is None
    assert math.isclose(critical_edge(detail)["err"], 0.005)


def test_window_nodes_writes_critical_mu_per_mesh_and_extrapolates(tmp_path):
    """dynslip window --nodes on a stand-in path whose critical mu is 1.3 - 4/N: the
    search finds it per N within tol and the extrapolation recovers 1.3 with order 1."""
    import json

    import yaml

    from dynslip.app.window import run_window_nodes
    from test_sweep import fake_validate

    def member(data, out_dir, console=None):
        s = fake_validate(data)
        n = int(data["numerics"]["nodes"])
        return {"trapped": bool(s.physics.friction.mu > 1.3 - 4.0 / n)}

    (tmp_path / "s.yaml").write_text(
        yaml.safe_dump({"kind": "fake", "physics": {"protocol": {"depth": 4.0}}})
    )
    res = run_window_nodes(tmp_path / "s.yaml", [25, 50, 100], lo=0.5, hi=2.0, coarse=7, tol=1e-4,
                           out=tmp_path / "w", member_fn=member, validate_fn=fake_validate)
    for n in (25, 50, 100):
        c = res["critical_mu"][str(n)]
        assert abs(c["value"] - (1.3 - 4.0 / n)) <= c["err"] + 1e-12
    ex = res["extrapolation"]
    assert ex["extrapolable"] and abs(ex["order"] - 1.0) < 0.02 and abs(ex["value"] - 1.3) < 2e-3
    assert (
        json.loads((tmp_path / "w" / "window.json").read_text())["critical_mu"]
        == res["critical_mu"]
    )
    assert (tmp_path / "w" / "critical_mu.png").stat().st_size > 0


def test_window_nodes_goes_on_past_a_mesh_that_cannot_answer(tmp_path):
    """At N = 25 every run of the stand-in path has no verdict (the tube's rim unresolved, as
    method 2 at N = 50): the study reports that mesh as unresolved with its reason and goes
    on; the finer meshes find their critical mu (1.3 - 4/N) and extrapolate without it. With
    every mesh unanswered the study fails (ComputationError, exit 3), naming the reason."""
    import json

    import pytest
    import yaml

    from dynslip.app.window import run_window_nodes
    from dynslip.errors import ComputationError
    from test_sweep import fake_validate

    rim = "the mesh does not resolve the tube wall (a chord 0.31 of its radius deep)"

    def member(data, out_dir, console=None):
        s = fake_validate(data)
        n = int(data["numerics"]["nodes"])
        if n < 40:
            return {"trapped": None, "trapped_unknown_reasons": [rim]}
        return {"trapped": bool(s.physics.friction.mu > 1.3 - 4.0 / n)}

    (tmp_path / "s.yaml").write_text(
        yaml.safe_dump({"kind": "fake", "physics": {"protocol": {"depth": 4.0}}})
    )
    kw = dict(lo=0.5, hi=2.0, coarse=7, tol=1e-4, member_fn=member, validate_fn=fake_validate)
    res = run_window_nodes(tmp_path / "s.yaml", [25, 50, 100, 200], out=tmp_path / "w", **kw)
    assert res["answered_nodes"] == [50, 100, 200] and res["critical_mu"]["25"] is None
    u = res["unresolved"]["25"]
    # the 7 coarse points and the quarter points tried beside each failed one
    assert u["answered"] is False and u["runs_failed"] >= 7
    assert u["reasons"] == [{"reason": f"trapped unknown: {rim}", "runs": u["runs_failed"]}]
    for n in (50, 100, 200):
        c = res["critical_mu"][str(n)]
        assert abs(c["value"] - (1.3 - 4.0 / n)) <= c["err"] + 1e-12
    ex = res["extrapolation"]
    assert ex["extrapolable"] and abs(ex["order"] - 1.0) < 0.02 and abs(ex["value"] - 1.3) < 2e-3
    assert "no answer at N = 25" in res["refinement_check"]["says"]
    assert json.loads((tmp_path / "w" / "window.json").read_text())["unresolved"]["25"] == u
    with pytest.raises(ComputationError, match="no mesh size of 25, 30 answered.*tube wall"):
        run_window_nodes(tmp_path / "s.yaml", [25, 30], out=tmp_path / "w2", **kw)
