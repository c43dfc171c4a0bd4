"""One member of a study: a scenario given as data, validated and run (sweeps and window
searches both run members; neither imports the other for it)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

__all__ = ["resolve", "default_member_fn"]


def resolve(data: dict, source: str, validate_fn: Callable | None = None) -> dict:
    """Validate scenario data and return the resolved scenario (every default filled in)."""
    if validate_fn is None:
        from dynslip.schema.base import validate_data as validate_fn
    return json.loads(validate_fn(data, source).to_json())


def default_member_fn(data: dict, out_dir: Path, console=None) -> dict:
    """The real member: validate the scenario data and run it into ``out_dir``."""
    from rich.console import Console

    from dynslip.app.kinds import run
    from dynslip.schema.base import validate_data

    return run(validate_data(data, "<member>"), Path(out_dir), console or Console(quiet=True))
