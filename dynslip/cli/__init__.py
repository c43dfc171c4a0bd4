"""The ``dynslip`` command line.

Exit status: 0 success; 2 bad input (one line naming the field, the value and what is
allowed; nothing written); 3 a computation that ran and failed (what was computed is
kept in ``<out>.incomplete-<UTC time>/`` marked ``INCOMPLETE``); 130 interrupted by
SIGINT, 143 terminated by SIGTERM (likewise kept, the marker naming the signal).

``--out`` of ``run``, ``sweep`` and ``window`` may be a new folder, an empty one or an
earlier dynslip result (replaced only once the new run succeeded); a folder that is not
a dynslip result needs ``--force``; an existing file is never replaced.

Here, in this order: :func:`main`, which turns errors into exit statuses; the parser
(:func:`build_parser`: the eight commands, every option with its help line (what, unit,
default) and every command with its examples); and the commands (``cmd_<name>``: what each
does with its parsed arguments).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rich.console import Console

from dynslip import _version
from dynslip._jaxconfig import configure_runtime
from dynslip.analysis.windows import MAX_COARSE
from dynslip.app import sizes
from dynslip.app.compare import run_compare
from dynslip.app.drawn import drawn_bodies_at
from dynslip.app.export import run_export
from dynslip.app.fit import FitOptions, run_fit
from dynslip.app.fronts import run_fronts
from dynslip.app.kinds import run_into
from dynslip.app.sweep import run_sweep, validate_sweep
from dynslip.app.window import parse_nodes, run_window, run_window_nodes
from dynslip.data.folders import INCOMPLETE, signal_name, sigterm_raises
from dynslip.data.trajectory import TRAJECTORY_FILE
from dynslip.errors import ComputationError, InputError, MaterialRangeError
from dynslip.plot.animate import animate, parse_size
from dynslip.schema import base as sc
from dynslip.schema.sweep import Linspace, SweepSpec, WindowSpec, is_sweep_file

__all__ = ["build_parser", "main"]


def _kept(err) -> str:
    """Where the partial results of a failed or interrupted run are (from the exception)."""
    kept = getattr(err, "dynslip_kept", None)
    if kept is None:
        return ""
    marked = ", marked INCOMPLETE" if (Path(kept) / INCOMPLETE).is_file() else ""
    return f"{kept}/{marked}"


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    # the platform, XLA's flags, equinox's error mode and the compilation cache: set before
    # any JAX computation (``import dynslip`` sets none of them)
    configure_runtime()
    try:
        with sigterm_raises():  # SIGTERM raises like SIGINT: partial results kept and marked
            return args.fn(args)
    except InputError as err:  # one line, whatever text of the user's the message quotes
        text = str(err).replace("\r", "\\r").replace("\n", "\\n")
        print(f"dynslip: error: {text}", file=sys.stderr)
        return 2
    except (ComputationError, MaterialRangeError) as err:
        print(f"dynslip: computation failed: {err}", file=sys.stderr)
        kept = _kept(err)
        if kept:
            print(f"dynslip: what was computed is kept in {kept}", file=sys.stderr)
        return 3
    except KeyboardInterrupt as err:
        name = signal_name(err)
        kept = _kept(err)
        print(
            f"dynslip: interrupted by {name}"
            + (f"; partial results kept in {kept}" if kept else ""),
            file=sys.stderr,
        )
        return getattr(err, "exit_code", 130)
    except Exception as err:  # a bug: the traceback follows, and where the partial results are
        kept = _kept(err)
        if kept:
            print(
                f"dynslip: unexpected error; what was computed is kept in {kept}", file=sys.stderr
            )
        raise


# The parser: one subcommand each, with its options and examples.


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2 (bad input)."""

    def error(self, message):
        self.exit(2, f"dynslip: error: {message}\n")


