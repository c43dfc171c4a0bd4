"""Exceptions that map to the CLI's exit statuses.

- :class:`InputError` (exit 2): bad input; the message is one line naming the field,
  the value and what is allowed.
- :class:`MaterialRangeError` (exit 3): a stretch outside the range where the material's
  energy is defined, met during a computation.
- :class:`ComputationError` (exit 3): a computation ran and did not succeed (solver
  failure, no root in a bracket); what was computed is kept and marked incomplete.
"""

from typing import Any


class InputError(ValueError):
    """Bad input: the CLI prints the one-line message and exits with status 2."""

    exit_code = 2


class ComputationError(RuntimeError):
    """A computation that ran and failed: the CLI exits with status 3. ``partial``: what was
    computed before it failed (set by the code that raises or passes it on; None if nothing)."""

    exit_code = 3
    partial: Any = None  # a dict, a dataset or a run record, by the code that raises


#: what a failed run's message ends with, before the path of its partial trajectory
PARTIAL_KEPT = "; partial trajectory kept in "


def run_not_kept(err: ComputationError) -> ComputationError:
    """``err`` of a run whose folder is then discarded (a window search's member): the path of
    its partial trajectory left out of the reason, so that the record is the same wherever it
    is computed."""
    why, kept, _ = str(err).partition(PARTIAL_KEPT)
    new = ComputationError(f"{why} (the member's run is not kept)" if kept else why)
    new.partial = err.partial
    return new


class MaterialRangeError(ValueError):
    """A stretch lies outside the range where the material's energy is defined."""
