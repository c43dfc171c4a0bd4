"""Observables per held body on a run (issue 21 item 6): the sheet pulled over a post's rounded
edge (mu 0.15) and a torus ring (mu 0.6), then held (the setup of test_bodies_friction.py,
N = 32): while it is drawn outward and down over both, the nodes slipping on each body slip
toward increasing s; held where the pull left it, the sheet rests at the friction limit and
creeps inside the smoothing's band (flagged slipping, as the ball's state is: the smoothed
law's criterion); eased off a little, the ring unloads from its outer side (slip back, stick,
slip forward along s). The extent in s is that of the nodes in contact. (At rest with no
tangential load the nodes are stuck: tests/test_body_observables.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynslip.physics.bodies.observe import SLIP_BACK, SLIP_ON, STUCK
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.protocols import Duration, Protocol, Stage
from dynslip.physics.solver.methods import Settings
from numerics import named_solver
from test_bodies_friction import (
    EPS,
    FRICTIONAL,
    PRE,
    RIM,
    SPEED,
    TAU,
    _coulomb,
    _held_state,
    _run,
)

# the quick loop (-m 'not slow') leaves these out: runs over held bodies (N = 24)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def frames():
    return _run(FRICTIONAL, hold=8.0).frames


def test_drawn_over_both_bodies_the_slipping_nodes_slip_toward_increasing_s(frames):
    push_end = [f for f in frames if f["stage"] == 0][-1]
    st, contact = push_end["body_state"], push_end["body_contact"].astype(bool)
    for k in range(2):
        assert contact[k].sum() >= 3, k
        slipping = contact[k] & (st[k] != STUCK)
        assert slipping.sum() >= 2, (k, st[k])
        assert set(st[k][slipping]) == {SLIP_ON}


def test_held_at_the_friction_limit_the_sheet_creeps_and_reads_slipping(frames):
    end = frames[-1]
    contact = end["body_contact"].astype(bool)
    for k in range(2):
        assert contact[k].sum() >= 3, k
        assert set(end["body_state"][k][contact[k]]) == {SLIP_ON}


@pytest.fixture(scope="module")
def eased():
    """Pulled as in ``frames``, then the clamp moved back up by 0.03 R, then held."""
    stages = (
        Stage("push", Duration(duration=1.5 / SPEED), clamp_vz=-SPEED),
        Stage("ease", Duration(duration=0.03 / SPEED), clamp_vz=SPEED),
        Stage("hold", Duration(duration=2.0)),
    )
    res = simulate(FRICTIONAL, Protocol(stages, clamp_rho0=RIM, clamp_z0=0.0, ball_z0=6.0),
                   friction=_coulomb(0.5), eps=EPS, drag=TAU, ball_drag=TAU * 4 * math.pi,
                   pre_stretch=PRE, z_sheet=0.0,
                   settings=Settings(solver=named_solver(), save_interval=0.5))
    assert res.failed is None, res.failed
    return res.frames


def test_eased_off_the_ring_unloads_from_its_outer_side(eased):
    """After the ease, the ring (mu 0.6) holds the sheet as a capstan unloaded from outside:
    along s the nodes slip forward (still at the limit, the inner side), stick, then slip back
    (the outer side, where the pull fell); at least one stuck. Stuck exactly where the return
    map's slip force is zero (recomputed from the frame)."""
    end = eased[-1]
    c = end["body_contact"].astype(bool)[1]
    st = end["body_state"][1][c]
    order = np.argsort(end["body_s"][1][c])
    rank = {SLIP_ON: 0, STUCK: 1, SLIP_BACK: 2}
    seq = [rank[int(v)] for v in st[order]]
    assert seq == sorted(seq) and 1 in seq, st[order]
    assert seq[-1] != 0  # the outermost node does not slip forward once the pull fell
    _, _, s, _, _ = _held_state(FRICTIONAL, end)
    np.testing.assert_array_equal(st == STUCK, s[1][c] == 0.0)


def test_extent_in_s_is_that_of_the_nodes_in_contact(frames):
    for f in (frames[len(frames) // 2], frames[-1]):
        c = f["body_contact"].astype(bool)
        for k in range(2):
            s = f["body_s"][k][c[k]]
            assert f["body_n_contact"][k] == c[k].sum()
            np.testing.assert_allclose([f["body_s_min"][k], f["body_s_max"][k]],
                                       [s.min(), s.max()], rtol=0, atol=0)
