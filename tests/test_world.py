"""The world of a forming run, built once from its scenario (:mod:`dynslip.schema.world`): the
protocol built once per physics and shared by the validator, the size check and the run; the
driver's settings taken from the numerics spec by name; nothing downstream of the world holding a
schema object."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from pydantic import BaseModel

import dynslip.schema.forming as schema_forming
from dynslip.app import kinds
from dynslip.physics.solver.methods import Settings
from dynslip.schema.base import load
from dynslip.schema.world import World

ROOT = Path(__file__).resolve().parents[1]
METHOD2 = ROOT / "scenarios" / "method2.yaml"
BAND = ROOT / "scenarios" / "method2_band.yaml"


@pytest.fixture
def builds(monkeypatch):
    """Every build of a core protocol, counted."""
    calls = []
    real = schema_forming.build_protocol

    def counted(sc):
        calls.append(sc)
        return real(sc)

    monkeypatch.setattr(schema_forming, "build_protocol", counted)
    return calls


def test_the_protocol_is_built_once_for_the_validator_the_size_check_and_the_run(builds):
    sc = load(BAND)
    assert len(builds) == 1  # the validator's clamp-path and frame-count checks
    world = kinds.preflight(sc)  # the world, its memory check and its start
    again = sc.world()
    assert len(builds) == 1
    assert world.protocol is sc.protocol() is again.protocol


def test_a_copy_with_other_physics_builds_its_own_protocol(builds):
    sc = load(METHOD2)
    slower = sc.physics.model_copy(update={"stages": [
        s.model_copy(update={"clamp_speed_mm_s": s.clamp_speed_mm_s / 2})
        if s.clamp_to_z_mm is not None else s for s in sc.physics.stages]})
    copy = sc.model_copy(update={"physics": slower})
    # the same stages at half the clamp's speed: the keyframed moves last twice as long
    first = sc.protocol().stages[0].max_duration
    assert copy.protocol().stages[0].max_duration == pytest.approx(2 * first, rel=1e-12)
    assert len(builds) == 2
    # numerics only: the physics, and so the protocol, are the same object
    finer = sc.model_copy(update={"numerics": sc.numerics.model_copy(update={"nodes": 80})})
    assert finer.protocol() is sc.protocol() and len(builds) == 2


def test_the_settings_take_every_setting_of_the_numerics_spec():
    """Each of the driver's settings, and each setting of the segment solver the spec builds,
    follows the scenario's field (renamed and converted where the spec states it in its own
    units), changed one at a time; the diffrax solver's own settings with ``solver:
    kvaerno5``."""
    kv = ["numerics.solver=kvaerno5"]
    changed = {
        "rtol": ("numerics.rtol", 3e-6, 3e-6, []),
        "atol": ("numerics.atol", 4e-8, 4e-8, []),
        "save_interval": ("numerics.save_interval_s", 0.5, 0.5, []),
        "contact_threshold": ("numerics.contact_threshold", 0.02, 0.02, []),
        "max_chord_depth": ("numerics.max_chord_depth", 0.05, 0.05, []),
        "solver.max_steps": ("numerics.max_steps", 1234, 1234, []),
        "solver.heal_rate": ("numerics.heal_rate_mm_s", 0.004, 0.004 / 20.0, []),  # R = 20 mm
        "solver.max_iter": ("numerics.newton_max_iter", 13, 13, []),
        "solver.backtrack": ("numerics.newton_backtrack", 2, 2, []),
        "solver.weight": ("numerics.newton_weight", 50.0, 50.0, []),
        "solver.max_increment": ("numerics.max_increment", 7.0, 7.0, []),
        "solver.max_increment_free": ("numerics.max_increment_free", 3.0, 3.0, []),
        "solver.name": ("numerics.solver", "kvaerno4", "kvaerno4", kv),
        "solver.pcoeff": ("numerics.pid_pcoeff", 0.25, 0.25, kv),
        "solver.icoeff": ("numerics.pid_icoeff", 0.35, 0.35, kv),
        "solver.linear_solver": ("numerics.linear_solver", "dense", "dense", kv),
    }
    assert {n for n in changed if "." not in n} | {"solver", "body_names"} == {
        f.name for f in dataclasses.fields(Settings)
    }

    def read(settings, name):
        for part in name.split("."):
            settings = getattr(settings, part)
        return settings

    base = load(BAND).world().settings
    assert base.body_names == ("tube wall",)
    assert base.solver.name == "load_step"
    for name, (path, value, expected, given) in changed.items():
        before = read(load(BAND, given).world().settings, name)
        got = read(load(BAND, [*given, f"{path}={value}"]).world().settings, name)
        assert got == pytest.approx(expected, rel=1e-15) if isinstance(got, float) \
            else got == expected, name
        assert got != before, name


def _schema_objects(x, path="world"):
    if isinstance(x, BaseModel):
        yield path
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        for f in dataclasses.fields(x):
            yield from _schema_objects(getattr(x, f.name), f"{path}.{f.name}")
    elif isinstance(x, dict):
        for k, v in x.items():
            yield from _schema_objects(v, f"{path}[{k!r}]")
    elif isinstance(x, tuple | list):
        for k, v in enumerate(x):
            yield from _schema_objects(v, f"{path}[{k}]")


def test_the_world_holds_no_schema_object():
    """Whatever the run, the summary and the figures read from the scenario is in the world as
    plain values and core objects: the scales G h0 R, the tube's rim and the band's stages."""
    sc = load(BAND)
    p = sc.physics
    world = sc.world()
    assert isinstance(world, World)
    assert list(_schema_objects(world)) == []
    g_h0_r = p.youngs_modulus_MPa * 1e6 / 3.0 * p.thickness_um * 1e-6 * p.ball_radius_mm * 1e-3
    assert world.scales.force_scale_N == pytest.approx(g_h0_r, rel=1e-15)
    assert world.tube_rim_z == pytest.approx(
        (p.ball_radius_mm + p.sheet_gap_mm + p.tube.rim_gap_mm) / p.ball_radius_mm, rel=1e-15)
    assert world.band_stages == tuple(k for k, s in enumerate(p.stages) if s.clamp == "band")
    assert world.band_stages and world.body_names == ["tube wall"]
