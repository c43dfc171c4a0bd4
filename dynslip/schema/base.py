"""Scenario files: YAML validated by pydantic, with ``--set section.key=value`` overrides.

A scenario has a ``kind`` (which computation), a ``physics`` section and a
``numerics`` section. The schema of each kind lives beside its runner
(:mod:`dynslip.schema.static`, :mod:`dynslip.schema.forming`); this module holds
the shared machinery: strict models (unknown keys rejected, ranges checked), units in
each field's metadata, loading, overrides, one-line error messages and the reference
printed by ``dynslip schema``.

Physical units in files: lengths in mm, speeds in mm/s, times in s, moduli in MPa.
The numerical core is nondimensional (lengths by R, tensions by G h0).
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import Annotated, Any, Union

import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from dynslip.errors import InputError
from dynslip.schema.paths import set_path

# kind -> (module, class). Each module defines its scenario class with ``kind: Literal[kind]``.
KINDS: dict[str, tuple[str, str]] = {
    "static": ("dynslip.schema.static", "StaticScenario"),
    "figure4": ("dynslip.schema.static", "Figure4Scenario"),
    "family": ("dynslip.schema.static", "FamilyScenario"),
    "cylinder": ("dynslip.schema.static", "CylinderScenario"),
    "forming": ("dynslip.schema.forming", "FormingScenario"),
}


class Strict(BaseModel):
    """Base of every schema section: unknown keys are errors; values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


def F(default: Any = ..., *, unit: str = "1", description: str = "", **kw) -> Any:
    """A pydantic ``Field`` carrying its physical unit (``"1"`` for dimensionless)."""
    return Field(default, description=description, json_schema_extra={"unit": unit}, **kw)


class ScenarioBase(Strict):
    """Fields every scenario has; subclasses add ``kind``, ``physics`` and ``numerics``."""

    name: str = F("", description="free-text name of the scenario")
    description: str = F("", description="free-text description")

    def to_json(self) -> str:
        """The resolved scenario (every default filled in) as JSON."""
        return self.model_dump_json()


def _classes() -> dict[str, type]:
    """kind -> scenario class. An import error of a schema module propagates: it is a bug,
    not an unknown kind."""
    return {kind: getattr(importlib.import_module(mod), cls) for kind, (mod, cls) in KINDS.items()}


def _adapter():
    classes = list(_classes().values())
    if not classes:
        raise InputError("no scenario kinds are installed")
    if len(classes) == 1:
        return TypeAdapter(classes[0])
    union = Annotated[Union[tuple(classes)], Field(discriminator="kind")]  # noqa: UP007
    return TypeAdapter(union)


