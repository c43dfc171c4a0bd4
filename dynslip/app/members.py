"""One member of a study: a scenario given as data, validated and run (sweeps and window
searches both run members; neither imports the other for it)."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["Member", "resolve", "default_member_fn"]


@dataclass
class Member:
    """A sweep's member: where it sits in the grid, what it assigns, its scenario before and
    after validation, and the fingerprint that names its record file."""

    index: tuple[int, ...]  # grid multi-index, or (list position,)
    assign: dict[str, Any]  # swept field -> value (``base`` included when swept)
    base: Path
    data: dict  # scenario data before validation (base file + overrides + assignments)
    resolved: dict  # validated, every default filled in
    fingerprint: str

    @property
    def key(self) -> str:
        return self.fingerprint[:16]

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.assign.items())


def resolve(data: dict, source: str, validate_fn: Callable | None = None) -> dict:
    """Validate scenario data and return the resolved scenario (every default filled in)."""
    if validate_fn is None:
        # at call time: the tests replace it in its home module
        from dynslip.schema.base import validate_data

        validate_fn = validate_data
    return json.loads(validate_fn(data, source).to_json())


def default_member_fn(data: dict, out_dir: Path, console=None) -> dict:
    """The real member: validate the scenario data and run it into ``out_dir``."""
    from rich.console import Console

    # at call time: the tests replace it in its home module
    from dynslip.app.kinds import run
    from dynslip.schema.base import validate_data

    return run(validate_data(data, "<member>"), Path(out_dir), console or Console(quiet=True))
