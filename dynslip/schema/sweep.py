"""The sweep file as a validated model (:class:`SweepSpec`, with its grid axes
:class:`Linspace` and its window search :class:`WindowSpec`), and reading it.

A sweep file is a small YAML file of its own (validated strictly, like a scenario); the
format is described in :mod:`dynslip.app.sweep`, which runs it.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from dynslip.errors import InputError
from dynslip.schema.base import kind_classes, read_yaml
from dynslip.schema.paths import get_path, set_path

BASE_KEY = "base"


#: the most members a sweep may have (a grid's product of axis lengths, or a list's length)
MAX_MEMBERS = 10_000


class _Strict(BaseModel):
    # strict: numbers given as text ("0.3") are errors, as in scenario files; finite numbers only
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


class Linspace(_Strict):
    """``{start, stop, num}``: ``num`` equally spaced values, both ends included."""

    start: float
    stop: float
    num: int = Field(ge=1, le=MAX_MEMBERS, description="number of values, 1..10000")

    def values(self) -> list[float]:
        return [float(v) for v in np.linspace(self.start, self.stop, self.num)]


class WindowSpec(_Strict):
    """The trapping-window search run for each member (see :mod:`dynslip.app.window`)."""

    field: str | None = Field(None, description="friction field; default mu (ideal law) or mu_s")
    lo: float = Field(0.0, ge=0, le=100)
    hi: float = Field(3.0, gt=0, le=100)
    coarse: int = Field(13, ge=2, le=1000, description="coarse scan points, 2..1000")
    tol: float = Field(
        0.02, ge=1e-6, le=100, description="width of the final brackets, in [1e-6, 100]"
    )

    @model_validator(mode="after")
    def _range(self):
        if not self.hi > self.lo:
            raise ValueError(f"empty range: hi = {self.hi} must exceed lo = {self.lo}")
        return self


class SweepSpec(_Strict):
    """A study: a base scenario, overrides for all, and a grid or a list of members."""

    name: str = ""
    description: str = ""
    base: str = Field(description="scenario file, relative to the sweep file")
    overrides: dict[str, Any] = Field(default_factory=dict)
    grid: dict[str, list[Any] | Linspace] | None = Field(
        None,
        description="field -> list of values or {start, stop, num}; at most 10000 members in all",
    )
    list_: list[dict[str, Any]] | None = Field(
        None, alias="list", description="members, at most 10000"
    )
    window: WindowSpec | None = None
    out: str | None = None
    mode: Literal["sequential", "batched", "dask"] | None = None
    keep_runs: bool = Field(False, description="keep each member's run folder under <out>/runs/")

    @model_validator(mode="after")
    def _one_of(self):
        if (self.grid is None) == (self.list_ is None):
            raise ValueError("give exactly one of 'grid' and 'list'")
        if self.grid is not None and not self.grid:
            raise ValueError("empty grid: name at least one field")
        if self.list_ is not None and not self.list_:
            raise ValueError("empty list: give at least one member")
        n = 1
        for k, v in (self.grid or {}).items():
            vals = v.values() if isinstance(v, Linspace) else v
            if not vals:
                raise ValueError(f"grid field '{k}': empty range (no values)")
            n *= len(vals)
        n = len(self.list_) if self.list_ is not None else n
        if n > MAX_MEMBERS:
            raise ValueError(f"{n} members: allowed at most {MAX_MEMBERS} (split the study)")
        return self

    def grid_values(self) -> dict[str, list[Any]]:
        return {
            k: (v.values() if isinstance(v, Linspace) else list(v))
            for k, v in (self.grid or {}).items()
        }


def is_sweep_file(path) -> bool:
    """Whether ``path`` reads as a sweep file (a mapping with ``base`` and no ``kind``) rather
    than a scenario; anything unreadable is left to the scenario loader to report."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and "kind" not in data and BASE_KEY in data