def _seconds(text: str) -> float:
    """A positive, finite number of seconds (argparse ``type``: a bad one exits 2)."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (0.0 < v < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r}; allowed: a positive number of seconds")
    return v


class _Version(argparse.Action):
    """``--version``: the version and the commit, asked of git only when given."""

    def __init__(self, option_strings, dest, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(_version.describe())
        parser.exit(0)


FORCE_HELP = (
    "replace a folder at --out that is not a dynslip result (never a file); default: refuse"
)
FORCE_IN_PLACE_HELP = (
    "write into a folder at --out that is not a dynslip result (never a file); default: refuse"
)
SET_HELP = (
    "override a scenario field, SECTION.KEY=VALUE in the file's units (e.g. numerics.nodes=30, "
    "physics.friction.mu_s=1.2, physics.stages.hold.duration_s=5); repeatable; default: none"
)
EPILOGS = {
    "run": """examples:
  dynslip run scenarios/method2_let_go.yaml
  dynslip run scenarios/method2.yaml --set numerics.nodes=30 --out outputs/m2_n30
  dynslip run scenarios/paper_neohookean.yaml --animate""",
    "validate": """examples:
  dynslip validate scenarios/method2.yaml
  dynslip validate scenarios/method2.yaml --set physics.friction.mu_s=1.2
  dynslip validate scenarios/sweep_method2.yaml     (a sweep: every member validated)""",
    "schema": """example:
  dynslip schema | less""",
    "animate": """examples:
  dynslip animate outputs/method2_let_go/trajectory.nc
  dynslip animate outputs/method2_let_go/trajectory.nc --format mp4 --t-start 100 --t-end 160""",
    "fronts": """examples:
  dynslip fronts outputs/method2_let_go/trajectory.nc
  dynslip fronts outputs/method2_let_go/trajectory.nc --rest-speed 1e-4 --out outputs/fronts
  dynslip fronts outputs/method2/trajectory.nc --body 'tube wall'""",
    "sweep": """examples:
  dynslip sweep scenarios/sweep_method2.yaml
  dynslip sweep scenarios/sweep_method2.yaml --mode batched --out outputs/study
  (an interrupted sweep resumes: run the same command again)""",
    "window": """The searched field is physics.friction.mu for the ideal law, else
physics.friction.mu_s with mu_k held at its ratio to mu_s. Defaults come from a sweep's
window section (dynslip schema, "sweep window").

examples:
  dynslip window scenarios/method2_let_go.yaml --lo 1.0 --hi 1.6 --coarse 4 --tol 0.005
  dynslip window scenarios/method2_let_go.yaml --set numerics.nodes=30
  dynslip window scenarios/method2_let_go.yaml --nodes 50,100,200 --lo 1.0 --hi 1.6""",
    "fit": """Observations file: docs/calibration.md (the paper's:
scenarios/observations/paper.yaml).
A coarse scan (--scan values of each parameter over its value x (1 +- --span)) picks the
start on the observations' branch (trapped, past the equator), then Levenberg-Marquardt
with central-difference Jacobians. Writes fit.json, fit.png, optimum/ (the run at the
optimum); a stopped fit resumes from fit_evaluations.json (run the same command again).

