"""Exceptions that map to the CLI's exit statuses.

- :class:`InputError` (exit 2): bad input; the message is one line naming the field,
  the value and what is allowed.
- :class:`MaterialRangeError` (exit 3): a stretch outside the range where the material's
  energy is defined, met during a computation.
- :class:`ComputationError` (exit 3): a computation ran and did not succeed (solver
  failure, no root in a bracket); what was computed is kept and marked incomplete.
"""


class InputError(ValueError):
    """Bad input: the CLI prints the one-line message and exits with status 2."""

    exit_code = 2


class ComputationError(RuntimeError):
    """A computation that ran and failed: the CLI exits with status 3. ``partial``: what was
    computed before it failed (set by the code that raises or passes it on; None if nothing)."""

    exit_code = 3
    partial = None


#: what a failed run's message ends with, before the path of its partial trajectory
PARTIAL_KEPT = "; partial trajectory kept in "


class MaterialRangeError(ValueError):
    """A stretch lies outside the range where the material's energy is defined."""