def parse_override(text: str) -> tuple[str, Any]:
    """``section.key=value`` -> (dotted path, YAML-parsed value)."""
    if "=" not in text:
        raise InputError(f"--set {text!r}: expected section.key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not k for k in key.split(".")):
        raise InputError(f"--set {text!r}: expected section.key=value")
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError:
        value = raw
    return key, value


def _field_path(loc, data) -> str:
    """The dotted field path of a pydantic error location, without the tags pydantic inserts
    for discriminated unions (``kind``, ``material.model``): a part is a tag when it is not a
    key of the data at that point and more parts follow."""
    parts, node = [], data
    for i, p in enumerate(loc):
        last = i == len(loc) - 1
        if isinstance(node, dict) and p in node:
            parts.append(str(p))
            node = node[p]
        elif isinstance(node, list) and isinstance(p, int) and 0 <= p < len(node):
            parts.append(str(p))
            node = node[p]
        elif last or not isinstance(node, dict):
            parts.append(str(p))
            node = None
    return ".".join(parts)


def format_validation_error(err: ValidationError, source: str, data=None) -> str:
    """One line: the first offending field, its value and what is allowed."""
    e = err.errors()[0]
    if data is not None:
        loc = _field_path(e["loc"], data)
    else:
        loc = ".".join(str(p) for p in e["loc"] if not (isinstance(p, str) and p in _classes()))
    value = e.get("input")
    shown = json.dumps(value) if isinstance(value, (int, float, str, bool, type(None))) else type(value).__name__
    msg = e["msg"]
    if e["type"] == "extra_forbidden":
        msg = "unknown field (not in the schema; see `dynslip schema`)"
    if e["type"] == "union_tag_invalid":
        loc, msg = "kind", f"unknown kind; allowed: {', '.join(_classes())}"
    more = f" (and {len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
    return f"{source}: field '{loc or '<root>'}' = {shown}: {msg}{more}"


def validate_data(data: Any, source: str = "<scenario>"):
    """Validate a mapping into a scenario object, or raise :class:`InputError`."""
    if not isinstance(data, dict):
        raise InputError(f"{source}: a scenario must be a mapping of sections, got {type(data).__name__}")
    if "kind" not in data:
        raise InputError(f"{source}: field 'kind' missing; allowed: {', '.join(_classes())}")
    if data["kind"] not in _classes():
        raise InputError(f"{source}: field 'kind' = {json.dumps(data['kind'])}: unknown kind; allowed: {', '.join(_classes())}")
    try:
        return _adapter().validate_python(data)
    except ValidationError as err:
        raise InputError(format_validation_error(err, source, data)) from None


def load_data(path, overrides: list[str] | tuple[str, ...] = ()) -> dict:
    """Read a YAML scenario file and apply ``section.key=value`` overrides."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: scenario file not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(f"{path}: malformed YAML{where}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(f"{path}: a scenario must be a mapping of sections, got {type(data).__name__}")
    for text in overrides:
        key, value = parse_override(text)
        set_path(data, key, value, f"{path}: --set")
    return data


def load(path, overrides: list[str] | tuple[str, ...] = (), values: dict[str, Any] | None = None):
    """Load, override and validate a scenario file; raises :class:`InputError`.

    ``overrides``: ``section.key=value`` texts (``--set``); ``values``: ``{dotted path:
    value}`` applied after them (:func:`dynslip.load`'s ``set=``). Both take the paths of
    :mod:`dynslip.schema.paths`."""
    data = load_data(path, overrides)
    for key, value in (values or {}).items():
        set_path(data, key, value, f"{path}: set")
    obj = validate_data(data, str(path))
    if hasattr(obj, "_source_dir"):
        obj._source_dir = Path(path).resolve().parent  # where relative start_from paths may live
    return obj


def _rows(schema: dict, defs: dict, prefix: str, rows: list) -> None:
    for name, prop in schema.get("properties", {}).items():
        if "$ref" in prop:
            sub = defs[prop["$ref"].split("/")[-1]]
            _rows(sub, defs, f"{prefix}{name}.", rows)
            continue
        if "allOf" in prop and "$ref" in prop["allOf"][0]:
            sub = defs[prop["allOf"][0]["$ref"].split("/")[-1]]
            _rows(sub, defs, f"{prefix}{name}.", rows)
            continue
        typ = prop.get("type")
        if typ is None and "anyOf" in prop:
            typ = " | ".join(p.get("type", p.get("$ref", "?").split("/")[-1]) for p in prop["anyOf"])
        if "enum" in prop:
            typ = " | ".join(map(str, prop["enum"]))
        if "const" in prop:
            typ = repr(prop["const"])
        rng = []
        for key, sym in (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"), ("maximum", "<=")):
            if key in prop:
                rng.append(f"{sym} {prop[key]}")
        if "minItems" in prop:
            rng.append(f"items >= {prop['minItems']}")
        rows.append(
            (
                prefix + name,
                str(typ),
                json.dumps(prop.get("default")) if "default" in prop else "required",
                ", ".join(rng),
                prop.get("unit", ""),
                prop.get("description", ""),
            )
        )


def schema_reference() -> str:
    """A plain-text reference of every field of every scenario kind."""
    lines = []
    for kind, cls in _classes().items():
        sch = cls.model_json_schema()
        rows: list = []
        _rows(sch, sch.get("$defs", {}), "", rows)
        lines.append(f"kind: {kind}  ({(cls.__doc__ or '').strip().splitlines()[0]})")
        lines.append(f"  {'field':42s} {'type':18s} {'default':14s} {'range':16s} {'unit':6s} description")
        for r in rows:
            lines.append(f"  {r[0]:42s} {r[1][:18]:18s} {r[2][:14]:14s} {r[3][:16]:16s} {r[4]:6s} {r[5]}")
        lines.append("")
    return "\n".join(lines)