examples:
  dynslip fit scenarios/method1.yaml --data OBS.yaml \
      --params physics.material.jm,physics.friction.mu_s
  dynslip fit scenarios/method1.yaml --data OBS.yaml --params physics.friction.mu_s --scan 1""",
    "export": """examples:
  dynslip export outputs/method2_let_go/trajectory.nc
  dynslip export outputs/method2_let_go/trajectory.nc --format xdmf --out outputs/m2_paraview""",
    "compare": """example:
  dynslip compare outputs/method2_let_go outputs/m2_n30 --out outputs/compare""",
}


def _sub(sub, name: str, help: str):  # noqa: A002 - argparse's keyword
    return sub.add_parser(name, help=help, description=help, epilog=EPILOGS[name],
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command; the first line of this module's docstring heads
    ``dynslip --help``."""
    description = __doc__.splitlines()[0].replace("``", "")
    p = _Parser(prog="dynslip", description=description,
                epilog="dynslip COMMAND --help: the options of a command, with examples")
    p.add_argument("--version", action=_Version,
                   help="print the version and the git commit, and exit")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    r = _sub(sub, "run", "run a scenario file")
    r.add_argument("scenario", help="scenario file (YAML, physical units: mm, mm/s, s, MPa)")
    r.add_argument("--out", help="output folder; default outputs/<scenario stem>/")
    r.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help=SET_HELP)
    r.add_argument("--animate", action="store_true",
                   help="also write the animation of the trajectory (forming runs); default: off")
    r.add_argument("--force", action="store_true", help=FORCE_HELP)
    r.set_defaults(fn=cmd_run)

    v = _sub(sub, "validate", "check a scenario or sweep file without running it")
    v.add_argument("scenario", help="scenario or sweep file (YAML)")
    v.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help=SET_HELP)
    v.set_defaults(fn=cmd_validate)

    s = _sub(sub, "schema", "print every scenario field: type, default, range, unit")
    s.set_defaults(fn=cmd_schema)

    a = _sub(sub, "animate", "animate a saved trajectory (GIF or MP4)")
    a.add_argument("trajectory", help="trajectory.nc of a forming run")
    a.add_argument("--out", help="animation file; default animation.<format> beside the trajectory")
    a.add_argument(
        "--fps", type=float, default=10.0, help="frames per second of the animation; default 10"
    )
    a.add_argument(
        "--t-start", type=float, default=None, help="first time shown [s]; default: the first frame"
    )
    a.add_argument(
        "--t-end", type=float, default=None, help="last time shown [s]; default: the last frame"
    )
    a.add_argument(
        "--size", default=None, help="WIDTHxHEIGHT in pixels, e.g. 1280x576; default 960x432"
    )
    a.add_argument(
        "--format", choices=["gif", "mp4"], default="gif", help="file format; default gif"
    )
    a.add_argument("--max-frames", type=int, default=200,
                   help="thin the saved frames evenly to at most this many; default 200")
    a.add_argument(
        "--rest-speed",
        type=float,
        default=None,
        help="show nodes slower than this [R/s] as at rest, whatever the force criterion says; "
        "default: the state flags as saved",
    )
    a.set_defaults(fn=cmd_animate)

    f = _sub(sub, "fronts", "track stick fronts in a saved trajectory")
    f.add_argument("trajectory", help="trajectory.nc of a forming run")
    f.add_argument(
        "--out",
        help="folder for fronts.nc, fronts.png, fronts_summary.json; default: the trajectory's",
    )
    f.add_argument(
        "--rest-speed",
        type=float,
        default=None,
        help="count slipping nodes slower than this [R/s] as at rest; default: the state flags as "
            "saved",
    )
    f.add_argument(
        "--body",
        default=None,
        help="instead of the fronts, draw the state map of this held body (a name of "
        "physics.named_bodies, e.g. 'tube wall') as state_map_<name>.png; default: the fronts",
    )
    f.set_defaults(fn=cmd_fronts)

    w = _sub(sub, "sweep", "run a study over scenario fields")
    w.add_argument(
        "sweep", help="sweep file (YAML: base, grid or list, window, ...; docs/sweeps.md)"
    )
    w.add_argument(
        "--out",
        help="sweep folder (resumed if it holds the sweep); default: the file's out, "
        "else outputs/<sweep stem>/",
    )
    w.add_argument("--mode", choices=["sequential", "batched", "dask"], default=None,
                   help="how members run; default: the file's mode, else sequential")
    w.add_argument(
        "--scheduler",
        default=None,
        help="dask.distributed scheduler address, e.g. tcp://HOST:8786 (implies --mode dask); "
        "default: a local cluster",
    )
    w.add_argument(
        "--connect-timeout",
        type=_seconds,
        default=None,
        metavar="SECONDS",
        help="how long to wait for the --scheduler to answer (default: 10 s)",
    )
    w.add_argument("--force", action="store_true", help=FORCE_IN_PLACE_HELP)
    w.set_defaults(fn=cmd_sweep)

    d = {k: f.default for k, f in WindowSpec.model_fields.items()}  # a sweep window's defaults
    n = _sub(sub, "window", "find the trapping windows of mu for a scenario")
    n.add_argument("scenario", help="scenario file (YAML)")
    n.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help=SET_HELP)
    n.add_argument(
        "--lo",
        type=float,
        default=None,
        help="lower end of the searched friction coefficient (dimensionless, >= 0); "
        f"default {d['lo']:g}",
    )
    n.add_argument(
        "--hi",
        type=float,
        default=None,
        help="upper end of the searched friction coefficient (dimensionless, > lo); "
        f"default {d['hi']:g}",
    )
    n.add_argument(
        "--coarse",
        type=int,
        default=None,
        help="equally spaced scan points on [lo, hi], each a full run (2..1000); "
        f"default {d['coarse']:g}",
    )
    n.add_argument(
        "--tol",
        type=float,
        default=None,
        help="width of the final bracket of each edge (dimensionless, like mu); "
        f"default {d['tol']:g}",
    )
    n.add_argument(
        "--out",
        help="folder for window.json and window.png; default outputs/<scenario stem>_window/",
    )
    n.add_argument("--force", action="store_true", help=FORCE_IN_PLACE_HELP)
    n.add_argument(
        "--nodes",
        default=None,
        metavar="N1,N2,N3",
        help="search at each mesh size (increasing, each 6..4000); window.json gets critical_mu "
        "per N and its extrapolation; default: the scenario's numerics.nodes only",
    )
    n.set_defaults(fn=cmd_window)

    f = _sub(sub, "fit", "fit scenario fields to observations of a pocket")
    f.add_argument("scenario", help="scenario file (YAML, a forming scenario)")
    f.add_argument("--data", required=True, metavar="OBS.yaml",
                   help="observations file (kind: observations; docs/calibration.md); "
                   "required, no default")
    f.add_argument("--params", required=True, metavar="A.B,C.D",
                   help="comma-separated scenario fields to fit (number fields; their bounds "
                   "are the schema's), e.g. physics.material.jm,physics.friction.mu_s; "
                   "required, no default")
    f.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help=SET_HELP)
    f.add_argument("--scan", type=int, default=3,
                   help="values of each parameter in the coarse scan (1..9; 1: start from the "
                   "scenario's values); default 3")
    f.add_argument("--span", type=float, default=0.3,
                   help="the scan's half-width as a fraction of each value (0 < span < 1); "
                   "default 0.3")
    f.add_argument("--max-steps", type=int, default=15,
                   help="Levenberg-Marquardt steps at most (1..200); default 15")
    f.add_argument("--jacobian", choices=["differences", "forward"], default="differences",
                   help="the Jacobian: central differences of forward runs (a step of 1%% of each "
                   "value), or forward-mode sensitivities through the loading path (the release "
                   "force's and the path stretch's rows by differences); default differences")
    f.add_argument("--out", help="folder for fit.json, fit.png and optimum/; default "
                   "outputs/<scenario stem>_fit/")
    f.add_argument("--force", action="store_true", help=FORCE_IN_PLACE_HELP)
    f.set_defaults(fn=cmd_fit)

    c = _sub(sub, "compare", "compare the end states of forming runs")
    c.add_argument("runs", nargs="+", help="run folders (each with trajectory.nc and summary.json)")
    c.add_argument(
        "--out", help="folder for compare.json and compare.png; default outputs/compare/"
    )
    c.set_defaults(fn=cmd_compare)

    x = _sub(sub, "export", "export a saved trajectory for ParaView (VTU series + .pvd, or XDMF)")
    x.add_argument("trajectory", help="a forming run's trajectory.nc")
    x.add_argument("--format", choices=["vtu", "xdmf"], default="vtu",
                   help="vtu: one .vtu per saved frame and a .pvd time series; xdmf: one XDMF "
                   "file with time (the motion as a displacement field); default: vtu")
    x.add_argument("--out", help="output folder; default: <trajectory folder>/paraview/")
    x.add_argument("--force", action="store_true", help=FORCE_HELP)
    x.set_defaults(fn=cmd_export)
    return p


