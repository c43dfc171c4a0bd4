"""The one dotted path to a scenario field: ``--set``, sweeps and window searches all use it.

A path is keys joined by dots: ``numerics.nodes``, ``physics.friction.mu_s``. A list (the
stages of a forming scenario) is stepped into by the index of an item or by its ``name``,
so ``physics.stages.push_down.clamp_speed_mm_s`` and ``physics.stages.0.clamp_speed_mm_s``
are the same field of ``scenarios/method2_pinned.yaml``.

:func:`set_path` creates the mappings missing along the way (a file may leave a section
out, its defaults apply); it never creates a list item: an index past the end or a name
no item has is bad input. :func:`get_path` raises :class:`KeyError` for a path that is
not there.

Example::

    >>> data = {"physics": {"stages": [{"name": "push_down", "clamp_speed_mm_s": 2.0}]}}
    >>> set_path(data, "physics.stages.push_down.clamp_speed_mm_s", 1.0)
    >>> get_path(data, "physics.stages.0.clamp_speed_mm_s")
    1.0
"""

from __future__ import annotations

from typing import Any

from dynslip.errors import InputError

__all__ = ["split", "get_path", "set_path"]


def split(dotted: str, source: str = "<scenario>") -> list[str]:
    """The keys of a dotted path; :class:`InputError` for an empty key (``a..b``, ``.a``)."""
    keys = str(dotted).split(".")
    if not all(keys):
        raise InputError(f"{source}: field '{dotted}': not a dotted path section.key")
    return keys


def _index(node: list, key: str) -> int:
    """The position of a list item named by its index or by its ``name``; KeyError if none."""
    if key.isdigit() and int(key) < len(node):
        return int(key)
    for i, item in enumerate(node):
        if isinstance(item, dict) and item.get("name") == key:
            return i
    raise KeyError(key)


def _step(node, key: str):
    """One step of a path: a mapping's key, or a list's item by index or by name."""
    if isinstance(node, dict) and key in node:
        return node[key]
    if isinstance(node, list):
        return node[_index(node, key)]
    raise KeyError(key)


def get_path(data, dotted: str) -> Any:
    """The value at ``dotted`` in nested mappings and lists; :class:`KeyError` if absent."""
    node = data
    for key in str(dotted).split("."):
        try:
            node = _step(node, key)
        except KeyError:
            raise KeyError(dotted) from None
    return node


def set_path(data: dict, dotted: str, value: Any, source: str = "<scenario>") -> None:
    """Set the field at ``dotted`` to ``value`` in place; :class:`InputError` (one line
    naming the field and ``source``) when the path leads through something that is not a
    section or names a list item that does not exist."""
    keys = split(dotted, source)
    node = data
    for i, key in enumerate(keys[:-1]):
        if isinstance(node, dict) and node.get(key) is None:
            node[key] = {}  # a section the file leaves out: its defaults apply
        try:
            node = _step(node, key)
        except KeyError:
            raise InputError(
                f"{source}: field '{dotted}' does not exist ('{'.'.join(keys[: i + 1])}' not found)"
            ) from None
        if not isinstance(node, (dict, list)):
            raise InputError(
                f"{source}: field '{dotted}' does not exist ('{key}' is not a section)"
            )
    last = keys[-1]
    if isinstance(node, list):
        try:
            node[_index(node, last)] = value
        except KeyError:
            raise InputError(
                f"{source}: field '{dotted}' does not exist ('{last}' is not an item)"
            ) from None
    else:
        node[last] = value
