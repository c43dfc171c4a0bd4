"""The Python entry points, for notebooks and scripts (docs/python-api.md).

Example::

    import dynslip

    scn = dynslip.load("scenarios/method2_pinned.yaml", set={"numerics.nodes": 20})
    res = dynslip.run(scn)                 # in memory; out="DIR" also writes the usual folder
    res.trajectory                         # xarray.Dataset (docs/trajectory-contract.md)
    res.summary                            # dict, as summary.json
    fig = dynslip.plot.meridian(res.trajectory)
    ds = dynslip.sweep("scenarios/sweep_method2.yaml")   # xarray.Dataset, as sweep.nc
    dynslip.window(scn)                    # the trapping windows, as window.json
    dynslip.api.fit("scenarios/method1.yaml", "OBS.yaml", ["physics.material.jm"])  # fit.json

Bad input raises :class:`~dynslip.errors.InputError` (one line naming the field); a
computation that ran and failed raises :class:`~dynslip.errors.ComputationError` whose
``partial`` holds what was computed (a :class:`RunResult`, a sweep's dataset or a window's
dictionary). Without ``out`` a run writes nothing: its datasets and summary are kept in
memory (no figures are drawn); with ``out`` the folder follows the same rules
as the command line (:mod:`dynslip.data.folders`): checked before anything is computed,
replaced only by a run that succeeded, a failed run kept as ``<out>.incomplete-<time>/``.
"""

from __future__ import annotations

import contextlib
import json
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dynslip.app import kinds
from dynslip.app.fit import FitOptions, run_fit
from dynslip.app.outputs import Outputs
from dynslip.app.sensitivities import Sensitivities
from dynslip.app.sensitivities import sensitivities as _sensitivities
from dynslip.app.sweep import run_sweep
from dynslip.app.window import run_window
from dynslip.data.trajectory import TRAJECTORY_FILE
from dynslip.errors import ComputationError, InputError, MaterialRangeError
from dynslip.schema.base import load as load_scenario

__all__ = ["RunResult", "load", "run", "sensitivities", "sweep", "window", "fit", "InputError",
           "ComputationError"]


@dataclass(frozen=True)
class RunResult:
    """What a run returns: its scenario, summary and datasets, loaded into memory.

    ``trajectory``: the trajectory of a forming run (None for the static kinds);
    ``dataset``: the run's dataset whatever the kind (``trajectory.nc`` or ``result.nc``);
    ``summary``: as ``summary.json`` (NaN written as None); ``out``: the folder the files
    were written to, or None for a run in memory.
    """

    scenario: Any
    summary: dict
    dataset: Any = None
    trajectory: Any = None
    out: Path | None = None


def load(path, set: dict[str, Any] | None = None):  # noqa: A002 - the documented keyword
    """Load and validate a scenario file; ``set``: ``{dotted path: value}`` overrides, the
    paths of ``--set`` (:mod:`dynslip.schema.paths`: lists by index or by name)."""

    return load_scenario(path, values=set)


def _console(console):
    if console is not None:
        return console
    from rich.console import Console

    return Console(quiet=True)


def _read(scn, folder: Path, out: Path | None) -> RunResult:
    """The files a runner wrote into ``folder``, in memory."""
    import xarray as xr

    summary = {}
    if (folder / "summary.json").is_file():
        summary = json.loads((folder / "summary.json").read_text())
    dataset = None
    for name in (TRAJECTORY_FILE, "result.nc"):
        if (folder / name).is_file():
            dataset = xr.load_dataset(folder / name, engine="netcdf4")
            break
    trajectory = dataset if getattr(scn, "kind", None) == "forming" else None
    return RunResult(scenario=scn, summary=summary, dataset=dataset, trajectory=trajectory, out=out)


def _kept(scn, outs) -> RunResult:
    """What a run in memory computed (:class:`dynslip.app.outputs.Outputs` without a folder)."""
    dataset = outs.dataset()
    trajectory = dataset if getattr(scn, "kind", None) == "forming" else None
    return RunResult(scenario=scn, summary=outs.summary or {}, dataset=dataset,
                     trajectory=trajectory, out=None)


def _failed(err: Exception, partial, folder: Path | None = None) -> ComputationError:
    """``err`` as a :class:`ComputationError` carrying ``partial``; a temporary folder named
    in its message is replaced by where the partial result now is."""
    new = err if isinstance(err, ComputationError) else ComputationError(str(err))
    if folder is not None:
        with contextlib.suppress(AttributeError, TypeError):
            new.args = tuple(
                a.replace(str(folder), "<in memory: err.partial>") if isinstance(a, str) else a
                for a in new.args
            )
    new.partial = partial
    return new


def run(scn, out=None, *, force: bool = False, console=None) -> RunResult:
    """Run a scenario (from :func:`load`); return its :class:`RunResult`.

    ``out``: also write the usual run folder there (the command line's rules; ``force``
    replaces a folder that is not a dynslip result). ``console``: a :class:`rich.console.Console`
    for the progress and the summary table (default: quiet).
    """

    console = _console(console)
    if out is not None:
        out = Path(out)
        try:
            kinds.run_into(scn, out, console, force=force)
        except (ComputationError, MaterialRangeError) as err:
            kept = getattr(err, "dynslip_kept", None)
            failed = _failed(err, _read(scn, Path(kept), Path(kept)) if kept is not None else None)
            if failed is err:
                raise
            raise failed from err
        return _read(scn, out, out)
    prepared = kinds.preflight(scn, console)  # bad input before anything runs
    outs = Outputs(None)  # in memory: no file written, none read back
    try:
        kinds.answered(kinds.run(scn, outs, console, prepared))
    except (ComputationError, MaterialRangeError) as err:
        failed = _failed(err, _kept(scn, outs))
        if failed is err:
            raise
        raise failed from err
    return _kept(scn, outs)


