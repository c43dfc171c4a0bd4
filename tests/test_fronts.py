"""Stick-front tracking on synthetic state fields whose fronts are known exactly.

Fields are written one frame per string, one character per node from the pole outward:
``.`` free, ``S`` stuck, ``p`` slipping toward the pole, ``e`` slipping toward the equator.
"""

import json

import numpy as np
import pytest
import xarray as xr

from dynslip.analysis.front_summary import fronts_dataset, stage_summary
from dynslip.analysis.fronts import (
    BIRTH_EVENTS,
    DEATH_EVENTS,
    fronts_in_frame,
    motion_state,
    track_fronts,
)
from dynslip.app.fronts import run_fronts, summary_lines
from dynslip.data.files import check_units, write_netcdf
from dynslip.errors import InputError
from helpers import synthetic_trajectory

CODES = {".": 0, "S": 1, "p": 2, "e": 3}


def field(*frames: str) -> np.ndarray:
    assert len({len(f) for f in frames}) == 1
    return np.array([[CODES[c] for c in f] for f in frames], dtype=np.int8)


def summary(tracks):
    """(frames, nodes, stuck_side, birth, death) of each track, for exact comparison."""
    return [(t.frames, t.nodes, t.stuck_side, t.birth_event, t.death_event) for t in tracks]


def test_single_frame_fronts_and_what_is_not_a_front():
    # stuck|slip fronts only; p|e boundary and contact edges are not fronts
    (f1, f2) = fronts_in_frame(field("SSppeeSS..SS")[0])
    assert (f1.node, f1.stuck_side) == (1, 1)
    assert (f2.node, f2.stuck_side) == (5, 2)
    assert fronts_in_frame(field("SSSS....eeee")[0]) == []  # separated by free nodes
    assert fronts_in_frame(field("pppeeeeS.SSS")[0])[0].node == 6


