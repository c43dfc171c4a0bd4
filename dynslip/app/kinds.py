"""Which runner runs which kind of scenario: schema objects describe, the app runs them.

:data:`RUNNERS` maps a scenario's ``kind`` to ``runner(scenario, out, console) -> summary``
(the runner writes its files into the folder ``out``); :data:`PREFLIGHTS` maps a kind to
what must be made and checked before any output folder is touched (a forming scenario's
world, its memory and its ``start_from``), which the runner then receives as ``prepared``.
:func:`run_into` is the one way a run folder is written, by
``dynslip run`` and by :func:`dynslip.run` with ``out=``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from dynslip.app import forming, static
from dynslip.app.outputs import Outputs
from dynslip.data.folders import StagedRun
from dynslip.errors import ComputationError, InputError

__all__ = ["RUNNERS", "PREFLIGHTS", "runner", "preflight", "run", "run_into"]

RUNNERS: dict[str, Callable] = {
    "static": static.run_static,
    "figure4": static.run_figure4,
    "family": static.run_family,
    "cylinder": static.run_cylinder,
    "forming": forming.run_forming,
}
PREFLIGHTS: dict[str, Callable] = {
    "forming": forming.prepare,
}


def runner(kind: str) -> Callable:
    """The runner of a kind; :class:`InputError` for a kind no runner runs."""
    try:
        return RUNNERS[kind]
    except KeyError:
        raise InputError(f"kind {kind!r}: no runner; allowed: {', '.join(RUNNERS)}") from None


def preflight(scn, console=None):
    """What ``scn``'s kind makes and checks before any output folder (bad input raises
    :class:`InputError` before anything is written): the forming world; None for a kind
    without a preflight."""
    check = PREFLIGHTS.get(scn.kind)
    return None if check is None else check(scn, console)


def run(scn, out, console=None, prepared=None) -> dict:
    """Run ``scn`` into the folder ``out`` (its files written there), or into
    :class:`~dynslip.app.outputs.Outputs` (in memory without a folder); return its summary.
    ``prepared``: what :func:`preflight` returned, handed to the runner."""
    out = out if isinstance(out, Outputs) else Path(out)
    if prepared is None:
        return runner(scn.kind)(scn, out, console)
    return runner(scn.kind)(scn, out, console, prepared)


def _inside(path, folder: Path) -> bool:
    try:
        Path(path).resolve().relative_to(folder.resolve())
        return True
    except (ValueError, OSError, RuntimeError):
        return False


def run_into(
    scn, out, console, *, force: bool = False, source=None, header: str | None = None
) -> dict:
    """Run ``scn`` into the run folder ``out`` under the rules of :mod:`dynslip.data.folders`:
    ``out`` is checked before anything is computed or created; the run writes into a staging
    folder that replaces ``out`` only on success; a failed or interrupted run is kept as
    ``<out>.incomplete-<UTC time>/``. ``source``: the scenario file, which ``out`` must not
    hold; ``header``: printed once the checks have passed."""

    out = Path(out)
    staged = StagedRun(out, force=force)
    staged.check()  # before anything is computed or created
    if source is not None and out.is_dir() and _inside(source, out):
        raise InputError(
            f"--out {str(out)!r}: holds the scenario file {str(source)!r}, which replacing "
            "the folder would delete; allowed: a folder that does not hold the scenario"
        )
    # bad input found before anything is written (e.g. a start_from file)
    prepared = preflight(scn, console)
    with staged as staging:
        if header is not None:
            console.print(header)
        return answered(run(scn, staging, console, prepared))


def answered(summary):
    """``summary`` of a run that answered; a forming run whose trapped is unknown raises
    :class:`ComputationError` with every reason (exit 3: a computation that did not give its
    answer; the caller keeps its files as an incomplete run)."""
    why = summary.get("trapped_unknown_reasons") if isinstance(summary, dict) else None
    if why and summary.get("status") == "ok":
        raise ComputationError("trapped: unknown: " + "; ".join(why))
    return summary
