"""Reading the YAML of scenario and sweep files, and of ``--set`` values.

- Files are read as UTF-8 text; a binary or non-UTF-8 file is bad input (one line).
- A key given twice in one mapping is an error (PyYAML keeps the last one silently).
- Numbers are read as YAML 1.2 reads them: ``1e-5`` is a float (PyYAML's YAML 1.1 rules
  need a dot, ``1.0e-5``, and would give the string "1e-5", which the schema refuses:
  numbers given as text are errors in files).

Every failure raises :class:`dynslip.errors.InputError` with a one-line message.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from dynslip.errors import InputError

__all__ = ["Loader", "parse_value", "parse_yaml", "read_text", "read_yaml"]


class _DuplicateKey(yaml.MarkedYAMLError):
    """A key given twice in one mapping."""


class Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
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
