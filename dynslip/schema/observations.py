"""Observations as data: the measurements a fit (``dynslip fit``) compares a run with, each
with its uncertainty and where it comes from; and the fit's parameters, each a scenario field
with the bounds its schema gives it.

The file (YAML, ``kind: observations``; the paper's: ``scenarios/observations/paper.yaml``)::

    kind: observations
    name: the paper's pocket
    theta_max: {value: 1.8, uncertainty: 0.27, source: "..."}      # rad: the contact's edge
    rbar_max: {value: 0.9, uncertainty: 0.09, source: "..."}       # R: its material radius
    theta_rbar:                                                    # inscribed circles
      - {rbar: 0.5, value: 1.1, uncertainty: 0.05, source: "..."}
    release_force_N: {value: 2.3, uncertainty: 0.575, source: "..."}
    max_stretch: {max: 6.0, uncertainty: 0.3, source: "..."}       # the path's largest stretch
    trapped: true                                                  # facts the branch must meet
    past_equator: true

Every section is optional; at least one measured value is required. ``uncertainty`` is one
standard deviation in the value's unit (the residual of a value is (model - value) /
uncertainty). A bound is one-sided: no residual while the model is within it, (model - max) /
uncertainty past it. What the model compares each with is in docs/calibration.md: the edge
located between nodes (``summary.json`` ``smooth``), theta at fixed material radii, the
release force at the located event, the path's largest principal stretch.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import ValidationError, model_validator

from dynslip.errors import InputError
from dynslip.physics.observables import OBS_RBAR
from dynslip.schema.base import F, Strict, format_validation_error, read_yaml
from dynslip.schema.paths import split

__all__ = ["Observations", "Measured", "ThetaPoint", "Bound", "load_observations",
           "FitParameter", "fit_parameters"]


def _source():
    return F("", description="where the value comes from (the sentence of the paper, a lab note)")


class Measured(Strict):
    """A measured value and its uncertainty (one standard deviation, same unit)."""

    value: float = F(..., description="the measured value")
    uncertainty: float = F(..., gt=0, description="one standard deviation, in the value's unit")
    source: str = _source()


class ThetaPoint(Strict):
    """theta at one material radius (an inscribed circle)."""

    rbar: float = F(..., unit="R", gt=0, lt=1e3,
                    description="the circle's material (undeformed) radius over R: one of the "
                                "radii every frame records (0.1, 0.2, ..., 0.9)")
    value: float = F(..., unit="rad", ge=0, le=math.pi, description="its polar angle on the ball")
    uncertainty: float = F(..., unit="rad", gt=0, description="one standard deviation")
    source: str = _source()

    @model_validator(mode="after")
    def _recorded(self):
        if not any(abs(self.rbar - r) < 1e-9 for r in OBS_RBAR):
            raise ValueError(f"rbar = {self.rbar:g}: allowed: one of "
                             f"{', '.join(f'{r:g}' for r in OBS_RBAR)} (the radii every frame "
                             "records, physics.observables.OBS_RBAR)")
        return self


class Bound(Strict):
    """An upper bound the model must stay within (one-sided)."""

    max: float = F(..., description="the largest value allowed")
    uncertainty: float = F(..., gt=0, description="how far past the bound counts as one "
                                                  "standard deviation")
    source: str = _source()


class ThetaMax(Measured):
    """The contact's edge: its polar angle (rad)."""

    value: float = F(..., unit="rad", gt=0, le=math.pi, description="polar angle of the edge")
    uncertainty: float = F(..., unit="rad", gt=0, description="one standard deviation")


class RbarMax(Measured):
    """The contact's edge: its material radius over R."""

    value: float = F(..., unit="R", gt=0, lt=1e3, description="material radius of the edge")
    uncertainty: float = F(..., unit="R", gt=0, description="one standard deviation")


class Force(Measured):
    """The force that pulls the ball out (N, its magnitude)."""

    value: float = F(..., unit="N", gt=0, le=1e4, description="magnitude of the release force")
    uncertainty: float = F(..., unit="N", gt=0, description="one standard deviation")


class StretchBound(Bound):
    """The path's largest principal stretch (meridional or hoop, any node, any frame)."""

    max: float = F(..., unit="1", gt=1, le=100, description="the largest stretch allowed")
    uncertainty: float = F(..., unit="1", gt=0, description="one standard deviation")


