"""The trapping-window search: coarse scan + bisection of every edge (dynslip.app.window)."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynslip.analysis.windows import find_windows
from dynslip.errors import ComputationError, InputError
from dynslip.schema.sweep import friction_field, member_at

TWO = [(0.31, 0.47), (1.23, 1.61)]


def two_windows(mu: float) -> bool:
    return any(a < mu < b for a, b in TWO)


@pytest.mark.parametrize("tol", [1e-2, 1e-4])
def test_two_windows_found_to_tolerance(tol):
    res = find_windows(two_windows, 0.0, 2.5, coarse=21, tol=tol)  # step 0.125 < widths
    assert len(res.windows) == 2
    for w, (a, b) in zip(res.windows, TWO, strict=True):
        assert abs(w.lo.value - a) <= tol and abs(w.hi.value - b) <= tol
        # the stated uncertainty covers the true edge and is at most tol / 2
        assert abs(w.lo.value - a) <= w.lo.err + 1e-15 and w.lo.err <= tol / 2
        assert abs(w.hi.value - b) <= w.hi.err + 1e-15 and w.hi.err <= tol / 2
        assert not (w.lo.open or w.hi.open or w.lo.unresolved or w.hi.unresolved)
    # cost: the coarse scan plus about log2(step / tol) runs per edge
    step = 2.5 / 20
    per_edge = -(-__import__("math").log2(step / tol) // 1)
    assert len(res.evaluations) <= 21 + 4 * (per_edge + 1)


def test_non_monotone_trapping_like_the_prototype():
    # trapped at low mu only, as in the prototype (0.8 trapped, 1.0..2.5 not)
    res = find_windows(lambda m: 0.65 <= m <= 0.9, 0.2, 2.5, coarse=12, tol=0.01)
    assert [[round(v, 2) for v in w.as_list()] for w in res.windows] == [[0.65, 0.9]]


def test_window_touching_the_range_is_open():
    res = find_windows(lambda m: m < 0.5 or m > 1.8, 0.0, 2.0, coarse=9, tol=1e-3)
    assert len(res.windows) == 2
    first, last = res.windows
    assert first.lo.open and first.lo.value == 0.0 and abs(first.hi.value - 0.5) <= 1e-3
    assert last.hi.open and last.hi.value == 2.0 and abs(last.lo.value - 1.8) <= 1e-3


def test_never_trapped_gives_no_window():
    res = find_windows(lambda m: False, 0.0, 1.0, coarse=5, tol=0.01)
    assert res.windows == [] and len(res.evaluations) == 5


def test_failed_points_are_listed_never_read_as_not_trapped():
    bad = {0.5}

    def pred(mu):
        if mu in bad:
            raise ComputationError("solver diverged")
        return 0.4 < mu < 0.9

    res = find_windows(pred, 0.0, 2.0, coarse=5, tol=1e-3)  # scan 0, .5, 1, 1.5, 2
    assert res.failed == [0.5] and "diverged" in res.errors[0.5]
    # the window is still found: the failed coarse point is skipped, its bracket bisected
    (w,) = res.windows
    assert abs(w.lo.value - 0.4) <= 1e-3 and abs(w.hi.value - 0.9) <= 1e-3
    d = res.to_dict()
    assert d["failed"] == [[0.5, "solver diverged"]]
    json.dumps(d)


def test_an_edge_blocked_by_failures_is_flagged_unresolved():
    # every run between 0.55 and 0.65 fails: the edge at 0.6 cannot be bisected below that
    res = find_windows(lambda m: None if 0.55 < m < 0.65 else m > 0.6, 0.0, 1.0, coarse=3, tol=1e-3)
    (w,) = res.windows
    assert w.lo.unresolved and w.lo.err > 1e-3 / 2
    assert w.lo.value - w.lo.err <= 0.6 <= w.lo.value + w.lo.err
    assert res.failed


@pytest.mark.parametrize("edge", [0.63, 0.4117])
def test_a_window_bounded_by_failed_runs_is_bisected_against_them_and_flagged(edge):
    """Below the edge every run fails (the mesh does not resolve the contact), above it the
    ball is trapped up to 0.8, and above 0.8 the runs fail again: each edge is found to tol
    on "trapped" and flagged failed_side (a bound on where the model answers), not open."""
    res = find_windows(lambda m: (edge < m < 0.8) or None, 0.0, 1.0, coarse=6, tol=1e-3)
    (w,) = res.windows
    for e, true in ((w.lo, edge), (w.hi, 0.8)):
        assert e.failed_side and not e.open and not e.unresolved
        assert abs(e.value - true) <= e.err <= 0.5e-3
    # a not-trapped run on the way makes it an ordinary edge
    res = find_windows(
        lambda m: True if m > edge else (False if m > edge - 0.01 else None),
        0.0,
        1.0,
        coarse=6,
        tol=1e-3,
    )
    assert not res.windows[0].lo.failed_side and abs(res.windows[0].lo.value - edge) <= 1e-3


@settings(max_examples=40, deadline=None)
@given(
    a=st.floats(0.0, 3.0),
    widths=st.lists(st.floats(0.25, 0.6), min_size=1, max_size=3),
    gaps=st.lists(st.floats(0.25, 0.6), min_size=3, max_size=3),
)
def test_every_window_wider_than_the_coarse_step_is_found(a, widths, gaps):
    lo, hi, coarse, tol = 0.0, 6.0, 31, 1e-3  # coarse step 0.2 < every width and gap
    edges, x = [], a + gaps[0]
    for w, g in zip(widths, gaps[1:] + [0.3], strict=False):
        edges.append((x, x + w))
        x += w + g
    edges = [(p, q) for p, q in edges if q < hi - 0.01]
    res = find_windows(lambda m: any(p < m < q for p, q in edges), lo, hi, coarse=coarse, tol=tol)
    assert len(res.windows) == len(edges)
    for w, (p, q) in zip(res.windows, edges, strict=True):
        assert abs(w.lo.value - p) <= tol and abs(w.hi.value - q) <= tol


@pytest.mark.parametrize(
    ("lo", "hi", "coarse", "tol"),
    [(1.0, 1.0, 5, 0.1), (2.0, 1.0, 5, 0.1), (0.0, 1.0, 1, 0.1), (0.0, 1.0, 5, 0.0)],
)
def test_bad_ranges_are_input_errors(lo, hi, coarse, tol):
    with pytest.raises(InputError):
        find_windows(two_windows, lo, hi, coarse=coarse, tol=tol)


def test_mu_s_is_searched_with_mu_k_over_mu_s_fixed():
    resolved = {"physics": {"friction": {"law": "slip", "mu_s": 1.0, "mu_k": 0.8, "d_c": 0.1}}}
    field, tied = friction_field(resolved)
    assert (field, tied) == ("physics.friction.mu_s", ["physics.friction.mu_k"])
    m = member_at({"physics": {"friction": {"mu_s": 1.0}}}, resolved, field, tied, 0.5)
    assert m["physics"]["friction"] == {"mu_s": 0.5, "mu_k": pytest.approx(0.4)}
    ideal = {"physics": {"friction": {"law": "ideal", "mu": 0.9}}}
    assert friction_field(ideal) == ("physics.friction.mu", [])
    with pytest.raises(InputError, match="physics.friction.nope"):
        friction_field(ideal, "physics.friction.nope")


def test_critical_mu_of_a_weakening_law_reports_the_tied_mu_k(tmp_path):
    """The slip-weakening law's window is searched in mu_s with mu_k / mu_s fixed; window.json
    gives the critical mu_s and the tied mu_k at it (mu_c = 1.25 here, mu_k/mu_s = 0.8)."""
    import io

    import yaml
    from rich.console import Console

    from dynslip.app.window import run_window

    def member(data, out_dir, console=None):
        fr = data["physics"]["friction"]
        assert fr["mu_k"] == pytest.approx(0.8 * fr["mu_s"])
        return {"trapped": fr["mu_s"] > 1.25}

    s = tmp_path / "s.yaml"
    s.write_text(yaml.safe_dump({"kind": "forming", "physics": {"friction": {
        "law": "slip_weakening", "mu_s": 1.5, "mu_k": 1.2, "d_c_mm": 0.4}}}))
    res = run_window(s, lo=1.0, hi=2.0, coarse=5, tol=1e-3, out=tmp_path / "w", member_fn=member,
                     console=Console(file=io.StringIO()))
    mu_c = res["critical_mu"]["value"]
    assert abs(mu_c - 1.25) <= 1e-3
    assert res["critical_mu_tied"] == {"physics.friction.mu_k": pytest.approx(0.8 * mu_c)}
    assert (
        json.loads((tmp_path / "w" / "window.json").read_text())["critical_mu_tied"]
        == res["critical_mu_tied"]
    )