# The commands: what each does with its parsed arguments.


def _console():
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
            path = animate(traj, bodies=drawn_bodies_at(traj))
            console.print(f"animation: {path}")
        else:
            console.print(
                "--animate: this kind of scenario writes no trajectory; nothing to animate"
            )
    return 0


def cmd_validate(args) -> int:
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

    print(sizes.describe())
    return 0


def cmd_animate(args) -> int:
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

    kw["bodies"] = drawn_bodies_at(Path(args.trajectory))
    path = animate(Path(args.trajectory), Path(args.out) if args.out else None, **kw)
    print(f"animation: {path}")
    return 0


def cmd_fronts(args) -> int:
    _check_dir_out(args.out)
    paths = run_fronts(
        Path(args.trajectory), Path(args.out) if args.out else None, rest_speed=args.rest_speed,
        body=args.body,
    )
    for p in paths:
        print(p)
    return 0


def cmd_sweep(args) -> int:
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
    kw = dict(overrides=args.set or [], lo=args.lo, hi=args.hi, coarse=args.coarse, tol=args.tol,
              out=Path(args.out) if args.out else None, console=_console(), force=args.force)
    if args.nodes:
        run_window_nodes(Path(args.scenario), parse_nodes(args.nodes), **kw)
    else:
        run_window(Path(args.scenario), **kw)
    return 0


def cmd_fit(args) -> int:
    params = [p.strip() for p in str(args.params).split(",") if p.strip()]
    run_fit(Path(args.scenario), Path(args.data), params, args.set or [],
            options=FitOptions(scan=args.scan, span=args.span, max_steps=args.max_steps,
                               jacobian=args.jacobian),
            out=Path(args.out) if args.out else None, force=args.force, console=_console())
    return 0


def cmd_compare(args) -> int:
    _check_dir_out(args.out)
    run_compare(
        [Path(p) for p in args.runs], out=Path(args.out) if args.out else None, console=_console()
    )
    return 0


def cmd_export(args) -> int:
    _check_dir_out(args.out)
    print(run_export(Path(args.trajectory), Path(args.out) if args.out else None, fmt=args.format,
                     force=args.force))
    return 0