def load_spec(path) -> SweepSpec:
    """Read and validate a sweep file; raises :class:`InputError` (one line)."""
    path = Path(path)
    data = read_yaml(path, "sweep")  # UTF-8 text, duplicate keys refused; InputError otherwise
    if not isinstance(data, dict):
        raise InputError(f"{path}: a sweep file must be a mapping (base, grid or list, ...)")
    try:
        return SweepSpec.model_validate(data)
    except ValidationError as err:
        e = max(
            err.errors(), key=lambda e: len(e["loc"])
        )  # for a union, the branch that got furthest
        loc = ".".join(str(p) for p in e["loc"] if p not in ("list[any]", "Linspace"))
        msg = (
            "unknown field (allowed: name, description, base, overrides, grid, list, window, out, "
            "mode, keep_runs)"
            if e["type"] == "extra_forbidden"
            else e["msg"]
        )
        value = e.get("input")
        shown = (
            json.dumps(value)
            if isinstance(value, (int, float, str, bool, type(None)))
            else type(value).__name__
        )
        if not loc and e["type"] == "value_error":  # a check across fields: its message names them
            raise InputError(f"{path}: {msg.removeprefix('Value error, ')}") from None
        raise InputError(f"{path}: field '{loc or '<root>'}' = {shown}: {msg}") from None


def unit_of_field(dotted: str, members: list) -> str:
    """The unit a scenario field declares in its schema metadata, or ``"1"``."""
    try:
        kind = members[0].resolved.get("kind")
        cls = kind_classes().get(kind)
        if cls is None:
            return "1"
        schema = cls.model_json_schema()
        node, defs = schema, schema.get("$defs", {})
        keys = iter(dotted.split("."))
        for k in keys:
            prop = node.get("properties", {}).get(k, {})
            if "items" in prop:  # a list: the next key names an item (by name or index)
                prop = prop["items"]
                next(keys, None)
            ref = prop.get("$ref") or (prop.get("allOf") or [{}])[0].get("$ref")
            node = defs[ref.split("/")[-1]] if ref else prop
        unit = node.get("unit", "1")
        return unit if isinstance(unit, str) else "1"
    except Exception:  # noqa: BLE001 - units are metadata; never fail a sweep on them
        return "1"


def friction_field(resolved: dict, field_name: str | None = None) -> tuple[str, list[str]]:
    """The swept friction field and the fields tied to it by a fixed ratio.

    ``physics.friction.mu`` for the ideal law; ``physics.friction.mu_s`` when the law
    has a static coefficient, with ``mu_k`` tied (``mu_k / mu_s`` fixed).
    """
    fr = resolved.get("physics", {}).get("friction", {})
    if field_name is None:
        # mu_s when the law has a static coefficient (any law but the ideal one that also has mu)
        if isinstance(fr, dict) and "mu_s" in fr and (fr.get("law") != "coulomb" or "mu" not in fr):
            field_name = "physics.friction.mu_s"
        elif isinstance(fr, dict) and "mu" in fr:
            field_name = "physics.friction.mu"
        else:
            raise InputError(
                "window: the scenario has no field 'physics.friction.mu' or "
                "'physics.friction.mu_s' to search over"
            )
    try:
        get_path(resolved, field_name)
    except KeyError:
        raise InputError(f"window: field '{field_name}' is not in the scenario") from None
    tied = []
    if field_name.endswith(".mu_s"):
        sib = field_name[: -len("mu_s")] + "mu_k"
        try:
            get_path(resolved, sib)
            tied.append(sib)
        except KeyError:
            pass
    return field_name, tied


def member_at(data: dict, resolved: dict, field_name: str, tied: list[str], mu: float) -> dict:
    """The scenario data with ``field_name = mu`` and every tied field at its base ratio."""
    base = float(get_path(resolved, field_name))
    out = copy.deepcopy(data)
    set_path(out, field_name, float(mu))
    for t in tied:
        ratio = float(get_path(resolved, t)) / base if base else 1.0
        set_path(out, t, float(mu) * ratio)
    return out
