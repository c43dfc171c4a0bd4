"""The ``dynslip`` commands: what each does with its parsed arguments (:mod:`dynslip.cli`)."""

from __future__ import annotations

import time
from pathlib import Path

from dynslip.data.trajectory import TRAJECTORY_FILE
from dynslip.errors import InputError


def _console():
    from rich.console import Console

    return Console(stderr=False, highlight=False)


def _default_out(scenario_path: str, out: str | None) -> Path:
    return Path(out) if out else Path("outputs") / Path(scenario_path).stem


def _check_dir_out(out: str | None) -> None:
    """``--out`` names a folder: an existing file (or a file above it) is bad input."""
    if out is None:
        return
    p = Path(out)
    for q in (p, *p.parents):
        if q.exists() and not q.is_dir():
            where = "an existing file" if q == p else f"{str(q)!r} is a file, not a folder"
            raise InputError(f"--out {out!r}: {where}; allowed: a folder (new or existing)")


def _check_file_out(out: str | None) -> None:
    """``--out`` names a file: an existing folder (or a file above it) is bad input."""
    if out is None:
        return
    p = Path(out)
    if p.is_dir():
        raise InputError(
            f"--out {out!r}: an existing folder; allowed: a file name (e.g. animation.gif)"
        )
    for q in p.parents:
        if q.exists() and not q.is_dir():
            raise InputError(
                f"--out {out!r}: {str(q)!r} is a file, not a folder; allowed: a file in a folder"
            )


def cmd_run(args) -> int:
    from dynslip.app.kinds import run_into
    from dynslip.schema import base as sc

    scn = sc.load(args.scenario, args.set or [])
    out = _default_out(args.scenario, args.out)
    console = _console()
    t0 = time.perf_counter()
    run_into(scn, out, console, force=args.force, source=args.scenario,
             header=f"[bold]dynslip run[/bold] {args.scenario} (kind: {scn.kind}) -> {out}/")
    console.print(f"done in {time.perf_counter() - t0:.1f} s; results in {out}/")
    if getattr(args, "animate", False):
        traj = out / TRAJECTORY_FILE
        if traj.exists():
            from dynslip.app.drawn import drawn_bodies_at
            from dynslip.plot.animate import animate

            path = animate(traj, bodies=drawn_bodies_at(traj))
            console.print(f"animation: {path}")
        else:
            console.print(
                "--animate: this kind of scenario writes no trajectory; nothing to animate"
            )
    return 0


def cmd_validate(args) -> int:
    from dynslip.app.sweep import validate_sweep
    from dynslip.schema import base as sc
    from dynslip.schema.sweep import is_sweep_file

    if is_sweep_file(args.scenario):
        if args.set:
            raise InputError(
                f"--set: {args.scenario}: a sweep file; allowed: --set with a scenario file "
                "(a sweep sets fields in its 'overrides')"
            )
        members = validate_sweep(args.scenario)
        print(f"{args.scenario}: valid (sweep of {len(members)} members, every member validated)")
        return 0
    scn = sc.load(args.scenario, args.set or [])
    print(f"{args.scenario}: valid (kind: {scn.kind})")
    return 0


def cmd_schema(args) -> int:
    from dynslip.analysis.windows import MAX_COARSE
    from dynslip.schema import base as sc
    from dynslip.schema.sweep import Linspace, SweepSpec, WindowSpec

    print(
        sc.schema_reference(
            {
                "sweep file": SweepSpec,
                "sweep grid axis {start, stop, num}": Linspace,
                "sweep window (also `dynslip window --lo --hi --coarse --tol`)": WindowSpec,
            }
        )
    )
    print(f"dynslip window: --coarse 2..{MAX_COARSE}; --tol finite, >= 1e-9 max(1, |lo|, |hi|); "
          "lo, hi finite with lo < hi, each a valid value of the friction field")
    from dynslip.app.sizes import describe

    print(describe())
    return 0


def cmd_animate(args) -> int:
    from dynslip.plot.animate import animate, parse_size

    kw = {
        "fps": args.fps,
        "fmt": args.format,
        "max_frames": args.max_frames,
        "rest_speed": args.rest_speed,
    }
    if args.t_start is not None or args.t_end is not None:
        kw["t_range"] = (args.t_start, args.t_end)
    if args.size:
        kw["size"] = parse_size(args.size)
    _check_file_out(args.out)
    from dynslip.app.drawn import drawn_bodies_at

    kw["bodies"] = drawn_bodies_at(Path(args.trajectory))
    path = animate(Path(args.trajectory), Path(args.out) if args.out else None, **kw)
    print(f"animation: {path}")
    return 0


def cmd_fronts(args) -> int:
    from dynslip.app.fronts import run_fronts

    _check_dir_out(args.out)
    paths = run_fronts(
        Path(args.trajectory), Path(args.out) if args.out else None, rest_speed=args.rest_speed,
        body=args.body,
    )
    for p in paths:
        print(p)
    return 0


def cmd_sweep(args) -> int:
    from dynslip.app.sweep import run_sweep

    run_sweep(
        Path(args.sweep),
        out=Path(args.out) if args.out else None,
        mode=args.mode,
        scheduler=args.scheduler,
        connect_timeout=args.connect_timeout,
        console=_console(),
        force=args.force,
    )
    return 0


def cmd_window(args) -> int:
    from dynslip.app.window import parse_nodes, run_window, run_window_nodes

    kw = dict(overrides=args.set or [], lo=args.lo, hi=args.hi, coarse=args.coarse, tol=args.tol,
              out=Path(args.out) if args.out else None, console=_console(), force=args.force)
    if args.nodes:
        run_window_nodes(Path(args.scenario), parse_nodes(args.nodes), **kw)
    else:
        run_window(Path(args.scenario), **kw)
    return 0


def cmd_compare(args) -> int:
    from dynslip.app.compare import run_compare

    _check_dir_out(args.out)
    run_compare(
        [Path(p) for p in args.runs], out=Path(args.out) if args.out else None, console=_console()
    )
    return 0


def cmd_export(args) -> int:
    from dynslip.app.export import run_export

    _check_dir_out(args.out)
    print(run_export(Path(args.trajectory), Path(args.out) if args.out else None, fmt=args.format,
                     force=args.force))
    return 0