@pytest.mark.parametrize("step", [1, 2, 3])
def test_front_moving_at_known_speed_outward(step):
    nr, nt, dt = 24, 6, 0.25
    frames = ["S" * (2 + step * k) + "e" * (nr - 4 - 2 - step * k) + "...." for k in range(nt)]
    state = field(*frames)
    tracks = track_fronts(state)
    assert summary(tracks) == [
        (list(range(nt)), [1 + step * k for k in range(nt)], 1, "run_start", "run_end")
    ]
    rbar = np.linspace(0.0, 2.3, nr)
    h = rbar[1] - rbar[0]
    ds = synthetic_trajectory(state, time=dt * np.arange(nt), rbar=rbar, theta_of_rbar=0.5)
    fr = fronts_dataset(ds)
    expected = 0.5 * (rbar[1 + step * np.arange(nt)] + rbar[2 + step * np.arange(nt)])
    np.testing.assert_allclose(fr.front_rbar.values[0], expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(fr.front_theta.values[0], 0.5 * expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(fr.front_rbar_speed.values[0], step * h / dt, rtol=1e-12)
    np.testing.assert_allclose(fr.front_theta_speed.values[0], 0.5 * step * h / dt, rtol=1e-12)
    assert set(fr.front_slip_state.values[0]) == {3}
    assert fr.attrs["max_front_step_nodes"] == step and fr.attrs["unresolved_events"] == 0


def test_slip_spreading_from_the_contact_edge_toward_the_pole():
    state = field(
        "SSSSSSSS....",
        "SSSSSSSp....",
        "SSSSSSpp....",
        "SSSSSppp....",
        "SSSSpppp....",
    )
    assert summary(track_fronts(state)) == [
        ([1, 2, 3, 4], [6, 5, 4, 3], 1, "nucleated_at_contact_edge", "run_end")
    ]


def test_nucleation_inside_a_domain_and_merging():
    # a slipping patch nucleates in the stuck region, grows, then shrinks and vanishes
    state = field(
        "SSSSSSSSSS..",
        "SSSSeSSSSS..",
        "SSSeeeSSSS..",
        "SSSSeeSSSS..",
        "SSSSSSSSSS..",
    )
    assert summary(track_fronts(state)) == [
        ([1, 2, 3], [3, 2, 3], 1, "nucleated", "merged"),
        ([1, 2, 3], [4, 5, 5], 2, "nucleated", "merged"),
    ]


def test_two_slipping_domains_merge_when_the_stuck_island_vanishes():
    state = field(
        "SSeeeSSeeee.",
        "SSeeeeSeeee.",
        "SSeeeeeeeee.",
    )
    assert summary(track_fronts(state)) == [
        ([0, 1, 2], [1, 1, 1], 1, "run_start", "run_end"),
        ([0, 1], [4, 5], 2, "run_start", "merged"),
        ([0, 1], [6, 6], 1, "run_start", "merged"),
    ]


def test_front_reaching_the_contact_edge_and_the_pole():
    edge = field(
        "SSSSSSeee...",
        "SSSSSSSee...",
        "SSSSSSSSe...",
        "SSSSSSSSS...",
    )
    assert summary(track_fronts(edge)) == [
        ([0, 1, 2], [5, 6, 7], 1, "run_start", "reached_contact_edge")
    ]
    pole = field(
        "SSpppppp....",
        "Sppppppp....",
        "pppppppp....",
    )
    assert summary(track_fronts(pole)) == [([0, 1], [1, 0], 1, "run_start", "reached_pole")]


def test_a_wide_domain_switching_at_once_is_named_so():
    # all of the slipping sheet comes to rest between two frames, then starts again
    state = field(
        "SSeeeeee....",
        "SSSSSSSS....",
        "SSeeeeee....",
    )
    assert summary(track_fronts(state)) == [
        ([0], [1], 1, "run_start", "domain_switched"),
        ([2], [1], 1, "domain_switched", "run_end"),
    ]
    # a two-node domain is within reach + 1: it reaches the contact edge
    edge = field("SSSSSSee....", "SSSSSSSS....")
    assert summary(track_fronts(edge)) == [([0], [5], 1, "run_start", "reached_contact_edge")]


def test_contact_lost_and_gained():
    lost = field(
        "SSSSSeee....",
        "SSSSS.......",
    )
    assert summary(track_fronts(lost)) == [([0], [4], 1, "run_start", "contact_lost")]
    gained = field(
        "SSSSS.......",
        "SSSSSee.....",
        "SSSSSeee....",
    )
    assert summary(track_fronts(gained)) == [([1, 2], [4, 4], 1, "contact_gained", "run_end")]


def test_pole_nucleation_and_fast_jump_linked_by_domain_overlap():
    state = field(
        "SSSSSSSSS...",
        "eSSSSSSSS...",
        "eeeeeeeSS...",  # the front jumps six nodes in one frame: still the same track
    )
    assert summary(track_fronts(state)) == [([1, 2], [0, 6], 2, "nucleated_at_pole", "run_end")]


def test_stuck_band_travelling_inward_through_slipping_sheet():
    # slip back toward the pole starts at the contact edge and spreads inward, behind a
    # one-node stuck band (the pattern of a whole-sheet run while the clamp is raised)
    state = field(
        "SeeeeeeS....",
        "SeeeeeSp....",
        "SeeeeSpp....",
        "SeeeSppp....",
        "SeeSpppp....",
        "SeSppppp....",
        "SSpppppp....",
        "Spppppp.....",
    )
    assert summary(track_fronts(state)) == [
        ([0, 1, 2, 3, 4, 5], [0] * 6, 1, "run_start", "merged"),
        ([0, 1, 2, 3, 4, 5], [6, 5, 4, 3, 2, 1], 2, "run_start", "merged"),
        ([1, 2, 3, 4, 5, 6, 7], [6, 5, 4, 3, 2, 1, 0], 1, "nucleated_at_contact_edge", "run_end"),
    ]
    # without reach the band is a new domain every frame: fronts die and are reborn
    assert len(track_fronts(state, reach=0)) > 3


def test_every_variable_has_units_and_long_name_and_round_trips(tmp_path):
    state = field("SSSeeee...", "SSSSeee...", "SSSSSee...", "SSSSSSS...")
    ds = synthetic_trajectory(
        state, stage=[0, 0, 1, 1], rbar=np.linspace(0, 1.8, 10), theta_of_rbar=0.5
    )
    fr = fronts_dataset(ds)
    check_units(fr)
    for name, var in {**fr.coords, **fr.data_vars}.items():
        assert var.attrs.get("long_name"), name
    assert fr.attrs["kind"] == "fronts" and fr.attrs["format_version"] == "1"
    flags = fr.death_event.attrs["flag_meanings"].split()
    assert flags[int(fr.death_event.values[0])] == "reached_contact_edge"
    assert tuple(flags) == DEATH_EVENTS
    assert tuple(fr.birth_event.attrs["flag_meanings"].split()) == BIRTH_EVENTS
    traj = write_netcdf(ds, tmp_path / "run" / "trajectory.nc")
    nc, png, summ = run_fronts(traj, tmp_path / "fronts")
    assert [nc.name, png.name, summ.name] == ["fronts.nc", "fronts.png", "fronts_summary.json"]
    back = xr.open_dataset(nc)
    xr.testing.assert_allclose(back.front_rbar.load(), fr.front_rbar)
    assert png.stat().st_size > 0
    assert json.loads(summ.read_text())["stages"][1]["name"] == "release"


def _release(order: str) -> xr.Dataset:
    """Stage 0 slips everywhere; in stage 1 ('release') nodes come to rest in ``order``."""
    if order == "outward":  # pole first, contact edge last (the paper's observation)
        frames = ["eeeeee....", "Seeeee....", "SSSeee....", "SSSSSe....", "SSSSSS...."]
    else:  # contact edge first, pole last
        frames = ["eeeeee....", "eeeeeS....", "eeeSSS....", "eSSSSS....", "SSSSSS...."]
    state = field("eeeeee....", *frames)
    return synthetic_trajectory(
        state,
        time=[0, 1, 2, 3, 4, 5],
        stage=[0, 1, 1, 1, 1, 1],
        rbar=np.linspace(0, 1.8, 10),
        theta_of_rbar=0.5,
    )


def test_stage_summary_rest_order_and_front_direction():
    out = stage_summary(_release("outward"))
    rel = out[1]
    assert rel["name"] == "release" and rel["frames"] == 5
    assert rel["front_direction"] == "toward_equator"
    assert rel["direction_stuck_toward_pole"] == "toward_equator"
    assert rel["last_rest_time_s"] == 5.0
    assert rel["last_to_rest_rbar"] == [1.0]  # node 5 (rbar = 5 * 0.2)
    assert rel["outermost_contact_rbar_at_end"] == 1.0
    assert rel["outermost_contact_rests_last"] is True
    assert rel["rest_order_spearman"] > 0.9
    assert rel["n_nodes_came_to_rest"] == 6
    assert out[0]["front_direction"] == "none"
    assert rel["stuck_inside_fraction"] == 1.0  # stuck from the pole out, slip outside
    assert "outermost contact rests last: yes" in summary_lines(out)[1]

    inward = stage_summary(_release("inward"))[1]
    assert inward["front_direction"] == "toward_pole"
    assert inward["direction_stuck_toward_equator"] == "toward_pole"
    assert inward["last_to_rest_rbar"] == [0.0]
    assert inward["outermost_contact_rests_last"] is False
    assert inward["stuck_inside_fraction"] == 0.0
    assert inward["rest_order_spearman"] < -0.9


def test_rest_speed_counts_slow_slipping_nodes_as_stuck():
    # flagged slipping at the friction limit, but the inner ones barely move
    state = field("Seeeep..", "Seeepp..", "Seeppp..")
    ds = synthetic_trajectory(state, stage=[0, 0, 0], stage_names=("raise",))
    v = np.array([[0, 1e-6, 1e-6, 0.1, 0.1, -0.1, 0, 0]] * 3, dtype=float)
    v[1, 4], v[2, 3] = -1e-6, -0.1  # node 4 at rest at frame 1; node 3 moving back at 2
    ds["slip_velocity"] = (("time", "rbar"), v, ds.slip_velocity.attrs)
    assert len(track_fronts(motion_state(ds))) == 1  # force criterion: only the pole front
    moving = motion_state(ds, rest_speed=1e-4)
    np.testing.assert_array_equal(moving[:, :6], field("SSSeep", "SSSeSp", "SSSppp")[:, :6])
    fr = fronts_dataset(ds, rest_speed=1e-4)
    assert fr.attrs["rest_speed"] == 1e-4
    assert list(fr.front_node.values[0]) == [2, 2, 2]
    assert summary(track_fronts(moving))[1:] == [
        ([1], [3], 2, "nucleated", "merged"),
        ([1], [4], 1, "nucleated", "merged"),
    ]
    with pytest.raises(InputError, match="rest_speed"):
        fronts_dataset(ds, rest_speed=-1.0)


def test_run_fronts_refuses_a_file_that_is_not_a_trajectory(tmp_path):
    bad = tmp_path / "trajectory.nc"
    bad.write_text("not netcdf")
    with pytest.raises(InputError, match="not a netCDF file"):
        run_fronts(bad)
    assert not (tmp_path / "fronts.nc").exists()


def test_rest_time_counts_only_slip_then_stick():
    state = field("SSee..", "SSeS..", "SSSS..", "SSSe..")
    ds = synthetic_trajectory(state, stage=[0, 0, 0, 0], stage_names=("only",))
    rest = fronts_dataset(ds).rest_time.values[0]
    # node 0, 1: never slipped; node 2 rests at t=2; node 3 slips at the end
    assert np.isnan(rest[0]) and np.isnan(rest[1]) and rest[2] == 2.0 and np.isnan(rest[3])


@pytest.mark.slow
def test_fronts_of_a_method2_run_are_continuous_between_named_events(tmp_path):
    """A real whole-sheet run (20 nodes, about 1.5 min): no unresolved event, small steps."""
    from pathlib import Path

    from rich.console import Console

    from dynslip.app.kinds import run as run_scenario
    from dynslip.schema import base as scenario

    path = Path(__file__).resolve().parents[1] / "scenarios" / "method2_let_go.yaml"
    assert path.exists(), "the shipped scenario scenarios/method2_let_go.yaml is missing"
    run_scenario(scenario.load(path, ["numerics.nodes=20"]), tmp_path, Console(quiet=True))
    ds = xr.open_dataset(tmp_path / "trajectory.nc").load()
    for rest_speed in (None, 1e-4):
        fr = fronts_dataset(ds, rest_speed)
        assert fr.attrs["unresolved_events"] == 0
        assert fr.attrs["max_front_step_nodes"] <= 2
        node = fr.front_node.values
        for k in range(fr.sizes["track"]):
            alive = np.flatnonzero(node[k] >= 0)
            assert np.array_equal(alive, np.arange(alive[0], alive[-1] + 1))  # no gaps
            steps = np.abs(np.diff(node[k, alive]))
            assert steps.max(initial=0) <= 2
