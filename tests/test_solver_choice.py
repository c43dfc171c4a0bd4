"""The segment solver named by the schema's ``numerics.solver``: each name maps to a class that
builds itself from :class:`~dynslip.physics.solver.methods.Settings`, taking each setting it runs on
from its own field (no copy by matching names), and every other parameter at its default."""

from __future__ import annotations

import dataclasses
import typing

import diffrax
import pytest

from dynslip.physics.solver.methods import (
    DIFFRAX_METHODS,
    SOLVERS,
    Settings,
    TimeStepping,
    solver_for,
)
from dynslip.physics.solver.newton import MotionNewton
from dynslip.schema.forming import FormingNumerics

# every setting a solver reads, away from its default (``linear_solver`` by solver family)
CHANGED = dict(
    max_steps=123,
    heal_rate=0.25,
    pcoeff=0.2,
    icoeff=0.4,
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


def test_every_schema_solver_name_has_a_class():
    names = typing.get_args(FormingNumerics.model_fields["solver"].annotation)
    assert set(names) == set(SOLVERS)
    assert set(DIFFRAX_METHODS) == set(SOLVERS) - {"load_step"}


@pytest.mark.parametrize("linear, built", [("thomas", "thomas"), ("cyclic", "cyclic"),
                                           ("structured", "auto"), ("dense", "auto")])
def test_load_step_takes_its_settings_and_nothing_else(linear, built):
    s = Settings(solver="load_step", linear_solver=linear, **CHANGED)
    solver = solver_for(s)
    assert type(solver) is MotionNewton
    changed = _changed_fields(solver, MotionNewton())
    changed.pop("linear", None)
    assert solver.linear == built
    assert changed == dict(
        max_iter=9,
        backtrack=2,
        weight=7.5,
        max_increment=11.0,
        max_increment_free=3.0,
        heal_rate=0.25,
        max_steps=123,
    )


@pytest.mark.parametrize("name", sorted(DIFFRAX_METHODS))
def test_time_stepping_takes_its_method_and_settings(name):
    s = Settings(solver=name, linear_solver="dense", **CHANGED)
    solver = solver_for(s)
    assert type(solver) is TimeStepping
    assert solver.method is getattr(diffrax, DIFFRAX_METHODS[name])
    default = TimeStepping(method=solver.method, max_steps=20000)
    assert _changed_fields(solver, default) == dict(
        max_steps=123, linear_solver="dense", pcoeff=0.2, icoeff=0.4, heal_rate=0.25
    )


def test_a_solver_object_is_used_as_it_is_and_an_unknown_name_refused():
    given = MotionNewton(max_iter=3)
    assert solver_for(Settings(solver=given)) is given
    with pytest.raises(ValueError, match="load_step"):
        solver_for(Settings(solver="rk4"))


def test_equal_settings_build_equal_solvers():
    """The compiled step's cache is keyed by the solver object: equal settings must give equal,
    equally hashed objects (one compile), and a changed setting a different one."""
    a, b = (solver_for(Settings(solver="load_step", **CHANGED)) for _ in range(2))
    assert a == b and hash(a) == hash(b)
    c = solver_for(Settings(solver="load_step", **{**CHANGED, "newton_max_iter": 10}))
    assert c != a
