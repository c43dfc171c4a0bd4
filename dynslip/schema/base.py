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
import re
import types
from pathlib import Path
from typing import Annotated, Any, Union, get_args, get_origin

import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator
from pydantic_core import PydanticCustomError

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


#: the error type of a number given as text (or a boolean): see :meth:`Strict._numbers_are_numbers`
NUMBER_AS_TEXT = "number_as_text"


def _wants_number(tp) -> bool:
    """The annotation takes numbers only (``float``, ``int``, optionally ``None``)."""
    if tp in (int, float):
        return True
    origin = get_origin(tp)
    if origin is Annotated:
        return _wants_number(get_args(tp)[0])
    if origin in (Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        return bool(args) and all(_wants_number(a) for a in args)
    return False


def _text_for_number(tp, value) -> str | None:
    """Why ``value`` is refused for a field of type ``tp``: a string or a boolean where only a
    number is allowed (pydantic would read "0.5" as 0.5 and true as 1); ``None`` when fine."""
    if _wants_number(tp):
        if isinstance(value, str):
            try:
                float(value)
            except ValueError:
                return f"a number is expected, not the text {value!r}"
            return "a number is expected, not text: write it without quotes"
        if isinstance(value, bool):
            return "a number is required, not a boolean"
        return None
    origin = get_origin(tp)
    if origin is Annotated:
        return _text_for_number(get_args(tp)[0], value)
    if origin in (Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        return _text_for_number(args[0], value) if len(args) == 1 else None
    if origin in (tuple, list) and isinstance(value, (list, tuple)):
        item_types = get_args(tp)
        for i, v in enumerate(value):
            if origin is tuple and not (len(item_types) == 2 and item_types[1] is Ellipsis):
                item = item_types[i] if i < len(item_types) else None
            else:
                item = item_types[0] if item_types else None
            why = None if item is None else _text_for_number(item, v)
            if why:
                return f"item {i}: {why}"
    return None


class Strict(BaseModel):
    """Base of every schema section: unknown keys are errors; values are frozen; numbers are
    finite (NaN and infinities refused) and never given as text or booleans."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )

    @model_validator(mode="before")
    @classmethod
    def _numbers_are_numbers(cls, data):
        # (a model validator: pydantic allows no field validator on a union's discriminator field)
        if isinstance(data, dict):
            for key, value in data.items():
                field = cls.model_fields.get(key) if isinstance(key, str) else None
                why = None if field is None else _text_for_number(field.annotation, value)
                if why:
                    raise PydanticCustomError(NUMBER_AS_TEXT, "field '{field}': {why}",
                                              {"field": key, "why": why, "value": value})
        return data


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


def kind_classes() -> dict[str, type[BaseModel]]:
    """kind -> scenario class. An import error of a schema module propagates: it is a bug,
    not an unknown kind."""
    return {kind: getattr(importlib.import_module(mod), cls) for kind, (mod, cls) in KINDS.items()}


def _adapter():
    classes = list(kind_classes().values())
    if not classes:
        raise InputError("no scenario kinds are installed")
    if len(classes) == 1:
        return TypeAdapter(classes[0])
    union = Annotated[Union[tuple(classes)], Field(discriminator="kind")]  # noqa: UP007
    return TypeAdapter(union)


# Reading YAML: UTF-8 text only; a key twice in one mapping is an error (PyYAML keeps the
# last one silently); numbers as YAML 1.2 reads them (``1e-5`` a float, where YAML 1.1 needs
# ``1.0e-5`` and would give text, which the schema refuses). Failures are one-line InputErrors.


class _DuplicateKey(yaml.MarkedYAMLError):
    """A key given twice in one mapping."""


# libyaml's loader when PyYAML was built with it; a name, as mypy takes no call as a base class
_SafeLoader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class Loader(_SafeLoader):
    """``yaml.SafeLoader`` (libyaml's parser when installed) that refuses duplicate keys and
    reads ``1e-5`` as a float."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.get(key)
                except (
                    TypeError
                ):  # an unhashable key (a list or mapping as key): SafeLoader says so
                    continue
                if first is not None:
                    raise _DuplicateKey(
                        f"duplicate key {key!r} (first at line {first.line + 1})", first,
                        "allowed: each key once per mapping", key_node.start_mark)
                seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


# YAML 1.2 floats: an exponent without a dot (1e-5, 2E3) is a number too.
Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def _where(err: yaml.YAMLError) -> str:
    mark = getattr(err, "problem_mark", None)
    return f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""


def parse_yaml(text: str, source: str) -> Any:
    """The data of a YAML text, or :class:`InputError` (one line, with the line and column)."""
    try:
        return yaml.load(text, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader
    except _DuplicateKey as err:
        raise InputError(f"{source}: {err.context}{_where(err)}; {err.problem}") from None
    except yaml.YAMLError as err:
        problem = getattr(err, "problem", None)
        why = f" ({problem})" if problem else ""
        raise InputError(f"{source}: malformed YAML{_where(err)}{why}") from None
    except RecursionError:
        raise InputError(f"{source}: malformed YAML (nested too deeply)") from None


def read_text(path, what: str = "scenario") -> str:
    """The text of a UTF-8 file (a leading BOM is dropped), or :class:`InputError`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {what} file not found")
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise InputError(
            f"{path}: cannot read the {what} file ({err.strerror or type(err).__name__})"
        ) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(
            f"{path}: not a UTF-8 text file (byte {err.start} is 0x{raw[err.start]:02x}); "
            f"allowed: a YAML {what} file in UTF-8"
        ) from None
    if "\x00" in text:
        raise InputError(
            f"{path}: a binary file (it holds NUL bytes); allowed: a YAML {what} file in UTF-8"
        )
    return text


def read_yaml(path, what: str = "scenario") -> Any:
    """The data of a YAML file read as UTF-8 text; :class:`InputError` otherwise."""
    return parse_yaml(read_text(path, what), str(path))


def parse_value(raw: str) -> Any:
    """A ``--set`` value parsed as YAML (the same rules as files); text YAML cannot parse
    stays the text."""
    try:
        return yaml.load(raw, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader
    except (yaml.YAMLError, RecursionError):
        return raw


def parse_override(text: str) -> tuple[str, Any]:
    """``section.key=value`` -> (dotted path, YAML-parsed value)."""
    if "=" not in text:
        raise InputError(f"--set {text!r}: expected section.key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not k for k in key.split(".")):
        raise InputError(f"--set {text!r}: expected section.key=value")
    return key, parse_value(raw)  # YAML, as in files (1e-5 a float); unparsable text stays text


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
    eloc: tuple[Any, ...] = tuple(e["loc"])
    if e["type"] == NUMBER_AS_TEXT:  # raised by the section: the field is in its context
        eloc = (*eloc, (e.get("ctx") or {}).get("field"))
    elif e["type"] == "value_error" and isinstance(e.get("input"), dict) and eloc and \
            eloc[-1] in (e["input"].get("model"), e["input"].get("kind")):
        eloc = eloc[:-1]  # a check of a tagged section (material: mooney_rivlin): not the tag
    if data is not None:
        loc = _field_path(eloc, data)
    else:
        loc = ".".join(str(p) for p in eloc if not (isinstance(p, str) and p in kind_classes()))
    if len(eloc) == 1 and loc in kind_classes():  # a check of the whole scenario (its kind's tag)
        loc = ""
    value = e.get("input")
    msg = " ".join(str(e["msg"]).split()).removeprefix("Value error, ")
    if e["type"] == "extra_forbidden":
        msg = "unknown field (not in the schema; see `dynslip schema`)"
    if e["type"] == "union_tag_invalid":  # a nested discriminated union (material: {model: ...})
        ctx = e.get("ctx") or {}
        disc = str(ctx.get("discriminator", "kind")).strip("'\"")
        loc = f"{loc}.{disc}" if loc else disc
        value = value.get(disc) if isinstance(value, dict) else ctx.get("tag", value)
        what = "kind" if disc == "kind" else disc
        msg = f"unknown {what}; allowed: {ctx.get('expected_tags') or ', '.join(kind_classes())}"
    if e["type"] == NUMBER_AS_TEXT:
        ctx = e.get("ctx") or {}
        value, msg = ctx.get("value"), str(ctx.get("why"))
    more = f" (and {len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
    if e["type"] == "value_error" and isinstance(
        value, dict
    ):  # a check across fields: its message names them
        return f"{source}: {loc + ': ' if loc else ''}{msg}{more}"
    if isinstance(value, (int, float, str, bool, type(None))):
        shown = json.dumps(value)
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
    else:
        shown = type(value).__name__
    return f"{source}: field '{loc or '<root>'}' = {shown}: {msg}{more}"


def validate_data(data: Any, source: str = "<scenario>"):
    """Validate a mapping into a scenario object, or raise :class:`InputError`."""
    if not isinstance(data, dict):
        raise InputError(
            f"{source}: a scenario must be a mapping of sections, got {type(data).__name__}"
        )
    if "kind" not in data:
        raise InputError(f"{source}: field 'kind' missing; allowed: {', '.join(kind_classes())}")
    if not isinstance(data["kind"], str) or data["kind"] not in kind_classes():
        kind = data["kind"]
        shown = (
            json.dumps(kind)
            if isinstance(kind, (int, float, str, bool, type(None)))
            else type(kind).__name__
        )
        raise InputError(
            f"{source}: field 'kind' = {shown[:80]}: unknown kind; "
            f"allowed: {', '.join(kind_classes())}"
        )
    try:
        return _adapter().validate_python(data)
    except ValidationError as err:
        raise InputError(format_validation_error(err, source, data)) from None


def load_data(path, overrides: list[str] | tuple[str, ...] = ()) -> dict:
    """Read a YAML scenario file and apply ``section.key=value`` overrides."""
    path = Path(path)
    data = read_yaml(path, "scenario")  # UTF-8 text, duplicate keys refused; InputError otherwise
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(
            f"{path}: a scenario must be a mapping of sections, got {type(data).__name__}"
        )
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


def _bounds(p: dict) -> str:
    """``> 0, <= 1e+04`` from the JSON schema of a number."""
    out = []
    for key, sym in (
        ("exclusiveMinimum", ">"),
        ("minimum", ">="),
        ("exclusiveMaximum", "<"),
        ("maximum", "<="),
    ):
        if key in p:
            v = p[key]
            out.append(f"{sym} {v:g}" if isinstance(v, float) else f"{sym} {v}")
    return ", ".join(out)


def _range_text(prop: dict) -> str:
    """The allowed range of a field: its bounds, those of a ``X | None``, of a tuple's items
    (``each ...`` or ``[i] ...``) or a list's length."""
    rng = _bounds(prop)
    if not rng and "anyOf" in prop:
        rng = " | ".join(b for b in (_bounds(p) for p in prop["anyOf"]) if b)
    items = prop.get("prefixItems")
    if items:
        parts = [_bounds(p) for p in items]
        if len(set(parts)) == 1:
            rng = f"each {parts[0]}" if parts[0] else ""
        else:
            rng = "; ".join(f"[{i}] {b}" for i, b in enumerate(parts) if b)
    elif "minItems" in prop or "maxItems" in prop:
        n = [
            f"{sym} {prop[key]}"
            for key, sym in (("minItems", ">="), ("maxItems", "<="))
            if key in prop
        ]
        rng = ", ".join([rng, "items " + ", ".join(n)] if rng else ["items " + ", ".join(n)])
    return rng


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
        disc = prop.get("discriminator")
        if disc and "oneOf" in prop:  # a choice by tag (friction law, stop rule): each variant's
            tag = disc["propertyName"]
            default = (prop.get("default") or {}).get(tag)
            rows.append((f"{prefix}{name}.{tag}", " | ".join(disc["mapping"]),
                         "required" if default is None else json.dumps(default), "", "",
                         prop.get("description", "")))
            variants = {value: defs[ref.split("/")[-1]].get("properties", {})
                        for value, ref in disc["mapping"].items()}
            # a field every variant has alike (a held body's name) once, the others named
            # after their tag
            first = next(iter(variants.values()))
            common = {k: v for k, v in first.items() if k != tag and all(
                p.get(k) == v for p in variants.values())}
            _rows({"properties": common}, defs, f"{prefix}{name}.", rows)
            for value, props in variants.items():
                sub = {"properties": {k: {**v, "description": f"{tag}: {value}: "
                                                              f"{v.get('description', '')}"}
                                      for k, v in props.items() if k != tag and k not in common}}
                _rows(sub, defs, f"{prefix}{name}.", rows)
            continue
        typ = prop.get("type")
        if typ is None and "anyOf" in prop:
            typ = " | ".join(
                p.get("type", p.get("$ref", "?").split("/")[-1]) for p in prop["anyOf"]
            )
        if "enum" in prop:
            typ = " | ".join(map(str, prop["enum"]))
        if "const" in prop:
            typ = repr(prop["const"])
        rows.append(
            (
                prefix + name,
                str(typ),
                json.dumps(prop.get("default")) if "default" in prop else "required",
                _range_text(prop),
                prop.get("unit", ""),
                prop.get("description", ""),
            )
        )
        items = prop.get("items") if isinstance(prop.get("items"), dict) else {}
        if items.get("$ref"):  # a list of sections (stages): their fields, as name[].field
            _rows(defs[items["$ref"].split("/")[-1]], defs, f"{prefix}{name}[].", rows)
        elif "discriminator" in items:  # a list of tagged entries (held bodies), by their tag
            _rows({"properties": {"": items}}, defs, f"{prefix}{name}[]", rows)


def schema_reference(extra: dict[str, type[BaseModel]] | None = None) -> str:
    """A plain-text reference of every field of every scenario kind (and of the models in
    ``extra``, title -> pydantic class: the sweep file)."""
    lines = []
    sections = [(f"kind: {kind}", cls) for kind, cls in kind_classes().items()] + list(
        (extra or {}).items()
    )
    for title, cls in sections:
        sch = cls.model_json_schema(by_alias=True)
        rows: list = []
        _rows(sch, sch.get("$defs", {}), "", rows)
        lines.append(f"{title}  ({(cls.__doc__ or '').strip().splitlines()[0]})")
        head = ("field", "type", "default", "range", "unit", "description")
        # no column is ever cut (a value list or a bound is part of the contract): each is as
        # wide as its widest entry in the section
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(5)]
        for r in [head, *rows]:
            lines.append("  " + " ".join(f"{r[i]:{w}s}" for i, w in enumerate(widths)) + f" {r[5]}")
        lines.append("")
    return "\n".join(lines)