def sweep(path, out=None, *, mode: str | None = None, force: bool = False, console=None):
    """Run a sweep file (docs/sweeps.md); return its dataset (``sweep.nc``), in memory.

    ``out``: write (and resume from) the sweep's folder there, as ``dynslip sweep --out``;
    without it the sweep runs in a temporary folder (no resume). When every member failed,
    :class:`ComputationError` carries the dataset (``partial``), with each member's error.
    """
    import xarray as xr


    console = _console(console)

    def go(folder: Path, plot: bool):
        try:
            run_sweep(Path(path), out=folder, mode=mode, console=console, force=force, plot=plot)
        except ComputationError as err:
            nc = folder / "sweep.nc"
            raise _failed(err, xr.load_dataset(nc) if nc.is_file() else None) from None
        return xr.load_dataset(folder / "sweep.nc")

    if out is not None:
        return go(Path(out), True)
    with tempfile.TemporaryDirectory(prefix="dynslip-sweep-") as tmp:
        return go(Path(tmp) / "sweep", False)


def window(scn, *, lo: float | None = None, hi: float | None = None, coarse: int | None = None,
           tol: float | None = None, field: str | None = None, out=None, force: bool = False,
           console=None) -> dict:
    """The trapping windows of a scenario's friction coefficient (:mod:`dynslip.app.window`):
    the dictionary of ``window.json`` (``windows``, every evaluation, failed points).

    ``field``: the swept field (default ``physics.friction.mu``, or ``mu_s`` with ``mu_k``
    tied); ``lo``, ``hi``, ``coarse``, ``tol``: as ``dynslip window``. ``out``: also write
    ``window.json`` and ``window.png`` there.
    """

    console = _console(console)
    data = json.loads(scn.to_json())
    name = scn.name or f"<{scn.kind} scenario>"
    kw = dict(
        lo=lo, hi=hi, coarse=coarse, tol=tol, field=field, console=console, force=force, data=data
    )

    def go(folder: Path):
        try:
            return run_window(name, out=folder, **kw)
        except ComputationError as err:  # every run failed: window.json says why
            found = folder / "window.json"
            err.partial = json.loads(found.read_text()) if found.is_file() else None
            raise

    if out is not None:
        return go(Path(out))
    with tempfile.TemporaryDirectory(prefix="dynslip-window-") as tmp:
        return go(Path(tmp) / "window")


def sensitivities(scn, params, *, step: float | None = None, check: bool = True) -> Sensitivities:
    """The derivatives of a forming run's end-frame scalars in the physical parameters
    ``params`` (dotted paths, as ``--set`` names them), forward mode through the whole loading
    path, every direction at once (docs/sensitivities.md).

    ``scn``: a scenario from :func:`load`, or a path to one. ``step``: the relative step of
    the neighbouring runs that ``check`` makes (default
    :data:`dynslip.app.sensitivities.STEP`) to find a contact set, a stick/slip branch or an
    increment count that changes within the step, and to compare the tangents with central
    differences; where one does, the result's ``defined`` is False and ``reasons`` say why.
    Returns a :class:`dynslip.app.sensitivities.Sensitivities` (``values``, ``jacobian``,
    ``defined``, ``reasons``, ``events``). Bad input raises :class:`InputError`.

    Example::

        sens = dynslip.sensitivities("scenarios/method2_let_go.yaml",
                                     ["physics.material.jm", "physics.friction.mu_s"])
        sens.values["theta_max"], sens.jacobian["theta_max"]   # value, (d/dJ_m, d/dmu_s)
    """
    if isinstance(scn, (str, Path)):
        scn = load(scn)
    kw = {} if step is None else {"step": step}
    return _sensitivities(scn, list(params), check=check, **kw)

def fit(scenario, data, params, *, set: dict[str, Any] | None = None,  # noqa: A002 - as load's
        scan: int = 3, span: float = 0.3, max_steps: int = 15, out=None, force: bool = False,
        console=None, jacobian="differences") -> dict:
    """Fit scenario fields to observations (:mod:`dynslip.app.fit`, docs/calibration.md): the
    dictionary of ``fit.json``. ``scenario``: a scenario file; ``data``: an observations file;
    ``params``: dotted scenario fields; ``set``: overrides as :func:`load`'s. ``out``: the fit's
    folder (its runs kept there, so a stopped fit resumes); without it a temporary folder.
    ``jacobian``: ``"differences"`` (central differences of forward runs, the default),
    ``"forward"`` (forward-mode sensitivities, :func:`sensitivities`) or a provider
    ``(p, model, lo, hi) -> dm/dp``."""
    console = _console(console)
    overrides = [f"{k}={json.dumps(v)}" for k, v in (set or {}).items()]
    opts = dict(scan=scan, span=span, max_steps=max_steps, jacobian=jacobian)
    if out is not None:
        return run_fit(Path(scenario), Path(data), list(params), overrides,
                       options=FitOptions(**opts), out=Path(out), force=force, console=console)
    with tempfile.TemporaryDirectory(prefix="dynslip-fit-") as tmp:
        return run_fit(Path(scenario), Path(data), list(params), overrides,
                       options=FitOptions(**opts, run_optimum=False), out=Path(tmp) / "fit",
                       console=console)