class Observations(Strict):
    """Measurements of a formed pocket (``dynslip fit --data``)."""

    kind: Literal["observations"] = F(..., description="the file's kind")
    name: str = F("", description="free-text name")
    description: str = F("", description="free-text description")
    theta_max: ThetaMax | None = F(None, unit="rad", description="the contact's edge, polar angle "
                                   "(model: the located edge, summary.json smooth.theta_edge)")
    rbar_max: RbarMax | None = F(None, unit="R", description="the contact's edge, material radius "
                                 "(model: smooth.rbar_edge)")
    theta_rbar: list[ThetaPoint] = F([], description="theta at material radii (model: "
                                     "smooth.theta_at_rbar)")
    release_force_N: Force | None = F(None, unit="N", description="the force that pulls the ball "
                                      "out (model: the ramped pull's force at the located event, "
                                      "summary.json release_force, its magnitude)")
    max_stretch: StretchBound | None = F(None, description="bound on the path's largest principal "
                                         "stretch (model: largest_stretch.path_max)")
    trapped: bool | None = F(None, description="fact: the ball ends trapped (the scan keeps only "
                             "branches that meet it)")
    past_equator: bool | None = F(None, description="fact: the contact ends past the equator")

    @model_validator(mode="after")
    def _something(self):
        if not (self.theta_max or self.rbar_max or self.theta_rbar or self.release_force_N):
            raise ValueError("no measured value: give at least one of theta_max, rbar_max, "
                             "theta_rbar, release_force_N")
        radii = [p.rbar for p in self.theta_rbar]
        if len(set(radii)) != len(radii):
            raise ValueError("theta_rbar: each rbar at most once")
        return self

    def rows(self) -> list[dict]:
        """Every residual the observations define, in order: ``{name, kind ('value' or
        'bound'), value, uncertainty, unit, key, source}``, with ``key`` what the model
        reads (docs/calibration.md)."""
        out = []

        def add(name, m, unit, key, kind="value"):
            out.append({"name": name, "kind": kind,
                        "value": m.max if kind == "bound" else m.value,
                        "uncertainty": m.uncertainty, "unit": unit, "key": key,
                        "source": m.source})

        if self.theta_max:
            add("theta_max", self.theta_max, "rad", "theta_edge")
        if self.rbar_max:
            add("rbar_max", self.rbar_max, "R", "rbar_edge")
        for p in self.theta_rbar:
            add(f"theta(rbar={p.rbar:g})", p, "rad", f"theta_at_rbar:{p.rbar:.2f}")
        if self.release_force_N:
            add("release_force_N", self.release_force_N, "N", "release_force")
        if self.max_stretch:
            add("max_stretch", self.max_stretch, "1", "path_max_stretch", kind="bound")
        return out


def load_observations(path) -> Observations:
    """Read and validate an observations file; :class:`InputError` (one line) otherwise."""
    data = read_yaml(path, "observations")
    if not isinstance(data, dict):
        raise InputError(f"{path}: an observations file must be a mapping, got "
                         f"{type(data).__name__}")
    try:
        return Observations.model_validate(data)
    except ValidationError as err:
        raise InputError(format_validation_error(err, str(path), data)) from None


class FitParameter(Strict):
    """A fitted scenario field: its dotted path, start value, bounds (from its schema's
    constraints; open bounds nudged inside) and unit."""

    path: str
    start: float
    lo: float
    hi: float
    unit: str


def fit_parameters(scenario, paths: list[str], source: str = "--params") -> list[FitParameter]:
    """The fit's parameters: each dotted path of the validated ``scenario`` (a pydantic model)
    names a number field; its bounds are the field's constraints (``ge``/``gt``/``le``/``lt``).
    :class:`InputError` for an unknown path, a field that is not a number, or a repeat."""
    if len(set(paths)) != len(paths) or not paths:
        raise InputError(f"{source} = {','.join(paths)!r}: allowed: one or more distinct "
                         "scenario fields, e.g. physics.material.jm,physics.friction.mu_s")
    out = []
    for dotted in paths:
        obj = scenario
        parts = split(dotted, source)
        for p in parts[:-1]:
            obj = _child(obj, p, dotted, source)
        fields = getattr(type(obj), "model_fields", {})
        last = parts[-1]
        if last not in fields:
            allowed = ", ".join(k for k, f in fields.items() if f.annotation in (float, int))
            raise InputError(f"{source}: {dotted!r} is not a field of the scenario; allowed at "
                             f"that place: {allowed or 'none'}")
        info = fields[last]
        value = getattr(obj, last)
        if info.annotation not in (float, int) or isinstance(value, bool):
            raise InputError(f"{source}: {dotted!r} = {value!r} is not a number field; "
                             "allowed: a number field (e.g. physics.material.jm)")
        lo, hi = -math.inf, math.inf
        for m in info.metadata:
            if getattr(m, "ge", None) is not None:
                lo = float(m.ge)
            if getattr(m, "gt", None) is not None:
                lo = float(m.gt) + 1e-9 * max(1.0, abs(float(m.gt)))
            if getattr(m, "le", None) is not None:
                hi = float(m.le)
            if getattr(m, "lt", None) is not None:
                hi = float(m.lt) - 1e-9 * max(1.0, abs(float(m.lt)))
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        out.append(FitParameter(path=dotted, start=float(value), lo=lo, hi=hi,
                                unit=str(extra.get("unit", "1"))))
    return out


def _child(obj, key: str, dotted: str, source: str):
    if isinstance(obj, (list, tuple)):
        try:
            return obj[int(key)]
        except (ValueError, IndexError):
            raise InputError(f"{source}: {dotted!r}: no item {key!r} (the list has "
                             f"{len(obj)})") from None
    if not hasattr(type(obj), "model_fields") or key not in type(obj).model_fields:
        raise InputError(f"{source}: {dotted!r} is not a field of the scenario (no section "
                         f"{key!r})")
    return getattr(obj, key)
