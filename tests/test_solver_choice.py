"""The segment solver named by the schema's ``numerics.solver``: the spec builds it
(:meth:`~dynslip.schema.forming.FormingNumerics.build_solver`), each setting it runs on taken
from its own field and every other parameter at the solver's default; the driver's
:class:`~dynslip.physics.solver.methods.Settings` take the rest of the spec, field by named
field (:func:`~dynslip.schema.world.settings_of`)."""

from __future__ import annotations

import dataclasses
import typing

import diffrax
import numpy as np
import pydantic
import pytest

from conftest import assert_energy_closes
from dynslip.physics.solver.loadstep import FullStateLoadStep
from dynslip.physics.solver.methods import DIFFRAX_METHODS, TimeStepping
from dynslip.physics.solver.newton import MotionNewton
from dynslip.schema.forming import FormingNumerics
from dynslip.schema.world import settings_of

# every numerics field a solver reads, away from its default (``linear_solver`` by family)
CHANGED = dict(
    max_steps=123,
    pid_pcoeff=0.2,
    pid_icoeff=0.4,
    newton_max_iter=9,
    newton_backtrack=2,
    newton_weight=7.5,
    max_increment=11.0,
    max_increment_free=3.0,
)


def _changed_fields(obj, default) -> dict:
    """The fields of ``obj`` that differ from ``default``'s, with ``obj``'s values."""
    return {
        f.name: getattr(obj, f.name)
        for f in dataclasses.fields(obj)
        if getattr(obj, f.name) != getattr(default, f.name)
    }


@pytest.mark.parametrize(
    "name", typing.get_args(FormingNumerics.model_fields["solver"].annotation)
)
def test_every_schema_solver_name_builds_the_solver_of_that_name(name):
    solver = FormingNumerics(solver=name).build_solver(0.0)
    assert solver.name == name
    if name in DIFFRAX_METHODS:
        assert solver.method is getattr(diffrax, DIFFRAX_METHODS[name])
    else:
        assert name in ("load_step", "load_step_full")


@pytest.mark.parametrize("linear", ["structured", "dense"])
def test_load_step_takes_its_settings_and_nothing_else(linear):
    solver = FormingNumerics(solver="load_step", linear_solver=linear, **CHANGED).build_solver(0.25)
    assert type(solver) is MotionNewton
    # load stepping picks its linear algebra by the mesh's size
    assert _changed_fields(solver, MotionNewton()) == dict(
        max_iter=9,
        backtrack=2,
        weight=7.5,
        max_increment=11.0,
        max_increment_free=3.0,
        heal_rate=0.25,
        max_steps=123,
    )


@pytest.mark.parametrize("linear", ["structured", "dense"])
def test_full_state_load_step_takes_its_settings_and_nothing_else(linear):
    """The reference of load stepping, Newton on the whole state: the increments' and
    Newton's settings and the linear algebra named (not the weighted form's c, not the PID's)."""
    spec = FormingNumerics(solver="load_step_full", linear_solver=linear, **CHANGED)
    solver = spec.build_solver(0.25)
    assert type(solver) is FullStateLoadStep
    assert _changed_fields(solver, FullStateLoadStep()) == dict(
        max_steps=123,
        newton_max_iter=9,
        newton_backtrack=2,
        heal_rate=0.25,
        max_increment=11.0,
        max_increment_free=3.0,
        **({"linear_solver": "dense"} if linear == "dense" else {}),
    )


@pytest.mark.slow
def test_a_scenario_run_by_the_full_state_newton_ends_where_load_stepping_ends(scenarios_dir):
    """``numerics.solver: load_step_full`` runs a scenario (method 1 on 12 nodes) by Newton on
    the whole state; the motion Newton of ``load_step`` solves the same implicit Euler
    increments, so the two take the same increments and end within Newton's tolerance
    (rtol 1e-5 on positions of order R; measured 3.1e-6 R), with the same verdict and energy
    residual (4.873e-3 of the work both; they differ by 8.4e-9 of the work, bound 1e-7)."""
    from dynslip import api

    def run(solver):
        sc = api.load(scenarios_dir / "method1.yaml", set={
            "numerics.nodes": 12, "numerics.max_chord_depth": 1, "numerics.solver": solver})
        return api.run(sc)

    a, b = run("load_step"), run("load_step_full")
    assert (a.summary["solver"]["method"], b.summary["solver"]["method"]) == (
        "load_step", "load_step_full")
    assert a.summary["solver"]["accepted"] == b.summary["solver"]["accepted"]
    assert a.summary["trapped"] == b.summary["trapped"]
    for r in (a, b):
        assert_energy_closes(r.summary)
    ea, eb = (r.summary["energy_balance"]["relative_residual"] for r in (a, b))
    assert abs(ea - eb) < 1e-7
    end_a, end_b = a.trajectory.isel(time=-1), b.trajectory.isel(time=-1)
    d = max(float(np.max(np.abs(end_a[v].values - end_b[v].values))) for v in ("rho", "z"))
    print(f"load_step vs load_step_full, method 1 at N = 12: max |dx| = {d:.2e} R")
    assert 0.0 < d < 1e-5


@pytest.mark.parametrize("name", sorted(DIFFRAX_METHODS))
def test_time_stepping_takes_its_scheme_and_settings(name):
    solver = FormingNumerics(solver=name, linear_solver="dense", **CHANGED).build_solver(0.25)
    assert type(solver) is TimeStepping
    assert _changed_fields(solver, TimeStepping(scheme=name)) == dict(
        max_steps=123, linear_solver="dense", pcoeff=0.2, icoeff=0.4, heal_rate=0.25
    )


def test_an_unknown_scheme_is_refused_by_the_schema_and_the_solver():
    with pytest.raises(pydantic.ValidationError, match="solver"):
        FormingNumerics(solver="rk4")
    with pytest.raises(ValueError, match="kvaerno5"):
        TimeStepping(scheme="rk4")


def test_equal_numerics_build_equal_solvers():
    """The compiled step's cache is keyed by the solver object: equal numerics must give
    equal, equally hashed objects (one compile), and a changed setting a different one."""
    a, b = (FormingNumerics(**CHANGED).build_solver(0.25) for _ in range(2))
    assert a == b and hash(a) == hash(b)
    c = FormingNumerics(**{**CHANGED, "newton_max_iter": 10}).build_solver(0.25)
    assert c != a


def test_settings_take_each_driver_field_from_the_spec():
    nu = FormingNumerics(rtol=1e-6, atol=1e-9, save_interval_s=0.5, contact_threshold=0.02,
                         max_chord_depth=0.2, heal_rate_mm_s=0.5, **CHANGED)
    s = settings_of(nu, ball_radius_mm=2.0, body_names=("post",))
    assert (s.rtol, s.atol, s.save_interval, s.contact_threshold, s.max_chord_depth) == (
        1e-6, 1e-9, 0.5, 0.02, 0.2
    )
    assert s.body_names == ("post",)
    # the healing rate in R/s: 0.5 mm/s on a ball of radius 2 mm
    assert s.solver == nu.build_solver(0.25)
