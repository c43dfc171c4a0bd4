"""Make every measured table of docs/ and the README from the code: one command.

    python docs/results.py                     # rerun every table that is not slow, rewrite it
    python docs/results.py selection_rule      # only this one (a named table runs, slow or not)
    python docs/results.py --slow              # the window searches at N = 200 too
    python docs/results.py --small             # each at a small mesh: printed, nothing rewritten
    python docs/results.py --check             # no run: the tables measured before a code change
    python docs/results.py --unmarked          # no run: tables of numbers outside the manifest
    python docs/results.py --mark-outdated     # no run: stale tables say they are not today's

:data:`TABLES` is the manifest: each measured table of the docs, the markdown file it lies
in, the commands that measure it, the function of this module that turns their output
folders into the table's rows, the arguments (or commands) that make the small-mesh variant
the suite runs, whether it is slow, and the files of the package it depends on. A command is
a ``dynslip`` command line or a script of docs/ or benchmarks/ (the benchmark harness for the
timings of docs/speed.md), either led by ``NAME=value`` settings of the environment; a
command two tables share runs once (:func:`run_command`). A run that answers "unknown" (exit
3) is a result: its kept folder is read. In its file a table lies between two markers, with
its provenance line under it::

    <!-- results:NAME -->
    | ... the table ... |

    Measured at 876967b, 2026-01-02 10:00 UTC, by `python docs/results.py NAME`
    (`dynslip run scenarios/...`); key: 0123456789ab.
    <!-- /results:NAME -->

Everything between the markers is rewritten. The key is :func:`key` of what the table
depends on: the package's source files (:data:`PACKAGE`, less :data:`NOT_PHYSICS`: the
plotting, the command line and the end-of-run table print nothing into a table) and the
scenario files its commands read, each file hashed, combined in sorted path order. A table
whose recorded key differs from today's is stale (``--check``; ``tests/test_docs.py``), unless
it says so under its provenance line, naming today's key (``--mark-outdated``: a table not
measured again after a change, shown as such rather than as today's).
:data:`REFERENCE` lists the tables with digits that are not measured (the commands, the
schema's fields and units), each with its reason; every other table of numbers in the docs
must be under the manifest.

docs/figures.py stamps its figures with a key computed the same way (:func:`files_key`).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import shlex
import subprocess
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ("README.md", "docs/*.md")

#: the package's source files that a measured number can depend on ...
PACKAGE = ("dynslip/**/*.py",)
#: ... less those that only draw, parse the command line or print the end-of-run table
NOT_PHYSICS = ("dynslip/plot/**", "dynslip/cli/**", "dynslip/app/endtable.py")
KEY_LEN = 12


# --- the key -----------------------------------------------------------------------------


def source_files(include: Iterable[str] = PACKAGE, exclude: Iterable[str] = NOT_PHYSICS
                 ) -> list[Path]:
    """The files under the root matching a glob of ``include`` and none of ``exclude``."""
    out = set()
    for pattern in include:
        out |= {p for p in ROOT.glob(pattern) if p.is_file() and "__pycache__" not in p.parts}
    return sorted(
        p for p in out if not any(p.relative_to(ROOT).match(x) or _under(p, x) for x in exclude)
    )


def _under(path: Path, pattern: str) -> bool:
    """``dir/**`` matches every file below ``dir`` (``Path.match`` reads ``**`` as ``*``)."""
    return pattern.endswith("/**") and (ROOT / pattern[:-3]) in path.parents


def scenario_files(scenarios: Iterable[str | Path]) -> list[Path]:
    """The scenario files and every file they name (``start_from``, a sweep's ``base`` and
    ``grid.base``: any string value ending in .yaml, relative to the file's folder), followed
    to the end."""
    import yaml

    todo, seen = [ROOT / s for s in scenarios], set()
    while todo:
        p = todo.pop().resolve()
        if p in seen or not p.is_file():
            continue
        seen.add(p)
        if p.suffix in (".yaml", ".yml"):
            todo += [p.parent / v for v in _strings(yaml.safe_load(p.read_text()))
                     if v.endswith((".yaml", ".yml"))]
    return sorted(seen)


def _strings(data) -> Iterable[str]:
    if isinstance(data, str):
        yield data
    elif isinstance(data, dict):
        for v in data.values():
            yield from _strings(v)
    elif isinstance(data, list):
        for v in data:
            yield from _strings(v)


def files_key(files: Iterable[Path], extra: str = "") -> str:
    """sha256 over ``path NUL sha256(content)`` of each file in sorted path order (then
    ``extra``, what is not in a file: a run's ``--set`` fields), first :data:`KEY_LEN` hex."""
    h = hashlib.sha256()
    for p in sorted({Path(f).resolve() for f in files}):
        try:
            digest = _digest(p)
        except FileNotFoundError:  # removed since it was listed: not part of the code now
            continue
        h.update(f"{p.relative_to(ROOT).as_posix()}\0{digest}\n".encode())
    h.update(extra.encode())
    return h.hexdigest()[:KEY_LEN]


_DIGESTS: dict[tuple, str] = {}


def _digest(p: Path) -> str:
    """sha256 of a file's content, remembered while its size and modification time stay."""
    st = p.stat()
    k = (p, st.st_size, st.st_mtime_ns)
    if k not in _DIGESTS:
        _DIGESTS[k] = hashlib.sha256(p.read_bytes()).hexdigest()
    return _DIGESTS[k]


def commit() -> str:
    """``git rev-parse --short HEAD``, with ``-dirty`` when a tracked file differs from it."""
    def git(*a):
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True)

    head = git("rev-parse", "--short", "HEAD").stdout.strip() or "unknown"
    return head + ("-dirty" if git("diff", "--quiet", "HEAD").returncode else "")


# --- the manifest --------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """One measured table. A command is ``dynslip ...`` (run in this process with ``--out
    DIR``) or ``python SCRIPT ...`` (a script of docs/ or benchmarks/, run in a subprocess
    whose working folder is DIR, so its ``outputs/`` land there), either led by ``NAME=value``
    settings of the environment (then a ``dynslip`` command runs in a subprocess too;
    ``{tmp}`` in a value is a folder of the table's own, the same for all its commands)."""

    doc: str  # the markdown file, from the root
    header: tuple[str, ...]  # the table's columns
    commands: tuple[str, ...]  # the commands that measure it
    rows: Callable[[list[Path]], list[list[str]]]  # run folders -> the rows, one cell a string
    small: str  # the small-mesh variant: NAME=value words set the environment of each
    #            command, the other words are appended to each dynslip command
    slow: bool = False  # run only when asked (--slow or by name)
    depends: tuple[str, ...] = PACKAGE  # the package files it depends on (globs) ...
    exclude: tuple[str, ...] = NOT_PHYSICS  # ... less these
    reads: tuple[str, ...] = ()  # other files it reads, when no command names them
    small_commands: tuple[str, ...] | None = None  # the small variant's, when not ``commands``
    small_quick: bool = False  # its small variant runs in the quick suite even when it is slow

    def scenarios(self) -> list[str]:
        """The scenario and sweep files its ``dynslip`` commands name."""
        from dynslip.cli import build_parser

        parser, out = build_parser(), []
        for cmd in self.commands:
            _env, words = split_command(cmd)
            if words[0] != "dynslip":
                continue
            args = parser.parse_args(words[1:])
            out += [v for a in ("scenario", "sweep") if (v := getattr(args, a, None))]
        return out

    def key(self) -> str:
        files = source_files(self.depends, self.exclude)
        scripts = [w[1] for c in self.commands if (w := split_command(c)[1])[0] == "python"]
        return files_key([*files, *scenario_files([*self.scenarios(), *self.reads, *scripts])])


ENV_WORD = re.compile(r"^[A-Z_][A-Z0-9_]*=")


def split_command(cmd: str) -> tuple[dict[str, str], list[str]]:
    """A command's leading ``NAME=value`` settings and its words."""
    words = shlex.split(cmd)
    env = {}
    while words and ENV_WORD.match(words[0]):
        name, value = words.pop(0).split("=", 1)
        env[name] = value
    return env, words


def _figure4_summary(run: Path) -> tuple[dict, dict]:
    import xarray as xr

    with xr.open_dataset(run / "result.nc") as ds:
        scenario = json.loads(ds.attrs["scenario"])
    return json.loads((run / "summary.json").read_text()), scenario


def selection_rule_rows(runs: list[Path]) -> list[list[str]]:
    """The selected member of each model (the boundary-value problem: mu, switch angle, pole
    stretch) against the paper, and the largest lambda_theta on the grid after the march and
    search; a difference over 5% in bold (the page's claim is "within 5%")."""
    from dynslip.analysis.paper import MODEL_LABELS

    summary, scenario = _figure4_summary(runs[0])
    rows = []
    for m in summary["models"]:
        label = MODEL_LABELS[m["model"]]
        if m["model"] == "gent":
            label += f" (J_m = {scenario['physics']['jm']:g})"
        diff = f"{m['mu_family_vs_paper_percent']:+.1f}%"
        if abs(m["mu_family_vs_paper_percent"]) > 5.0:
            diff = f"**{diff}**"
        rows.append([label, f"{m['mu_family']:.4f}", f"{m['paper_mu']:g}", diff,
                     f"{m['switch_theta']:.3f}", f"{m['pole_stretch']:.3g}",
                     f"{m['lambda_theta_max']:.1f}"])
    return rows


# --- reading run folders into cells ----------------------------------------------------------


def summary(run: Path) -> dict:
    """A run folder's summary.json ({} without one)."""
    f = run / "summary.json"
    return json.loads(f.read_text()) if f.is_file() else {}


def window_json(run: Path) -> dict:
    """A ``dynslip window`` folder's window.json ({} without one)."""
    f = run / "window.json"
    return json.loads(f.read_text()) if f.is_file() else {}


def bench(run: Path, part: str) -> dict:
    """What ``python benchmarks/run.py PART`` wrote in its working folder."""
    return json.loads((run / "outputs" / "benchmarks" / f"{part}.json").read_text())


def dig(d, dotted: str):
    """``d["a"]["b"]`` for ``"a.b"``; None where a key is missing."""
    for k in dotted.split("."):
        d = d.get(k) if isinstance(d, dict) else None
    return d


def num(v, spec: str = ".3g") -> str:
    """A number as text; "-" for None or not finite."""
    if v is None or isinstance(v, str) or (isinstance(v, float) and v != v) or v in (
            float("inf"), float("-inf")):
        return "-" if v is None or not isinstance(v, str) else v
    return format(v, spec)


def yes(v) -> str:
    return {True: "yes", False: "no"}.get(v, "unknown")


def S(dotted: str, spec: str = ".3g") -> Callable[[Path], str]:
    """The cell of a summary field."""
    return lambda run: num(dig(summary(run), dotted), spec)


def TRAPPED(run: Path) -> str:  # noqa: N802  (a cell, named like the other column readers)
    return yes(summary(run).get("trapped"))


def STEPS(run: Path) -> str:  # noqa: N802
    s = summary(run).get("solver", {})
    return f"{s.get('steps', '-')} ({s.get('rejected', '-')})"


def RESIDUAL(run: Path) -> str:  # noqa: N802
    return num(dig(summary(run), "energy_balance.relative_residual"), ".2g")


def each_run(labels, *cells: Callable[[Path], str], per_row: int = 1, join: str = " / "):
    """Rows of ``labels[i]`` (the row's fixed cells) then one cell per column reader, read off
    the row's ``per_row`` consecutive run folders and joined by ``join``."""
    def rows(runs: list[Path]) -> list[list[str]]:
        chunks = [runs[i : i + per_row] for i in range(0, len(runs), per_row)]
        return [[*lab, *(join.join(c(r) for r in ch) for c in cells)]
                for lab, ch in zip(labels, chunks, strict=True)]
    return rows


def cmds(template: str, *values) -> tuple[str, ...]:
    """``template.format(*v)`` (or ``**v`` for a dict) for each ``v`` of ``values``."""
    return tuple(template.format(**v) if isinstance(v, dict) else
                 template.format(*(v if isinstance(v, tuple) else (v,))) for v in values)


# --- the speed tables (docs/speed.md) ----------------------------------------------------------

SPEED_NODES = (50, 100, 200, 400, 800)


def speed_scaling_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "speed")
    rows = []
    for k in sorted((k for k in b if k[:1] == "N" and k[1:].isdigit()), key=lambda k: int(k[1:])):
        ls = b[k]["load_step"]
        its = ls["newton_iterations"]
        rows.append([k[1:], f"{ls['steps']} ({ls['rejected']})", f"{its}",
                     num(ls["newton_per_step"], ".2f"), num(ls["compile_s"], ".1f"),
                     num(ls["run_s"], ".3f"), num(ls["ms_per_step"], ".2f"),
                     num(1e3 * ls["run_s"] / its, ".3f"), yes(ls["trapped"]),
                     num(ls["theta_max"], ".4f")])
    return rows


def speed_kvaerno5_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "speed")
    (k,) = [k for k in b if k[:1] == "N" and k[1:].isdigit()]
    row, ag = b[k], b[k]["load_step_vs_kvaerno5"]
    out = []
    for solver, ratio in (("load_step", "1"), ("kvaerno5", num(row["speedup_vs_kvaerno5"], ".1f"))):
        r = row[solver]
        out.append([solver, k[1:], f"{r['steps']} ({r['rejected']})", num(r["run_s"], ".3f"),
                    ratio, yes(r["trapped"]), num(r["theta_max"], ".4f"),
                    num(ag["max_abs_dtheta_contact"], ".1e") if solver == "kvaerno5" else "-"])
    return out


def main_job_rows(runs: list[Path]) -> list[list[str]]:
    out = []
    for label, run in zip(("cold (empty cache)", "warm (cache filled by the first)"), runs,
                          strict=True):
        s = summary(run).get("solver", {})
        out.append([label, num(RUNS[run]["wall_s"], ".1f"), num(s.get("compile_s"), ".1f"),
                    num(s.get("run_s"), ".2f"), f"{s.get('steps')} ({s.get('rejected')})",
                    f"{s.get('newton_iterations')}", num(s.get("time_per_step_ms"), ".2f")])
    return out


def driver_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "driver")
    return [[k[1:], f"{r['segments']}", f"{r['steps']}", num(r["wall_s"], ".3f"),
             num(r["run_s"], ".3f"), num(r["host_s"], ".3f"),
             num(r["host_ms_per_segment"], ".2f"), num(100 * r["host_share"], ".0f") + "%"]
            for k, r in sorted(((k, v) for k, v in b.items() if k[:1] == "N"),
                               key=lambda kv: int(kv[0][1:]))]


SPEED = {
    "speed_let_go": Table(
        doc="docs/speed.md",
        header=("N", "increments (rejected)", "Newton iterations", "per increment",
                "compile s (cold)", "run s", "ms per increment", "ms per Newton iteration",
                "trapped", "theta_max"),
        commands=("DYNSLIP_CACHE_DIR={tmp} DYNSLIP_BENCH_SPEED_SOLVERS= "
                  "DYNSLIP_BENCH_SPEED_NODES=" + ",".join(map(str, SPEED_NODES))
                  + " python benchmarks/run.py speed",),
        rows=speed_scaling_rows,
        small="DYNSLIP_BENCH_SPEED_NODES=12,14,16,18,20",
        slow=True,
        reads=("benchmarks/method2_let_go.yaml", "benchmarks/speed.py"),
    ),
    "speed_kvaerno5": Table(
        doc="docs/speed.md",
        header=("solver", "N", "steps (rejected)", "run s", "run s / load_step's", "trapped",
                "theta_max", "max abs dtheta on the common contact (rad)"),
        commands=("DYNSLIP_BENCH_SPEED_LAW=coulomb DYNSLIP_BENCH_SPEED_SOLVERS=kvaerno5 "
                  "DYNSLIP_BENCH_SPEED_NODES=200 python benchmarks/run.py speed",),
        rows=speed_kvaerno5_rows,
        small="DYNSLIP_BENCH_SPEED_NODES=16",
        slow=True,
        reads=("benchmarks/method2_let_go.yaml", "benchmarks/speed.py"),
    ),
    "speed_main_job": Table(
        doc="docs/speed.md",
        header=("cache", "wall s (the whole command)", "compile s", "run s (the segments)",
                "increments (rejected)", "Newton iterations", "ms per increment"),
        commands=("DYNSLIP_CACHE_DIR={tmp} dynslip run scenarios/method2.yaml",) * 2,
        rows=main_job_rows,
        small="--set numerics.nodes=20",
        slow=True,
    ),
    "speed_driver": Table(
        doc="docs/speed.md",
        header=("N", "save segments", "increments", "wall s (warm)", "run s (the segments)",
                "host s", "host ms per segment", "host share"),
        commands=("DYNSLIP_BENCH_DRIVER_NODES=50,200 python benchmarks/run.py driver",),
        rows=driver_rows,
        small="DYNSLIP_BENCH_DRIVER_NODES=12,16",
        slow=True,
        reads=("benchmarks/method2_let_go.yaml", "benchmarks/driver.py"),
    ),
}


# --- trajectories and the experiment's study ------------------------------------------------


def trajectory(run: Path):
    """A run folder's trajectory dataset, loaded (None without one)."""
    import xarray as xr

    f = run / "trajectory.nc"
    if not f.is_file():
        return None
    with xr.open_dataset(f) as ds:
        return ds.load()


def stage_end(ds, stage: str) -> int | None:
    """The last frame of stage ``stage`` (None when it did not run)."""
    import numpy as np

    names = json.loads(ds.attrs["stage_names"]) if isinstance(ds.attrs.get("stage_names"),
                                                                 str) else None
    names = names or list(ds.attrs.get("stage_names", []))
    if stage not in names:
        return None
    at = np.flatnonzero(ds["stage"].values == names.index(stage))
    return int(at[-1]) if at.size else None


def at_stage_end(stage: str, var: str, spec: str = ".3f") -> Callable[[Path], str]:
    """The cell of ``var`` at the end of ``stage`` ("-" when no contact is left)."""
    def cell(run: Path) -> str:
        ds = trajectory(run)
        i = None if ds is None else stage_end(ds, stage)
        if i is None or float(ds["rbar_max"].values[i]) <= 0.0:
            return "-"
        return num(float(ds[var].values[i]), spec)
    return cell


def _study():
    """docs/experiment_study.py, the experiment's study (its data and formatting)."""
    import importlib.util
    import sys

    if "docs_experiment_study" not in sys.modules:
        spec = importlib.util.spec_from_file_location("docs_experiment_study",
                                                      ROOT / "docs" / "experiment_study.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
    return sys.modules["docs_experiment_study"]


def deepest(key: str, spec: str = ".3g") -> Callable[[Path], str]:
    """The cell of the study's ``span_geometry`` of a run: the lip at the deepest push."""
    def cell(run: Path) -> str:
        g = _study().span_geometry(run) or {}
        return num(g.get(key), spec)
    return cell


def BOTTOM(run: Path) -> str:  # noqa: N802
    """theta_max / rbar_max at the deepest push."""
    return f"{deepest('deepest_theta_max', '.3f')(run)} / {deepest('deepest_rbar_max', '.3f')(run)}"


def study_answer_rows(_runs: list[Path]) -> list[list[str]]:
    st = _study()
    rows = []
    for key, row in st._ordered(st._load().get("jm", {})):
        path, mat = key.split(" | ")
        trapped = {True: "**yes**", False: "no"}.get(row["measured"]["trapped"], "unknown")
        rows.append([path, mat, st._crit(row["window"]["window"], brackets=True), trapped])
    return rows


def study_jm_rows(_runs: list[Path]) -> list[list[str]]:
    st = _study()
    rows = []
    for key, row in st._ordered(st._load().get("jm", {})):
        path, mat = key.split(" | ")
        m = row["measured"]
        rows.append([path, mat, st._crit(row["window"]["window"]), yes(m["trapped"]),
                     f"{st._f(m['largest_stretch'])} ({st._f(m['largest_stretch_i1_uniaxial'])})",
                     f"`{row['window']['command']}`"])
    return rows


def study_depth_rows(_runs: list[Path]) -> list[list[str]]:
    st = _study()
    rows = []
    for key, m in st._ordered(st._load().get("depth", {})):
        d, mat = key.split(" | ")
        g = st.span_geometry(st.OUT / st._slug("d", int(d.split()[0]), mat)) or {}
        bottom = (f"{st._f(g.get('deepest_theta_max'))} / {st._f(g.get('deepest_rbar_max'))}, "
                  f"{st._f(g.get('span_angle_deg'), '.0f')} deg, {st._f(g.get('neck_rho'))} R")
        rows.append([d, mat, yes(m["trapped"]), bottom,
                     f"{st._f(m['theta_max'])} / {st._f(m['rbar_max'])}",
                     f"{st._f(m['largest_stretch'])} ({st._f(m['largest_stretch_i1_uniaxial'])})",
                     f"`{m['command']}`"])
    return rows


def study_release_rows(_runs: list[Path]) -> list[list[str]]:
    st = _study()
    return [[key, f"{st._f(m['release_force_N'], '.2f')} N", f"`{m['command']}`"]
            for key, m in sorted(st._load().get("release", {}).items(),
                                 key=lambda kv: int(kv[0].split()[-1]))]


STUDY_READS = ("scenarios/method2.yaml", "scenarios/method1.yaml",
               "scenarios/method2_let_go.yaml", "scenarios/release_pull_tube.yaml")


def _study_table(doc: str, header: tuple[str, ...], what: str, rows) -> Table:
    """A table of docs/experiment_study.py: the study runs its commands (window searches at
    N = 150 and 200: hours) and records them in docs/data/experiment_study/WHAT.json, which
    the rows read (a file per part: rerunning one part stales its own tables only). It has no
    small mesh: the small variant formats the recorded study
    (``experiment_study.py answer``), so the suite checks the reading, not the runs."""
    return Table(doc=doc, header=header, commands=(f"python docs/experiment_study.py {what}",),
                 rows=rows, small="", slow=True,
                 reads=(*STUDY_READS, f"docs/data/experiment_study/{what}.json"),
                 small_quick=True,
                 small_commands=("python docs/experiment_study.py answer",))


# --- windows ---------------------------------------------------------------------------------


def crit_cells(runs: list[Path], n: int) -> tuple[str, str]:
    """(critical mu, +-) at mesh size ``n`` of the window folders ``runs``."""
    for r in runs:
        c = (window_json(r).get("critical_mu") or {}).get(str(n))
        if c:
            return num(c["value"], ".4f"), num(c["err"], ".4f")
        if str(n) in (window_json(r).get("critical_mu") or {}):
            return "none", "-"
    return "-", "-"


def windows_text(w: dict, n: int | None = None) -> str:
    """The trapping windows of a window.json at mesh size ``n`` (the finest by default)."""
    wins = w.get("windows") or {}
    if not wins:
        return "-" if "windows" not in w else "none"
    if isinstance(wins, list):  # one mesh size (no --nodes): the windows themselves
        found = wins
    else:
        n = n or max(int(k) for k in wins)
        found = wins.get(str(n)) or []
    return ", ".join(f"[{a:.3f}, {b:.3f}]" for a, b in found) or "none"


def converged_rows(ratio: float):
    """Rows ``N | mu_c | +- | mu_k at mu_c`` of a ``--nodes`` window, and its extrapolation."""
    def rows(runs: list[Path]) -> list[list[str]]:
        w = window_json(runs[0])
        out = []
        for n in w.get("nodes", []):
            c = (w.get("critical_mu") or {}).get(str(n)) or {}
            v = c.get("value")
            out.append([str(n), num(v, ".4f"), num(c.get("err"), ".4f"),
                        num(None if v is None else ratio * v, ".3f")])
        ex = w.get("extrapolation") or {}
        order = ex.get("order")
        v = ex.get("value") if ex.get("extrapolable") else None
        out.append([f"Richardson (measured order {num(order, '.2f')})", num(v, ".3f"),
                    num(ex.get("err"), ".3f"), num(None if v is None else ratio * v, ".3f")])
        return out
    return rows


def per_n_window_rows(runs: list[Path]) -> list[list[str]]:
    """``N | critical | +-`` over the mesh sizes of ``--nodes`` windows."""
    out = []
    for r in runs:
        w = window_json(r)
        for n in w.get("nodes", []):
            c = (w.get("critical_mu") or {}).get(str(n)) or {}
            out.append([str(n), num(c.get("value"), ".3f"), num(c.get("err"), ".3f")])
    return out


# --- the docs' tables ------------------------------------------------------------------------

M = "--set physics.friction.mu_s=0.99 --set physics.friction.mu_k=0.82"  # the measured pair
SMALL = "--set numerics.nodes=16"
SMALL_WINDOW = "--set numerics.nodes=30 --nodes 30 --coarse 2 --tol 3"


def coin_chord_rows(runs: list[Path]) -> list[list[str]]:
    d = [S("mesh_check.max_chord_depth", ".4f")(r) + " R" for r in runs]
    return [["50", d[0], d[1]], ["100", d[2], d[3]], ["200", d[4], d[5]], ["400", "-", d[6]]]


def coin_window_rows(runs: list[Path]) -> list[list[str]]:
    """``N | windows | critical mu_s | resolution`` of each window search: a ``--nodes`` one
    (a row per N) or one at the scenario's N (its resolution check names the N)."""
    out = []
    for r in runs:
        w = window_json(r)
        if "nodes" not in w:  # one mesh size
            rc = w.get("resolution_check") or {}
            c = w.get("critical_mu") or {}
            crit = "none" if c.get("value") is None else (
                num(c["value"], ".3g") + (" (open)" if c.get("open") else ""))
            deep = sum(v > 0.05 for v in (rc.get("max_chord_depth") or {}).values())
            total = w.get("n_evaluations", "-")
            res = ("resolved" if rc.get("members_resolved") else
                   f"not resolved ({deep} of {total} members: chord > 0.05 R)")
            out.append([str(rc.get("nodes", "-")), windows_text(w), crit, res])
            continue
        bad = set((w.get("refinement_check") or {}).get("unresolved_at") or [])
        for n in w.get("nodes", []):
            c = (w.get("critical_mu") or {}).get(str(n))
            crit = ("none" if not c else
                    num(c["value"], ".3g") + (" (open)" if c.get("open") else ""))
            out.append([str(n), windows_text(w, n), crit,
                        "not resolved" if n in bad else "resolved"])
    return out


def body_chords(run: Path) -> str:
    """Each held body's deepest chord (R), when and on which element."""
    bodies = dig(summary(run), "mesh_check.bodies") or {}
    return "; ".join(
        f"{name} {num(b.get('max_chord_depth'), '.4f')} (t = {num(b.get('time_s'), '.1f')} s, "
        f"rbar {'-'.join(num(x, '.2f') for x in b.get('element_rbar') or [])})"
        for name, b in bodies.items()) or "none"


def TUBE_WALL(run: Path) -> str:  # noqa: N802
    b = dig(summary(run), "mesh_check.bodies.tube wall") or {}
    return (f"{num(b.get('max_chord_depth'), '.4f')} (t = {num(b.get('time_s'), '.1f')} s, "
            f"rbar {'-'.join(num(x, '.3f') for x in b.get('element_rbar') or [])})")


def bottle_clearance(run: Path) -> str:
    """The sheet's closest approach to the assumed bottle (R), and when where it is touched."""
    from dynslip.analysis.clearance import clearance
    from dynslip.physics.bodies.apparatus import bottle

    ds = trajectory(run)
    if ds is None:
        return "-"
    c = clearance(ds, bottle(20.0))
    text = num(c["min"], ".3f")
    return f"**{text}** (t = {c['time']:.0f} s)" if c["touched"] else text


def bodies_bench_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "bodies")
    return [[k[1:], num(r["ratio_sphere_vs_inline"], ".2f"),
             num(r["ratio_one_body_vs_sphere"], ".2f"),
             num(r["ratio_frictional_body_vs_sphere"], ".2f"),
             num(r["ratio_frictional_body_free_ball_vs_sphere"], ".2f")]
            for k, r in sorted(((k, v) for k, v in b.items() if k[:1] == "N"),
                               key=lambda kv: int(kv[0][1:]))]


def corners_bench_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "corners")
    return [[k[1:], num(r["iteration_ms_node_only"], ".3f"), num(r["iteration_ms_two_pass"], ".3f"),
             num(r["ratio"], ".2f"), yes(r["met"])]
            for k, r in sorted(((k, v) for k, v in b.items() if k[:1] == "N"),
                               key=lambda kv: int(kv[0][1:]))]


def static_speed_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "static")
    rows = []
    for model, label in (("hookean", "Hookean"), ("neo_hookean", "neo-Hookean"),
                         ("gent", "Gent")):
        r = dig(b, f"models.{model}") or {}
        rows.append([f"{label}, warm", num(r.get("search_warm_s"), ".3g") + " s",
                     num(r.get("search_implicit_warm_s"), ".3g") + " s",
                     num(r.get("implicit_speedup_warm"), ".1f")])
    rows.append(["**three models, warm**", f"**{num(b.get('search_warm_three_models_s'))} s**",
                 f"**{num(b.get('search_warm_three_models_implicit_s'))} s**",
                 f"**{num(b.get('implicit_speedup_three_models_warm'), '.1f')}**"])
    mus = [dig(b, f"models.{m}") or {} for m in ("hookean", "neo_hookean", "gent")]
    rows.append(["three mu", ", ".join(num(m.get("mu_search"), ".6g") for m in mus),
                 ", ".join(num(m.get("mu_search_implicit"), ".6g") for m in mus),
                 "largest difference " + num(b.get("mu_implicit_minus_explicit_max_abs"), ".1g")])
    return rows


def static_rules_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "static").get("selection_rules", {})
    rows = []
    for m, label, paper in (("hookean", "Hookean", "1.47"), ("neo_hookean", "neo-Hookean", "0.99"),
                            ("gent", "Gent (J_m = 50)", "1.1"),
                            ("mooney_rivlin", "Mooney-Rivlin (C1 = 0.4, C2 = 0.1)", "-")):
        r = b.get(m, {})
        rows.append([label, f"{num(r.get('mu_bvp_switch_radius_0.25'), '.4f')} "
                     f"({num(r.get('theta_s_switch_radius'), '.3f')})",
                     f"{num(r.get('mu_bvp_switch_angle_pi/4'), '.4f')} "
                     f"({num(r.get('rbar_s_switch_angle'), '.4f')})",
                     num(r.get("mu_search_switch_angle_pi/4"), ".4f"), paper])
    return rows


def _static_mu(s: dict) -> tuple[str, float | None]:
    """A static run's mu (each model's, for a figure's several) and its search time."""
    if "models" in s:
        return (", ".join(num(m.get("mu"), ".6g") for m in s["models"]),
                sum(m.get("t_search_s") or 0.0 for m in s["models"]))
    return num(s.get("mu"), ".6g"), s.get("t_search_s")


def static_march_rows(runs: list[Path]) -> list[list[str]]:
    """Per paper scenario, run with the explicit and the implicit march: mu (both, when they
    differ), the wall time of each command (the search's own time in brackets)."""
    out = []
    for name, ex, im in zip(PAPER, runs[::2], runs[1::2], strict=True):
        (mu_e, t_e), (mu_i, t_i) = _static_mu(summary(ex)), _static_mu(summary(im))
        out.append([f"`{name}`" + (" (three models)" if name == "paper_figure4" else ""),
                    mu_e if mu_e == mu_i else f"{mu_e} / {mu_i}",
                    f"{RUNS[ex]['wall_s']:.1f} s ({num(t_e, '.1f')} s)",
                    f"{RUNS[im]['wall_s']:.1f} s ({num(t_i, '.1f')} s)"])
    return out


PAPER = ("paper_hookean", "paper_neohookean", "paper_gent", "paper_mooney_rivlin",
         "paper_figure4")


def sweep_bench_rows(runs: list[Path]) -> list[list[str]]:
    b = bench(runs[0], "sweep")
    label = {"sequential": "sequential (first, pays the compilation)",
             "batched": "batched", "dask": "dask (new worker processes)"}
    rows = []
    for mode in ("sequential", "batched", "dask"):
        r = b.get(mode, {})
        rows.append([label[mode], num(r.get("wall_s"), ".0f") + " s",
                     num(r.get("members_per_minute"), ".2f"),
                     f"{num(r.get('member_s_min'), '.0f')}-{num(r.get('member_s_max'), '.0f')} s"])
    return rows


def _sweep_summary(run: Path) -> dict:
    f = run / "summary.json"
    return json.loads(f.read_text()) if f.is_file() else {}


def sweep_rows(runs: list[Path]) -> list[list[str]]:
    """The 64-member sweep, one member per batch and a worker's share per batch: the
    command's wall time, members per minute, outcome."""
    out = []
    for label, run in zip(("1 (members one after another; the default on the CPU)",
                           "32 (a worker's whole share in one lockstep batch)"), runs, strict=True):
        s = _sweep_summary(run)
        out.append([label, f"{RUNS[run.parent]['wall_s']:.0f} s",
                    num(s.get("members_per_minute"), ".1f"), f"{s.get('n_ok', '-')} ok"])
    return out


def lockstep_rows(runs: list[Path]) -> list[list[str]]:
    out = []
    for label, run in zip(("sequential", "batched, 2 worker processes, lockstep batches of 2",
                           "batched, 2 worker processes, one member per batch",
                           "dask, 2 workers"),
                          runs, strict=True):
        s = _sweep_summary(run)
        recs = [json.loads(f.read_text()) for f in sorted((run / "members").glob("*.json"))]
        solve = sum(dig(r, "summary.solver.run_s") or 0.0 for r in recs)
        out.append([label, f"{RUNS[run.parent]['wall_s']:.1f} s",
                    num(s.get("members_per_minute"), ".1f"), f"{solve:.1f} s"])
    return out


def study_loading_rows(runs: list[Path]) -> list[list[str]]:
    """Each member of the shipped study (its record in the sweep's members/): the run at the
    study's friction, and its windows."""
    recs = [json.loads(f.read_text()) for f in sorted((runs[0] / "members").glob("*.json"))]
    out = []
    for r in sorted(recs, key=lambda r: (str(r.get("base")), json.dumps(r.get("assign"),
                                                                        sort_keys=True))):
        s = r.get("summary") or {}
        depth = next((v for k, v in (r.get("assign") or {}).items() if k.endswith("_z_mm")), "-")
        wins = (r.get("window") or {}).get("windows") or []
        out.append(["1" if "method1" in str(r.get("base")) else "2", f"{num(depth, '.0f')} mm",
                    yes(s.get("trapped")), num(s.get("theta_max"), ".3f"),
                    num(s.get("rbar_max"), ".3f"), num(s.get("mu_mobilised_max"), ".3f"),
                    ", ".join(f"[{a:.3f}, {b:.3f}]" for a, b in wins) or "none"])
    return out


def release_cell(key: str, spec: str = ".3g", percent: bool = False) -> Callable[[Path], str]:
    """A cell of the release as measured (summary.json ``release.force_ramp``; a force as its
    magnitude, the summary's sign being the pull's direction, toward the opening)."""
    def cell(run: Path) -> str:
        v = dig(summary(run), f"release.force_ramp.{key}")
        return "-" if v is None else (num(100 * v, ".2g") + "%" if percent else num(abs(v), spec))
    return cell


def pressure_frames_rows(runs: list[Path]) -> list[list[str]]:
    """The measured let-go run with the pressure law, at four frames: the contact's true
    pressure (kPa: the force per deformed area), J and the law's mu."""
    import numpy as np

    ds = trajectory(runs[0])
    out = []
    for t, stage in ((100, "end of hold"), (108, "let go"), (110, "let go"), (112, "release")):
        if ds is None:
            out.append([str(t), stage, "-", "-", "-", "-"])
            continue
        i = int(np.argmin(np.abs(ds["time"].values - t)))
        on = ds["state"].values[i] > 0
        J = (ds["lambda_theta"].values[i] * ds["lambda_phi"].values[i])[on]
        # the saved pressure is already per deformed area (the trajectory contract)
        p = ds["pressure"].values[i][on] * float(ds.attrs["G_Pa"]) * float(ds.attrs["h0_m"]) / (
            float(ds.attrs["R_m"])) / 1e3 if on.any() else np.array([])
        mu = ds["mu_mobilised"].values[i][on]
        if not on.any():
            out.append([str(t), stage, num(float(ds["theta_max"].values[i]), ".3f"), "-", "-",
                        "-"])
            continue
        out.append([str(t), stage, num(float(ds["theta_max"].values[i]), ".3f"),
                    f"{p.min():.2g} / {np.median(p):.2g} / {p.max():.2g}", f"{np.median(J):.3g}",
                    f"{mu.min():.2g}..{mu.max():.3g} ({np.median(mu):.3g})"])
    return out


def fronts_rows(runs: list[Path]) -> list[list[str]]:
    out = []
    for label, run in zip(("method 2, let go", "method 1"), runs, strict=True):
        ds = trajectory(run)
        s = summary(run)
        out.append([label, str(ds.sizes["time"]) if ds is not None else "-", TRAPPED(run),
                    num(s.get("theta_max"), ".3f"), num(s.get("rbar_max"), ".3f"),
                    num(s.get("mu_mobilised_max"), ".3f"),
                    "at rest" if s.get("end_at_rest") else "not at rest"])
    return out


def fronts_stage_rows(runs: list[Path]) -> list[list[str]]:
    """Each stage's direction of travel of the stick fronts (``dynslip fronts``'s
    fronts_summary.json), with the push-down and release stages that moved none left out."""
    out = []
    for label, run in zip(("method 2, let go", "method 1"), runs[2:], strict=True):
        f = run / "fronts_summary.json"
        for st in json.loads(f.read_text())["stages"] if f.is_file() else []:
            if st.get("name") == "rest":
                continue
            if not st.get("frames"):  # a stage the run did not reach
                out.append([label, st["name"], "-", "-"])
                continue
            out.append([label, st["name"], str(st.get("front_direction", "-")).replace("_", " "),
                        f"{num(st.get('front_travel_toward_equator_rbar'), '.3f')} / "
                        f"{num(st.get('front_travel_toward_pole_rbar'), '.3f')}"])
    return out


# --- the docs' tables: rows of fixed cells and cells read off each row's runs ------------------

Cell = Callable[[list[Path]], str]


def joined(cell: Callable[[Path], str], sep: str = " / ") -> Cell:
    """A row's cell from a run's: each run's, joined."""
    return lambda runs: sep.join(cell(r) for r in runs)


def spec(rows: list[tuple[tuple[str, ...], tuple[str, ...]]], *cells: Cell
         ) -> tuple[tuple[str, ...], Callable[[list[Path]], list[list[str]]]]:
    """(commands, rows function) of rows given as (fixed cells, the row's commands): each row
    is its fixed cells, then each of ``cells`` applied to the row's run folders."""
    commands = tuple(c for _, cs in rows for c in cs)

    def read(runs: list[Path]) -> list[list[str]]:
        out, i = [], 0
        for labels, cs in rows:
            mine, i = runs[i : i + len(cs)], i + len(cs)
            out.append([*labels, *(c(mine) for c in cells)])
        return out
    return commands, read


def table(doc: str, header: tuple[str, ...], made: tuple, small: str = SMALL, **kw) -> Table:
    commands, rows = made
    return Table(doc=doc, header=header, commands=commands, rows=rows, small=small,
                 slow=kw.pop("slow", True), **kw)


def run(scenario: str, *sets: str, nodes: int | None = None) -> str:
    """``dynslip run scenarios/SCENARIO.yaml`` with ``--set`` of each of ``sets``."""
    words = [f"dynslip run scenarios/{scenario}.yaml"]
    words += [f"--set numerics.nodes={nodes}"] if nodes else []
    words += [x if x.startswith("--") else f"--set {x}" for x in sets]
    return " ".join(words)


def window(scenario: str, args: str, *sets: str) -> str:
    words = [f"dynslip window scenarios/{scenario}.yaml", args]
    words += [x if x.startswith("--") else f"--set {x}" for x in sets]
    return " ".join(words)


GENT = ("physics.material.model=gent", "physics.material.jm=50")
NEO = ("physics.material.model=neo_hookean",)
MR = ("physics.material.model=mooney_rivlin", "physics.material.c1=0.4",
      "physics.material.c2=0.1")
MEAS = ("physics.friction.mu_s=0.99", "physics.friction.mu_k=0.82")
DEF = ("physics.friction.mu_s=1.5", "physics.friction.mu_k=1.25")
DEPTH = "physics.stages.0.clamp_to_z_mm={}"
RATIO = 1.25 / 1.5  # mu_k / mu_s of the shipped static/kinetic pairs


def crit(w: dict, ratio: float | None = RATIO) -> str:
    """The critical mu_s at a window's finest N (value +- err, and mu_k at it)."""
    c = w.get("critical_mu") or {}
    if "value" not in c:
        c = c.get(str(max(w.get("nodes") or [0]))) or {}
    if not c:
        return "none"
    text = f"{c['value']:.3f} +- {c['err']:.3f}"
    return text + (f" / {ratio * c['value']:.3f}" if ratio else "")


def windows_all(w: dict) -> str:
    """The windows at each N of a window.json."""
    wins = w.get("windows") or {}
    if isinstance(wins, list) or len(wins) <= 1:
        return windows_text(w)
    return "; ".join(f"N = {n}: {windows_text(w, int(n))}" for n in wins)


def WINDOWS(runs: list[Path]) -> str:  # noqa: N802
    return windows_all(window_json(runs[0]))


def CRIT(runs: list[Path]) -> str:  # noqa: N802
    return crit(window_json(runs[0]))


def LAST_TRAPPED(runs: list[Path]) -> str:  # noqa: N802
    """Trapped in the row's last run (the run at the measured friction)."""
    return TRAPPED(runs[-1])


def trapped_theta(run: Path) -> str:
    s = summary(run)
    t = yes(s.get("trapped"))
    return t + (f" (theta_max {num(s.get('theta_max'), '.3f')})" if s.get("trapped") else "")


def pinned_rows(runs: list[Path]) -> list[list[str]]:
    """The pinned tube's raise: the end of the push-down; the clamp's height (mm) where the
    contact comes back above the equator; the smallest pull while it is past it; where the pull
    falls below 0.02 N."""
    import math

    import numpy as np

    labels = (("1.0", "0.99 / 0.82"), ("1.0", "1.5 / 1.25"), ("1.05", "1.5 / 1.25"))
    out = []
    for lab, run in zip(labels, runs, strict=True):
        ds, s = trajectory(run), summary(run)
        if ds is None:
            out.append([*lab, "-", "-", "-", "-", TRAPPED(run), STEPS(run)])
            continue
        fs, mm = float(ds.attrs["force_scale_N"]), 1e3 * float(ds.attrs["R_m"])
        i = stage_end(ds, "push_down")
        th, rb = float(ds["theta_max"].values[i]), float(ds["rbar_max"].values[i])
        pull = np.abs(ds["clamp_force_static"].values) * fs
        end = (f"{th:.3f}, {rb:.3f}, {math.sin(th) / rb:.2f}, {pull[i]:.0f} N" if rb > 0
               else "-")
        later = np.arange(ds.sizes["time"]) > i
        past = later & (ds["theta_max"].values > math.pi / 2)
        back = np.flatnonzero(later & ~past & (ds["rbar_max"].values > 0))
        low = np.flatnonzero(later & (pull < 0.02))
        z = ds["clamp_z"].values * mm
        out.append([*lab, end, f"{z[back[0]]:+.0f} mm" if back.size else "-",
                    f"{pull[past].min():.1f} N" if past.any() else "-",
                    f"{z[low[0]]:+.0f} mm" if low.size else "-", yes(s.get("trapped")),
                    STEPS(run)])
    return out


def rim_feed_edge_rows(runs: list[Path]) -> list[list[str]]:
    """The lowest mu_s that traps per N (the windows' critical mu), whether the members below
    it are resolved, and the run at the measured friction."""
    windows, measured = runs[:3], runs[3:]
    out = []
    for k, n in enumerate((50, 100, 200, 400, 800)):
        w = next((window_json(r) for r in windows
                  if str(n) in (window_json(r).get("critical_mu") or {})), {})
        if not w:  # the small variant's mesh sizes
            w = window_json(windows[min(k, 2)])
            n = (w.get("nodes") or [n])[min(k, len(w.get("nodes") or [0]) - 1)]
        c = (w.get("critical_mu") or {}).get(str(n)) or {}
        below = "unresolved" if c.get("unresolved") or c.get("failed_side") else "resolved"
        run_ = measured[k]
        s = summary(run_)
        out.append([str(n), f"{num(c.get('value'), '.3f')} +- {num(c.get('err'), '.3f')}", below,
                    trapped_theta(run_) if s.get("trapped") is None else
                    f"{yes(s.get('trapped'))} (theta_max {num(s.get('theta_max'), '.3f')}, "
                    f"deepest chord {num(dig(s, 'mesh_check.max_chord_depth'), '.3f')} R)"])
    return out


def sensitivity_rows(runs: list[Path]) -> list[list[str]]:
    """mu_c of the let-go path at N = 100 against each numerical parameter changed."""
    def mu(run: Path) -> tuple[float | None, float | None]:
        w = window_json(run)
        c = (w.get("critical_mu") or {})
        c = c if "value" in c else next(iter(c.values()), None) or {}
        return c.get("value"), c.get("err")

    base, _ = mu(runs[0])
    params = (("nodes", "100", "50 / 200", 2), ("`physics.friction.d_c_mm`", "0.4", "0.2", 1),
              ("`numerics.penalty_stiffness`", "1e4", "2e4", 1),
              ("`numerics.friction_smoothing`", "1e-3", "5e-4", 1),
              ("`numerics.drag_time_s`", "0.1", "0.05", 1),
              ("`numerics.max_increment`, `max_increment_free`", "20, 5", "10, 2.5", 1),
              ("`numerics.contact_threshold`", "1e-2", "5e-3", 1),
              ("`numerics.rtol`, `atol`", "1e-5, 1e-7", "1e-6, 1e-8", 1))
    out, i = [], 1
    for name, default, changed, k in params:
        got = [mu(r) for r in runs[i : i + k]]
        i += k
        out.append([name, default, changed,
                    " / ".join(f"{num(v, '.4f')} +- {num(e, '.4f')}" for v, e in got),
                    " / ".join("-" if v is None or base is None else f"{v - base:+.3f}"
                               for v, _ in got)])
    return out


def transposed(labels: tuple[str, ...], cells: tuple[tuple[str, Callable[[Path], str]], ...]):
    """A table whose columns are runs: the first row ``labels``' header is the table's; one row
    per (name, cell)."""
    return lambda runs: [[name, *(c(r) for r in runs)] for name, c in cells]


def verdict_cell(runs: list[Path]) -> str:
    trapped = [summary(r).get("trapped") for r in runs]
    return "no" if not any(trapped) and None not in trapped else ", ".join(map(yes, trapped))


def stretch_range(runs: list[Path]) -> str:
    v = [x for r in runs if (x := dig(summary(r), "largest_stretch.path_max_lambda_theta"))]
    return f"{min(v):.1f}-{max(v):.1f}" if v else "-"


WIN_TOL = "--coarse 6 --tol 0.01"


def HOOP(run: Path) -> str:  # noqa: N802
    """sin(theta_max) <= rbar_max (the lip's hoop stretch at most 1), and the hoop stretch."""
    h = dig(summary(run), "lip.hoop_stretch")
    return f"{yes(None if h is None else h <= 1.0)} ({num(h, '.3f')})"
LETGO_P = "method2_let_go_pressure"
STRETCH = S("largest_stretch.path_max_lambda_theta", ".3g")
CHORD = S("mesh_check.max_chord_depth", ".3f")
END = joined(lambda r: f"{S('theta_max', '.3f')(r)} / {S('rbar_max', '.3f')(r)}")

def last(cell: Callable[[Path], str]) -> Cell:
    """A row's cell read off its last run (the release, after the run that formed its start)."""
    return lambda runs: cell(runs[-1])


def _release(pocket_nodes: tuple[int, int, int]):
    """The release rows from the main job's pocket: at the file's N (150) with the file's
    settings, the ramp twice as slow, the drag time halved, both, and the drag time quartered;
    then from the pockets formed at N = 100 and 200 (``pocket_nodes``: the N of the three
    pockets), at 200 with the drag time halved, and with the ramp twice as slow too. Each row
    runs its pocket, then its release (the ``{run:K}`` of its start: the row's first
    command)."""
    n0, n1, n2 = pocket_nodes
    slow = " --set physics.stages.pull.duration_s=570"
    half, quarter = " --set numerics.drag_time_s=0.0125", " --set numerics.drag_time_s=0.00625"
    cases = [("the file (N = 150)", n0, ""),
             ("ramp twice as slow (`physics.stages.pull.duration_s=570`)", n0, slow),
             ("drag time halved (`numerics.drag_time_s=0.0125`)", n0, half),
             ("drag time halved, ramp twice as slow", n0, half + slow),
             ("drag time quartered (`numerics.drag_time_s=0.00625`)", n0, quarter),
             ("N = 100 (start formed at N = 100)", n1, ""),
             ("N = 200 (start formed at N = 200)", n2, ""),
             ("N = 200, drag time halved", n2, half),
             ("N = 200, drag time halved, ramp twice as slow", n2, half + slow)]
    rel = "dynslip run scenarios/release_pull_tube.yaml --set numerics.nodes={} --set " \
          "start_from={{run:{}}}/trajectory.nc"
    rows = [((label,), (run("method2", nodes=n), rel.format(n, 2 * i) + extra))
            for i, (label, n, extra) in enumerate(cases)]
    return spec(rows, last(release_cell("release_force_N", ".3g")),
                last(release_cell("ball_speed_mm_s", ".2g")),
                last(release_cell("drag_share", percent=True)),
                last(release_cell("sheet_drag_share", percent=True)),
                last(lambda r: num(abs(dig(summary(r), "release.peak_force_N") or float("nan")),
                                   ".4g")))


RELEASE = _release((150, 100, 200))
#: the release needs the main job's pocket, which the mesh resolves from N = 150 only: the
#: small variant releases every row from the pocket at N = 150
RELEASE_SMALL = _release((150, 150, 150))[0]


def _small_answer(cmd: str) -> str:
    """The small variant of a command of the answer per path: windows at N = 30, 40, 50 with
    two coarse points, runs at N = 30; the margin's at its start's N (its start_from is the
    let-go run at the file's N)."""
    if "margin_let_go" in cmd:
        return cmd + " --coarse 2 --tol 3" if cmd.startswith("dynslip window") else cmd
    if cmd.startswith("dynslip window"):
        return cmd + " --nodes 30,40,50 --coarse 2 --tol 3"
    return cmd + " --set numerics.nodes=30"


ANSWER = spec([(("method 2 on the tube, rim pinned (`method2_pinned.yaml`)", "Gent J_m = 50"),
           (window("method2_pinned", f"--lo 0.8 --hi 3.0 {WIN_TOL}", "numerics.nodes=50"),
            run("method2_pinned", *MEAS, nodes=50))),
          (("method 2 on the tube, 5.6 mm fed over the rim (`method2_rim_feed.yaml`)",
            "neo-Hookean"),
           (window("method2_rim_feed", "--nodes 50,100,200 --lo 0.6 --hi 1.6 --coarse 6 "
                   "--tol 0.005"), run("method2_rim_feed", *MEAS, nodes=50))),
          (("method 2 on the tube, whole half width fed (`--set physics.pre_stretch=0.8`)",
            "Gent J_m = 50"),
           (window("method2_pinned", f"--lo 0.6 --hi 2.4 {WIN_TOL}", "numerics.nodes=50",
                   "physics.pre_stretch=0.8"),
            run("method2_pinned", "physics.pre_stretch=0.8", *MEAS, nodes=50))),
          (("let-go (`method2_let_go.yaml`)", "Gent J_m = 50"),
           (window("method2_let_go", "--nodes 50,100,200 --lo 1.0 --hi 1.6 --coarse 4 "
                   "--tol 0.005"), run("method2_let_go", *MEAS, nodes=50))),
          (("let-go", "neo-Hookean (`--set physics.material.model=neo_hookean`)"),
           (window("method2_let_go", "--nodes 50,100,200 --lo 0.6 --hi 1.2 --coarse 4 "
                   "--tol 0.02", *NEO), run("method2_let_go", *MEAS, *NEO, nodes=50))),
          (("let-go", "Mooney-Rivlin C1 = 0.4, C2 = 0.1"),
           (window("method2_let_go", "--nodes 50,100,200 --lo 0.8 --hi 2.0 --coarse 5 "
                   "--tol 0.02", *MR), run("method2_let_go", *MEAS, *MR, nodes=50))),
          (("method 1 (`method1.yaml`, hand stretch 2)", "Gent J_m = 50"),
           (window("method1", "--nodes 50,100,200 --lo 1.0 --hi 1.6 --coarse 4 --tol 0.005"),
            run("method1", *MEAS, nodes=50))),
          (("margin of the formed let-go pocket (`margin_let_go.yaml`)", "Gent J_m = 50"),
           (window("margin_let_go", "--lo 1.0 --hi 1.5 --coarse 4 --tol 0.005"),
            run("margin_let_go", *MEAS)))],
         WINDOWS, CRIT, LAST_TRAPPED)
ANSWER_SMALL = tuple(_small_answer(c) for c in ANSWER[0])


DOCS_TABLES = {
    # README.md and docs/experiment.md: the experiment's study
    "answer": _study_table(
        "README.md", ("path", "material", "critical mu_s at N (mu_k tied, ratio 0.83)",
                      "trapped at the measured 0.99 / 0.82"), "jm", study_answer_rows),
    "study_jm": _study_table(
        "docs/experiment.md", ("path", "material", "critical mu_s by N", "trapped at 0.99 / 0.82",
                               "largest stretch (I1-uniaxial)", "command"), "jm", study_jm_rows),
    "study_depth": _study_table(
        "docs/experiment.md", ("push", "material", "trapped", "bottom: lip theta_max / rbar_max, "
                               "span from the axis, neck", "end: theta_max / rbar_max",
                               "largest stretch (I1-uniaxial)", "command"), "depth",
        study_depth_rows),
    "study_release": _study_table(
        "docs/experiment.md", ("N", "release force (the paper: 2.3 N)", "command"), "release",
        study_release_rows),
    "clearance_paths": table(
        "docs/experiment.md",
        ("path", "rim depth D (mm)", "mu_s / mu_k", "N", "trapped", "theta_max", "rbar_max",
         "largest stretch", "closest to the bottle (R)"),
        spec([(("tube, raised (`method2_pinned.yaml`)", "-40", "0.99 / 0.82", "100 / 200"),
               tuple(run("method2_pinned", DEPTH.format(-40), *MEAS, nodes=n) for n in (100, 200))),
              (("tube, raised", "-60", "0.99 / 0.82", "100 / 200"),
               tuple(run("method2_pinned", DEPTH.format(-60), *MEAS, nodes=n) for n in (100, 200))),
              (("tube, raised", "-80", "0.99 / 0.82", "100 / 200"),
               tuple(run("method2_pinned", DEPTH.format(-80), *MEAS, nodes=n) for n in (100, 200))),
              (("tube, raised", "-160 (past the tube)", "0.99 / 0.82", "100"),
               (run("method2_pinned", DEPTH.format(-160), *MEAS, nodes=100),)),
              (("let go (`method2_let_go.yaml`)", "-80", "1.5 / 1.25", "100"),
               (run("method2_let_go", DEPTH.format(-80), *DEF, nodes=100),)),
              (("let go", "-80", "0.99 / 0.82", "100"),
               (run("method2_let_go", DEPTH.format(-80), *MEAS, nodes=100),)),
              (("let go", "-100, -120, -140 (past the tube)", "1.5 / 1.25", "100"),
               tuple(run("method2_let_go", DEPTH.format(d), *DEF, nodes=100)
                     for d in (-100, -120, -140))),
              (("let go", "-160 (past the tube)", "1.5 / 1.25", "100"),
               (run("method2_let_go", DEPTH.format(-160), *DEF, nodes=100),)),
              (("method 1 (`method1.yaml`, hands)", "-80", "1.5 / 1.25", "100"),
               (run("method1", DEPTH.format(-80), *DEF, nodes=100),)),
              (("method 1", "-80", "0.99 / 0.82", "100"),
               (run("method1", DEPTH.format(-80), *MEAS, nodes=100),)),
              (("method 1", "-160", "1.5 / 1.25", "100"),
               (run("method1", DEPTH.format(-160), *DEF, nodes=100),)),
              (("rim feed (`method2_rim_feed.yaml`, neo-Hookean)", "-160", "0.99 / 0.82", "100"),
               (run("method2_rim_feed", DEPTH.format(-160), *MEAS, nodes=100),))],
             joined(TRAPPED), joined(S("theta_max", ".3f")), joined(S("rbar_max", ".3f")),
             joined(STRETCH), joined(bottle_clearance))),
    "band_n": table(
        "docs/experiment.md",
        ("N", "trapped", "bottom of the push-down: theta_max / rbar_max",
         "end of the raise (t = 115 s): theta_max / rbar_max", "largest stretch on the path",
         "deepest chord (R)", "energy residual / work"),
        spec([((str(n),), (run("method2_band", nodes=n),)) for n in (50, 100, 200)],
             joined(TRAPPED), joined(BOTTOM),
             joined(lambda r: f"{at_stage_end('raise', 'theta_max')(r)} / "
                              f"{at_stage_end('raise', 'rbar_max')(r)}"),
             joined(STRETCH), joined(S("mesh_check.max_chord_depth", ".2g")),
             joined(lambda r: num(100 * (dig(summary(r), "energy_balance.relative_residual")
                                         or float("nan")), ".2g") + "%"))),
    "band_changes": table(
        "docs/experiment.md",
        ("change", "trapped", "bottom: theta_max / rbar_max", "end of the raise: theta_max",
         "largest stretch"),
        spec([(("none (above)",), (run("method2_band", nodes=100),)),
              (("`physics.tube.mu=0.3` (low end, latex on PVC)",),
               (run("method2_band", "physics.tube.mu=0.3", nodes=100),)),
              (("`physics.tube.mu=1.0` (high end)",),
               (run("method2_band", "physics.tube.mu=1.0", nodes=100),)),
              (("`physics.band_grip_N_per_mm=0.03`",),
               (run("method2_band", "physics.band_grip_N_per_mm=0.03", nodes=100),)),
              (("`physics.band_grip_N_per_mm=0.3`",),
               (run("method2_band", "physics.band_grip_N_per_mm=0.3", nodes=100),)),
              (("`physics.friction.mu_s=1.5`, `mu_k=1.242` (on the ball)",),
               (run("method2_band", "physics.friction.mu_s=1.5", "physics.friction.mu_k=1.242",
                    nodes=100),)),
              (("`physics.friction.mu_s=2.5`, `mu_k=2.07`",),
               (run("method2_band", "physics.friction.mu_s=2.5", "physics.friction.mu_k=2.07",
                    nodes=100),))],
             joined(TRAPPED), joined(BOTTOM), joined(at_stage_end("raise", "theta_max")),
             joined(STRETCH))),
    "pressure_runs": table(
        "docs/experiment.md",
        ("path, friction", "command", "trapped", "theta_max / rbar_max at the end",
         "largest stretch on the path", "deepest chord (R)"),
        spec([(("let go, measured", f"`{run(LETGO_P)}`"), (run(LETGO_P),)),
              (("let go, mu_ref 2.07 (the highest the bound 2.18 allows)",
                "`... --set physics.friction.mu_ref=2.07`"),
               (run(LETGO_P, "physics.friction.mu_ref=2.07"),)),
              (("let go, mu_ref 1.85, mu_max 10",
                "`... --set physics.friction.mu_ref=1.85 --set physics.friction.mu_max=10`"),
               (run(LETGO_P, "physics.friction.mu_ref=1.85", "physics.friction.mu_max=10"),)),
              (("let go, mu_ref 2.42, mu_max 10, on the reference area",
                "`... --set physics.friction.mu_ref=2.42 --set physics.friction.mu_max=10 --set "
                "physics.friction.pressure_on=reference`"),
               (run(LETGO_P, "physics.friction.mu_ref=2.42", "physics.friction.mu_max=10",
                    "physics.friction.pressure_on=reference"),)),
              (("let go, mu_ref 9.5, mu_max 10",
                "`... --set physics.friction.mu_ref=9.5 --set physics.friction.mu_max=10`"),
               (run(LETGO_P, "physics.friction.mu_ref=9.5", "physics.friction.mu_max=10"),)),
              (("tube, raised, measured (rim -160 mm)",
                f"`{run('method2_pinned', 'physics.friction.law=pressure', nodes=100)}`"),
               (run("method2_pinned", "physics.friction.law=pressure", nodes=100),)),
              (("tube, raised, measured (rim -80 mm, within the tube)",
                "the same `--set physics.stages.0.clamp_to_z_mm=-80`"),
               (run("method2_pinned", "physics.friction.law=pressure", DEPTH.format(-80),
                    nodes=100),))],
             joined(TRAPPED), END, joined(STRETCH), joined(CHORD))),
    "pressure_window": Table(
        doc="docs/experiment.md", header=("N", "critical mu_ref", "+-"),
        commands=("python docs/window_field.py scenarios/method2_let_go_pressure.yaml --field "
                  "physics.friction.mu_ref --nodes 50,100,200 --lo 1.6 --hi 2.0 --coarse 4 "
                  "--tol 0.01 --set physics.friction.mu_max=10",),
        rows=lambda runs: per_n_window_rows([runs[0] / "window"]), small="", slow=True,
        reads=("scenarios/method2_let_go_pressure.yaml",),
        small_commands=("python docs/window_field.py scenarios/method2_let_go_pressure.yaml "
                        "--field physics.friction.mu_ref --nodes 30,40,50 --lo 1.6 --hi 2.0 "
                        "--coarse 2 --tol 1 --set physics.friction.mu_max=10",)),
    "pressure_frames": Table(
        doc="docs/experiment.md",
        header=("t (s)", "stage", "theta_max", "true pressure min / median / max (kPa)",
                "J median", "mu min..max on the contact (median)"),
        commands=(run(LETGO_P),), rows=pressure_frames_rows, small=SMALL, slow=True),
    # docs/coin.md
    "coin_chords": Table(
        doc="docs/coin.md", header=("N", "penalty 1e4", "penalty 1e6"),
        commands=tuple(run("coin", *MEAS, f"numerics.penalty_stiffness={k}", nodes=n)
                       for n, k in ((50, "1e4"), (50, "1e6"), (100, "1e4"), (100, "1e6"),
                                    (200, "1e4"), (200, "1e6"), (400, "1e6"))),
        rows=coin_chord_rows, small=SMALL, slow=True),
    "coin_window": Table(
        doc="docs/coin.md",
        header=("N", "trapping window of mu_s (mu_k = 0.83 mu_s)", "critical mu_s",
                "the tool's resolution check"),
        commands=(window("coin", "--nodes 100,200,400 --lo 0 --hi 3 --coarse 13 --tol 0.02"),),
        rows=coin_window_rows, small="--nodes 24,30,36 --coarse 2 --tol 3", slow=True),
    # docs/bodies.md
    "mesh_check_bodies": table(
        "docs/bodies.md", ("run", "ball", "held bodies"),
        spec([((f"`{c}`",), (c,)) for c in (run("method2", nodes=30), run("method2", nodes=50),
                                            run("method2_band", nodes=50),
                                            run("free_weight", nodes=24))],
             joined(S("mesh_check.max_chord_depth", ".4f")), joined(body_chords))),
    "relative_chords": table(
        "docs/bodies.md",
        ("run", "ball", "tube wall: depth (R)", "relative to the rim's radius", "element span",
         "resolved"),
        spec([((f"`{c}`",), (c,)) for c in (run("method2", nodes=30), run("method2", nodes=50),
                                            run("method2", nodes=100))],
             joined(S("mesh_check.max_chord_depth", ".4f")), joined(TUBE_WALL),
             joined(S("mesh_check.bodies.tube wall.max_relative_chord_depth", ".3f")),
             joined(lambda r: S("mesh_check.bodies.tube wall.span_rad", ".2f")(r) + " rad"),
             joined(lambda r: yes(dig(summary(r), "mesh_check.bodies.tube wall.resolved"))))),
    # docs/sharp-edges.md
    "wall_resolution": table(
        "docs/sharp-edges.md",
        ("wall", "N", "trapped", "theta_max (rad)", "rbar_max (R)", "largest lambda_theta",
         "rim chord / rim radius", "energy residual / work"),
        spec([(("3 mm", str(n)), (run("method2", "physics.tube.wall_mm=3.0", nodes=n),))
              for n in (100, 150, 200)]
             + [(("6 mm", str(n)), (run("method2", nodes=n),)) for n in (100, 150, 200)],
             joined(TRAPPED), joined(S("theta_max", ".3f")), joined(S("rbar_max", ".4f")),
             joined(S("largest_stretch.lambda_theta", ".3f")),
             joined(S("mesh_check.bodies.tube wall.max_relative_chord_depth", ".3f")),
             joined(S("energy_balance.relative_residual", ".4f")))),
    "corners_cost": Table(
        doc="docs/sharp-edges.md",
        header=("N", "node-only contact (ms)", "two-pass contact (ms)", "ratio", "within 1.5"),
        commands=("DYNSLIP_BENCH_CORNERS_NODES=150 python benchmarks/run.py corners",),
        rows=corners_bench_rows, small="DYNSLIP_BENCH_CORNERS_NODES=16", slow=True,
        reads=("scenarios/method2.yaml", "benchmarks/corners.py")),
    "bodies_cost": Table(
        doc="docs/bodies.md",
        header=("N", "ball as a body / inline", "+ frictionless rim / ball",
                "+ frictional rim, ball held / ball", "+ frictional rim, ball free / ball"),
        commands=("DYNSLIP_BENCH_BODIES_NODES=50,200 python benchmarks/run.py bodies",),
        rows=bodies_bench_rows, small="DYNSLIP_BENCH_BODIES_NODES=12,16", slow=True,
        reads=("benchmarks/method2_let_go.yaml", "benchmarks/bodies.py")),
    # docs/forming.md
    "mesh_at_measured": table(
        "docs/forming.md",
        ("path", "material", "deepest chord (R)", "path's largest lambda_theta", "trapped"),
        spec([(("tube (`method2_pinned.yaml`)",
                "Gent J_m = 50 / neo-Hookean / Mooney-Rivlin 0.4 / 0.1"),
               tuple(run("method2_pinned", *MEAS, *m, nodes=50) for m in (GENT, NEO, MR))),
              (("let-go (`method2_let_go.yaml`)", "Gent / neo-Hookean / Mooney-Rivlin"),
               tuple(run("method2_let_go", *MEAS, *m, nodes=50) for m in (GENT, NEO, MR))),
              (("method 1 (`method1.yaml`)", "Gent / neo-Hookean / Mooney-Rivlin"),
               tuple(run("method1", *MEAS, *m, nodes=50) for m in (GENT, NEO, MR))),
              (("tube, rim feed (`method2_rim_feed.yaml`)", "neo-Hookean, N = 50 / 100 / 200"),
               tuple(run("method2_rim_feed", *MEAS, nodes=n) for n in (50, 100, 200)))],
             joined(CHORD), joined(STRETCH), joined(TRAPPED))),
    "pinned_raise": Table(
        doc="docs/forming.md",
        header=("pre_stretch", "mu_s / mu_k", "end of push-down: theta_max, rbar_max, "
                "sin(theta_max)/rbar_max, tube pull", "contact back above the equator at tube "
                "height", "smallest pull while the contact is past the equator",
                "pull below 0.02 N at", "trapped", "steps (rejected)"),
        commands=(run("method2_pinned", "physics.pre_stretch=1.0", *MEAS, nodes=50),
                  run("method2_pinned", "physics.pre_stretch=1.0", *DEF, nodes=50),
                  run("method2_pinned", "physics.pre_stretch=1.05", *DEF, nodes=50)),
        rows=pinned_rows, small=SMALL, slow=True),
    "rim_feed_tried": table(
        "docs/forming.md", ("pre_stretch (material radius)", "material", "mu_s tried", "trapped"),
        spec([(("1.0 (50.8 mm, `method2_pinned.yaml`)", "Gent J_m = 50", "0.8-3.0 (6 points)"),
               (window("method2_pinned", f"--lo 0.8 --hi 3.0 {WIN_TOL}", "numerics.nodes=50"),)),
              (("0.8 (63.5 mm: the whole half width)", "Gent J_m = 50", "0.6-2.4 (6 points)"),
               (window("method2_pinned", f"--lo 0.6 --hi 2.4 {WIN_TOL}", "numerics.nodes=50",
                       "physics.pre_stretch=0.8"),)),
              (("0.9 (56.4 mm), at 0.99 / 0.82 only", "Gent J_m = 50", "0.99"),
               (run("method2_pinned", "physics.pre_stretch=0.9", *MEAS, nodes=50),)),
              (("1.0", "neo-Hookean", "0.6-2.0 (5 points)"),
               (window("method2_pinned", "--lo 0.6 --hi 2.0 --coarse 5 --tol 0.01",
                       "numerics.nodes=50", *NEO),)),
              (("1.0, 0.98 at 0.99 / 0.82", "neo-Hookean", "0.99"),
               tuple(run("method2_pinned", f"physics.pre_stretch={x}", *MEAS, *NEO, nodes=50)
                     for x in (1.0, 0.98))),
              (("0.95, 0.9, 0.85, 0.8 at 0.99 / 0.82", "neo-Hookean", "0.99"),
               tuple(run("method2_pinned", f"physics.pre_stretch={x}", *MEAS, *NEO, nodes=50)
                     for x in (0.95, 0.9, 0.85, 0.8))),
              (("0.8", "neo-Hookean", "0.3-1.3, N = 50 / 100 / 200"),
               (window("method2_pinned", f"--nodes 50,100,200 --lo 0.3 --hi 1.3 {WIN_TOL}",
                       "physics.pre_stretch=0.8", *NEO),)),
              (("1.0", "Mooney-Rivlin 0.4 / 0.1", "0.6-2.0 (5 points)"),
               (window("method2_pinned", "--lo 0.6 --hi 2.0 --coarse 5 --tol 0.01",
                       "numerics.nodes=50", *MR),))],
             lambda runs: (windows_all(window_json(runs[0])) if (runs[0] / "window.json").is_file()
                           else ", ".join(trapped_theta(r) for r in runs))),
        small=SMALL_WINDOW),
    "rim_feed_edge": Table(
        doc="docs/forming.md",
        header=("N", "lowest mu_s that traps (mu_k = 0.828 mu_s)", "below it",
                "trapped at 0.99 / 0.82"),
        commands=(window("method2_rim_feed", "--nodes 50,100,200 --lo 0.6 --hi 1.6 --coarse 6 "
                         "--tol 0.005"),
                  window("method2_rim_feed", "--nodes 400 --lo 0.6 --hi 0.7 --coarse 3 "
                         "--tol 0.005"),
                  window("method2_rim_feed", "--nodes 800 --lo 0.62 --hi 0.66 --coarse 3 "
                         "--tol 0.005"),
                  *(run("method2_rim_feed", *MEAS, nodes=n) for n in (50, 100, 200, 400, 800))),
        rows=rim_feed_edge_rows, small="", slow=True,
        small_commands=(window("method2_rim_feed", "--nodes 30,40,50 --lo 0.6 --hi 1.6 --coarse 2 "
                               "--tol 1"),
                        window("method2_rim_feed", "--nodes 60 --lo 0.6 --hi 0.7 --coarse 2 "
                               "--tol 1"),
                        window("method2_rim_feed", "--nodes 70 --lo 0.62 --hi 0.66 --coarse 2 "
                               "--tol 1"),
                        *(run("method2_rim_feed", *MEAS, nodes=n) for n in (30, 40, 50, 60, 70)))),
    "shipped_defaults": table(
        "docs/forming.md",
        ("run", "N", "trapped", "theta_max", "rbar_max", "sin(theta_max) <= rbar_max",
         "largest lambda_theta", "mu_mobilised_max", "energy residual / work", "steps (rejected)",
         "compile s", "run s"),
        spec([(("method 2", "50"), (run("method2_pinned", nodes=50),)),
              (("method 1", "50"), (run("method1", nodes=50),)),
              (("method 2 (mu_s 1.3, mu_k 1.08)", "100"),
               (run("method2_pinned", "physics.friction.mu_s=1.3", "physics.friction.mu_k=1.08",
                    nodes=100),)),
              (("method 2 (mu_s 1.3, mu_k 1.08)", "50"),
               (run("method2_pinned", "physics.friction.mu_s=1.3", "physics.friction.mu_k=1.08",
                    nodes=50),))],
             joined(TRAPPED), joined(S("theta_max", ".3f")), joined(S("rbar_max", ".3f")),
             joined(HOOP),
             joined(S("largest_stretch.lambda_theta", ".3g")),
             joined(S("mu_mobilised_max", ".3f")), joined(RESIDUAL), joined(STEPS),
             joined(S("solver.compile_s", ".0f")), joined(S("solver.run_s", ".1f")))),
    "coulomb_mu": table(
        "docs/forming.md",
        ("mu", "trapped", "theta_max", "rbar_max", "sin(theta_max) <= rbar_max",
         "largest lambda_theta (rbar, theta)", "mu_mobilised_max", "energy residual / work",
         "steps (rejected)", "ms/step", "compile s"),
        spec([((label,), (run("method2_pinned", "physics.friction.law=coulomb",
                              f"physics.friction.mu={mu}", nodes=50),))
              for label, mu in (("1.0", 1.0), ("1.15 (default)", 1.15), ("1.3", 1.3))],
             joined(TRAPPED), joined(S("theta_max", ".3f")), joined(S("rbar_max", ".3f")),
             joined(HOOP),
             joined(lambda r: f"{S('largest_stretch.lambda_theta', '.3g')(r)} "
                              f"({S('largest_stretch.rbar', '.3f')(r)}, "
                              f"{S('largest_stretch.theta', '.3f')(r)})"),
             joined(S("mu_mobilised_max", ".3f")), joined(RESIDUAL), joined(STEPS),
             joined(S("solver.time_per_step_ms", ".2g")), joined(S("solver.compile_s", ".0f")))),
    "weakening_scan": Table(
        doc="docs/forming.md",
        header=("mu_s / mu_k", "1.15/0.95", "1.2/0.99", "1.3/1.08", "1.4/1.16", "1.5/1.245",
                "1.8/1.49", "2.2/1.82"),
        commands=tuple(run("method2_pinned", f"physics.friction.mu_s={a}",
                           f"physics.friction.mu_k={b}", nodes=50)
                       for a, b in ((1.15, 0.95), (1.2, 0.99), (1.3, 1.08), (1.4, 1.16),
                                    (1.5, 1.245), (1.8, 1.49), (2.2, 1.82))),
        rows=transposed((), (("trapped", TRAPPED), ("theta_max", S("theta_max", ".3f")),
                             ("mu_mobilised_max", S("mu_mobilised_max", ".3f")))),
        small=SMALL, slow=True),
    "world_verdict": table(
        "docs/forming.md", ("part of the world", "trapped", "largest stretch on the path"),
        spec([(("all of it: the rim with friction, the band, the bottle, pushed as deep as the "
                "tube allows (`method2.yaml`, the main job), N = 150 / 200",),
               tuple(run("method2", *MEAS, nodes=n) for n in (150, 200))),
              (("the tube's depth (rim at -40, -60, -80 mm; `method2_pinned.yaml`), N = 100 / "
                "200",),
               tuple(run("method2_pinned", DEPTH.format(d), *MEAS, nodes=n)
                     for d in (-40, -60, -80) for n in (100, 200))),
              (("the rounded rim with friction 0.3-1.0, the sheet beyond it, the band's grip "
                "0.03-0.3 N/mm (`method2_band.yaml`), N = 100 / 200",),
               (run("method2_band", nodes=100), run("method2_band", nodes=200),
                run("method2_band", "physics.tube.mu=0.3", nodes=100),
                run("method2_band", "physics.tube.mu=1.0", nodes=100),
                run("method2_band", "physics.band_grip_N_per_mm=0.03", nodes=100),
                run("method2_band", "physics.band_grip_N_per_mm=0.3", nodes=100))),
              (("friction rising as the pressure falls (`law: pressure`, let-go and tube paths)",),
               (run(LETGO_P), run("method2_pinned", "physics.friction.law=pressure", nodes=100),
                run("method2_pinned", "physics.friction.law=pressure", DEPTH.format(-80),
                    nodes=100)))],
             verdict_cell, stretch_range)),
    "letgo_converged": Table(
        doc="docs/forming.md", header=("N", "mu_c (mu_s)", "+-", "mu_k at mu_c"),
        commands=(window("method2_let_go", "--nodes 50,100,200 --lo 1.0 --hi 1.6 --coarse 4 "
                         "--tol 0.005"),),
        rows=converged_rows(RATIO), small="--nodes 30,40,50 --coarse 2 --tol 1", slow=True),
    "method1_converged": Table(
        doc="docs/forming.md", header=("N", "mu_c (mu_s)", "+-", "mu_k at mu_c"),
        commands=(window("method1", "--nodes 50,100,200 --lo 1.0 --hi 1.6 --coarse 4 "
                         "--tol 0.005"),),
        rows=converged_rows(RATIO), small="--nodes 30,40,50 --coarse 2 --tol 1", slow=True),
    "letgo_sensitivity": Table(
        doc="docs/forming.md", header=("parameter", "default", "changed to", "mu_c", "change"),
        commands=tuple(window("method2_let_go", "--lo 1.1 --hi 1.5 --coarse 5 --tol 0.01", *sets)
                       for sets in (
                           ("numerics.nodes=100",), ("numerics.nodes=50",), ("numerics.nodes=200",),
                           ("numerics.nodes=100", "physics.friction.d_c_mm=0.2"),
                           ("numerics.nodes=100", "numerics.penalty_stiffness=2e4"),
                           ("numerics.nodes=100", "numerics.friction_smoothing=5e-4"),
                           ("numerics.nodes=100", "numerics.drag_time_s=0.05"),
                           ("numerics.nodes=100", "numerics.max_increment=10",
                            "numerics.max_increment_free=2.5"),
                           ("numerics.nodes=100", "numerics.contact_threshold=5e-3"),
                           ("numerics.nodes=100", "numerics.rtol=1e-6", "numerics.atol=1e-8"))),
        rows=sensitivity_rows, small=SMALL_WINDOW, slow=True),
    "answer_per_path": table(
        "docs/forming.md",
        ("path", "material", "trapping windows of mu_s", "mu_c (mu_s / mu_k)",
         "trapped at the measured 0.99 / 0.82?"),
        ANSWER,
        small="", small_commands=ANSWER_SMALL),
    "method1_stretch": table(
        "docs/forming.md",
        ("hand stretch", "trapped", "theta_max", "rbar_max", "largest lambda_theta",
         "mu_mobilised_max"),
        spec([((f"{x}",), (run("method1", f"physics.pre_stretch={x}",
                               f"physics.rim_radius_mm={63.5 * x:g}", nodes=50),))
              for x in (1.5, 2.0, 2.5)],
             joined(TRAPPED), joined(S("theta_max", ".3f")), joined(S("rbar_max", ".3f")),
             joined(STRETCH), joined(S("mu_mobilised_max", ".3f")))),
    "release_tube": Table(
        doc="docs/forming.md",
        header=("run", "release force (N)", "ball speed at that frame (mm/s)", "ball drag share",
                "sheet drag share", "peak force against the sheet (N)"),
        commands=RELEASE[0], rows=RELEASE[1], small="", slow=True,
        small_commands=RELEASE_SMALL),
    # docs/fronts.md
    "fronts_runs": Table(
        doc="docs/fronts.md",
        header=("run", "frames", "trapped", "theta_max", "rbar_max", "mu_mobilised_max", "end"),
        commands=(run("method2_let_go"), run("method1")), rows=fronts_rows, small=SMALL,
        slow=True),
    "fronts_stages": Table(
        doc="docs/fronts.md",
        header=("run", "stage", "fronts travel", "travel toward the equator / the pole (rbar)"),
        commands=(run("method2_let_go"), run("method1"), "dynslip fronts {run:0}/trajectory.nc",
                  "dynslip fronts {run:1}/trajectory.nc"),
        rows=fronts_stage_rows, small=SMALL, slow=True),
    # docs/static-model.md
    "static_march": Table(
        doc="docs/static-model.md",
        header=("scenario", "mu explicit = implicit", "explicit", "implicit"),
        commands=tuple(c for name in PAPER for c in (
            f"dynslip run scenarios/{name}.yaml --set numerics.march=explicit",
            f"dynslip run scenarios/{name}.yaml --set numerics.march=implicit")),
        rows=static_march_rows, small="--set numerics.n_nodes=30", slow=True),
    "static_rules": Table(
        doc="docs/static-model.md",
        header=("model", "mu, rbar_s = 0.25 R (theta_s)", "mu, theta_s = pi/4 (rbar_s)",
                "march + search from the pi/4 member", "paper"),
        commands=("python benchmarks/run.py static",), rows=static_rules_rows, small="",
        slow=True, reads=("benchmarks/static.py",)),
    "static_speed": Table(
        doc="docs/static-model.md",
        header=("case", "explicit (baseline)", "implicit", "ratio explicit / implicit"),
        commands=("python benchmarks/run.py static",), rows=static_speed_rows, small="",
        slow=True, reads=("benchmarks/static.py",)),
    # docs/sweeps.md
    "sweep_throughput": Table(
        doc="docs/sweeps.md", header=("mode", "wall", "members / minute", "per member"),
        commands=("DYNSLIP_BENCH_SWEEP_MEMBERS=3 python benchmarks/run.py sweep",),
        rows=lambda runs: sweep_bench_rows(runs),
        small="DYNSLIP_BENCH_SWEEP_NODES=30 DYNSLIP_BENCH_SWEEP_MEMBERS=2", slow=True,
        reads=("benchmarks/sweep.py", "scenarios/method2_let_go.yaml")),
    "sweep_64": Table(
        doc="docs/sweeps.md",
        header=("batch size per worker", "wall", "members / minute", "outcome"),
        commands=("python docs/sweep_batch.py scenarios/sweep_method2.yaml --mode batched "
                  "--batch-size 1",
                  "python docs/sweep_batch.py scenarios/sweep_method2.yaml --mode batched "
                  "--batch-size 32"),
        rows=lambda runs: sweep_rows([r / "sweep" for r in runs]), small="", slow=True,
        reads=("scenarios/sweep_method2.yaml",),
        small_commands=tuple(f"python docs/sweep_batch.py scenarios/sweep_method2.yaml --mode "
                             f"batched --batch-size {b} --nodes 30 --head 2" for b in (1, 4))),
    "sweep_lockstep": Table(
        doc="docs/sweeps.md",
        header=("runner", "wall", "members / minute", "solve time (all members)"),
        commands=tuple(f"python docs/sweep_batch.py docs/data/sweep_lockstep.yaml {a}" for a in (
            "--mode sequential", "--mode batched --batch-size 4", "--mode batched --batch-size 1",
            "--mode dask")),
        rows=lambda runs: lockstep_rows([r / "sweep" for r in runs]), small="", slow=True,
        reads=("docs/data/sweep_lockstep.yaml",),
        small_commands=tuple(f"python docs/sweep_batch.py docs/data/sweep_lockstep.yaml {a} "
                             "--nodes 30 --head 2" for a in (
            "--mode sequential", "--mode batched --batch-size 2", "--mode batched --batch-size 1",
            "--mode dask"))),
    "study_loading": Table(
        doc="docs/sweeps.md",
        header=("method", "depth", "trapped at 1.5/1.25", "theta_max", "rbar_max",
                "mu_mobilised_max", "windows of mu_s"),
        commands=("python docs/sweep_batch.py scenarios/study_loading_path.yaml",),
        rows=lambda runs: study_loading_rows([runs[0] / "sweep"]), small="", slow=True,
        reads=("scenarios/study_loading_path.yaml",),
        small_commands=("python docs/sweep_batch.py scenarios/study_loading_path.yaml "
                        "--nodes 30 --head 2",)),
}


def fit_rows(runs: list[Path]) -> list[list[str]]:
    """The observations against the fit at its optimum (``fit.json``): observed (value +-
    one standard deviation, or the bound), the model's value, the residual in standard
    deviations."""
    fit = json.loads((runs[0] / "fit.json").read_text())
    rows = []
    for r in fit["residuals"]:
        unit = f" ({r['unit']})" if r.get("unit") not in (None, "", "1") else ""
        observed = (f"<= {num(r['value'])}" if r["kind"] == "bound"
                    else f"{num(r['value'])} +- {num(r['uncertainty'])}")
        rows.append([f"{r['name']}{unit}", observed, num(r["model"], ".4g"),
                     f"{r['residual']:+.2f}"])
    return rows


TABLES: dict[str, Table] = {
    "fit_paper": Table(
        doc="docs/calibration.md",
        header=("observation", "observed", "fit", "residual (sd)"),
        commands=("dynslip fit scenarios/method1.yaml --data scenarios/observations/"
                  "paper_shape.yaml --params physics.material.jm,physics.friction.mu_s "
                  "--set numerics.nodes=30",),
        rows=fit_rows, small="--scan 1 --max-steps 1", slow=True,
        reads=("scenarios/observations/paper_shape.yaml",)),
    "selection_rule": Table(
        doc="docs/static-model.md",
        header=("model", "mu (rule)", "paper", "difference", "switch angle", "pole stretch",
                "peak lambda_theta (grid)"),
        commands=("dynslip run scenarios/paper_figure4.yaml",),
        rows=selection_rule_rows,
        small="--set numerics.n_nodes=30",
    ),
    **SPEED,
    **DOCS_TABLES,
}

#: tables of the docs with digits that are not measured: (file, header row) -> why
REFERENCE: dict[tuple[str, str], str] = {
    ("docs/guide.md", "| command | what it does |"): "the commands, a reference",
    ("docs/guide.md", "| file | what |"): "the shipped scenarios and what each sets",
    ("docs/bodies.md", "| | ball (`ball`) | held bodies (`bodies`) |"):
        "what the solver supports, a reference",
    ("docs/experiment.md", "| part | size | source |"):
        "the apparatus's sizes: inputs, from the paper or assumed",
    ("docs/experiment.md", "| field | default | range | meaning |"):
        "the pressure law's fields, defaults and ranges: the schema",
    ("docs/modelling-choices.md", "| choice | default | field | why | more |"):
        "the modelling choices and their defaults; a number a 'why' cell quotes is measured "
        "in the table its 'more' cell links",
    ("docs/python-api.md", "| call | returns |"): "the Python API, a reference",
    ("docs/calibration.md", "| key | unit | the model's value |"):
        "the observations file's format: its keys, units and the summary value each is read "
        "against",
    ("docs/adhesion.md", "| run | w (J/m^2) | tau_0 s / k (kPa) | mu_s / mu_k | push (mm) | "
                         "trapped | theta_max | rbar_max | largest stretch (I1-equivalent) | "
                         "release (N) |"):
        "the adhesion study: runs measured by hand, each row's command below the table; not yet "
        "under the manifest",
    ("docs/trajectory-contract.md", "| name | meaning |"): "the dataset's attributes",
    ("docs/trajectory-contract.md", "| name | dims | units | meaning |"):
        "the dataset's variables and their units",
    ("docs/trajectory-contract.md", "| name | units | meaning |"):
        "the dataset's variables and their units",
    ("docs/evidence.md", "| variant | caught by |"):
        "which test caught a defect planted in a scratch copy: a record of an experiment on "
        "code that is not the package's",
    ("docs/evidence.md", "| test | old tolerance | measured | new tolerance |"):
        "a record of each change to a test's tolerance, with the value the test measured when "
        "it was changed; the tests themselves assert today's values",
    ("docs/evidence.md", "| test | what it compares | measured | tolerance |"):
        "the tests' independent checks: each figure is measured by the test the row names "
        "(``pytest -s`` prints it) and asserted there at the tolerance the row gives, so the "
        "suite re-measures the table on every run",
    ("docs/evidence.md", "| variant | stick/slip | tear-out | critical mu | headline |"):
        "the tests' verdicts on defects planted in scratch copies: a record of an "
        "experiment on code that is not the package's",
}


# --- the tables of the docs ----------------------------------------------------------------

MARK = re.compile(r"^<!-- (/?)results:([\w.-]+) -->\s*$")
PROVENANCE = re.compile(rf"key: ([0-9a-f]{{{KEY_LEN}}})")
_SEP = re.compile(r"^\s*\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?\s*$")


@dataclass(frozen=True)
class DocTable:
    doc: str  # the file, from the root
    line: int  # of its header row, from 1
    heading: str  # the heading it lies under
    header: str  # its header row, stripped
    body: tuple[str, ...]
    marker: str | None  # the results marker it lies under

    def holds_numbers(self) -> bool:
        """A digit in a body cell, code spans and link targets left out."""
        text = re.sub(r"`[^`]*`|\]\([^)]*\)", "", "\n".join(self.body))
        return any(c.isdigit() for c in text)

    def where(self) -> str:
        return f"{self.doc}:{self.line} [{self.heading}] {self.header}"


def doc_files() -> list[Path]:
    return [p for g in DOCS for p in sorted(ROOT.glob(g))]


def doc_tables(path: Path) -> list[DocTable]:
    """The markdown tables of a file (a header row, a separator row, body rows; indented in
    a list item or not; none inside a fenced code block)."""
    lines, rel = path.read_text().splitlines(), path.relative_to(ROOT).as_posix()
    out, heading, marker, fence, i = [], "", None, False, 0
    while i < len(lines):
        s = lines[i].strip()
        if s.startswith("```"):
            fence = not fence
        elif not fence and (m := MARK.match(s)):
            marker = None if m.group(1) else m.group(2)
        elif not fence and s.startswith("#"):
            heading = s.lstrip("#").strip()
        elif not fence and s.startswith("|") and i + 1 < len(lines) and _SEP.match(lines[i + 1]):
            j = i + 2
            while j < len(lines) and lines[j].strip().startswith("|"):
                j += 1
            body = tuple(x.strip() for x in lines[i + 2 : j])
            out.append(DocTable(rel, i + 1, heading, s, body, marker))
            i = j
            continue
        i += 1
    return out


def unmarked_tables() -> list[DocTable]:
    """Every table of numbers in the docs under no results marker and not in
    :data:`REFERENCE`."""
    return [t for p in doc_files() for t in doc_tables(p)
            if t.marker is None and t.holds_numbers() and (t.doc, t.header) not in REFERENCE]


def block(text: str, name: str) -> tuple[int, int] | None:
    """The span of the lines between the markers of table ``name`` in ``text``."""
    m = re.search(rf"^[ \t]*<!-- results:{re.escape(name)} -->[^\n]*\n(.*?)^[ \t]*<!-- "
                  rf"/results:{re.escape(name)} -->", text, flags=re.DOTALL | re.MULTILINE)
    return m.span(1) if m else None


def recorded_key(name: str) -> str | None:
    """The key in table ``name``'s provenance line, None without markers or key."""
    text = (ROOT / TABLES[name].doc).read_text()
    span = block(text, name)
    m = PROVENANCE.search(text[span[0] : span[1]]) if span else None
    return m.group(1) if m else None


#: the line a table measured before a change to its code carries until it is measured again
#: (:func:`mark_outdated`), naming the key of the code it has not been measured at
OUTDATED_TEXT = "Not measured again since its code changed: today's key is {key}"
OUTDATED = re.compile(OUTDATED_TEXT.format(key=rf"([0-9a-f]{{{KEY_LEN}}})"))


def outdated_key(name: str) -> str | None:
    """The key that table ``name``'s "not measured again" line names, None without one."""
    text = (ROOT / TABLES[name].doc).read_text()
    span = block(text, name)
    m = OUTDATED.search(text[span[0] : span[1]]) if span else None
    return m.group(1) if m else None


def outdated() -> dict[str, str]:
    """Each table measured before a change to its code that says so, naming today's key: its
    numbers are those of the code at its recorded key, and its doc says they are not today's."""
    return {name: f"{t.doc}: measured with key {recorded_key(name)} (None: by hand)"
            for name, t in TABLES.items()
            if recorded_key(name) != t.key() and outdated_key(name) == t.key()}


def mark_outdated(names: Iterable[str]) -> list[str]:
    """Add, under the provenance line of each table of ``names`` measured before a change to
    its code, the line that says so (:data:`OUTDATED_TEXT`, today's key; an earlier such line
    replaced). Measuring the table again rewrites the block and drops the line. Returns the
    tables marked."""
    done = []
    for name in names:
        t = TABLES[name]
        if recorded_key(name) == t.key():
            continue
        text = (ROOT / t.doc).read_text()
        span = block(text, name)
        kept = "".join(x for x in text[span[0] : span[1]].splitlines(keepends=True)
                       if not OUTDATED.search(x)).rstrip("\n")
        line = (f"**{OUTDATED_TEXT.format(key=t.key())}**: the numbers above are those of the "
                f"code at the key above; `python docs/results.py {name}` measures them again.")
        write(name, re.sub(r"^[ \t]+", "", kept, flags=re.MULTILINE) + "\n\n" + line + "\n")
        done.append(name)
    return done


def stale() -> dict[str, str]:
    """Each table of the manifest whose recorded key is not today's and that does not say so
    (:func:`outdated`), with what is wrong."""
    out = {}
    for name, t in TABLES.items():
        now, was = t.key(), recorded_key(name)
        if was != now and outdated_key(name) != now:
            text = (ROOT / t.doc).read_text()
            why = ("no markers" if block(text, name) is None else "no key" if was is None
                   else f"measured with key {was}")
            out[name] = f"{t.doc}: {why}, today's key {now}"
    return out


# --- measuring and writing -----------------------------------------------------------------


def render(t: Table, rows: list[list[str]], name: str, small: bool) -> str:
    """The table and its provenance line, as written between the markers."""
    lines = ["| " + " | ".join(t.header) + " |", "|" + "---|" * len(t.header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    cmds = "; ".join(f"`{c}{' ' + t.small if small else ''}`" for c in t.commands)
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    how = f"`python docs/results.py {name}{' --small' if small else ''}`"
    lines += ["", f"Measured at {commit()}, {when}, by {how} ({cmds}); key: {t.key()}."]
    return "\n".join(lines) + "\n"


#: run folder -> what running it gave: ``rc`` (0, or 3: an unknown answer, its files kept),
#: ``wall_s`` (the whole command's) and ``log`` (a subprocess's output)
RUNS: dict[Path, dict] = {}
#: (runs folder, environment, words) -> its folder: a command two tables share runs once
_DONE: dict[tuple, Path] = {}


def accepted(sub: str, words: list[str]) -> list[str]:
    """The options of ``words`` (each ``--name value``) that ``dynslip SUB`` takes: a table's
    small arguments apply to each of its commands as far as that command has them."""
    from dynslip.cli import build_parser

    known = build_parser()._subparsers._group_actions[0].choices[sub]._option_string_actions
    pairs = [words[i : i + 2] for i in range(0, len(words), 2)]
    return [w for pair in pairs if pair[0] in known for w in pair]


def run_command(cmd: str, extra: str, runs_dir: Path, name: str, i: int,
                before: list[Path] = ()) -> Path:
    """Run one command of table ``name`` (``extra``: the small variant's words) and return its
    run folder (a kept ``.incomplete-*`` folder when ``dynslip`` answered "unknown").
    ``{run:K}`` in a word is the folder of the table's command K (in ``before``)."""
    import os
    import sys
    import time

    env, words = split_command(cmd)
    words = [re.sub(r"\{run:(\d+)\}", lambda m: str(before[int(m.group(1))]), w) for w in words]
    more_env, more = split_command(extra)
    env |= more_env
    if words[0] == "dynslip":
        words += accepted(words[1], more)
    own = runs_dir / name / "tmp"
    env = {k: v.replace("{tmp}", str(own)) for k, v in env.items()}
    fresh = any("{tmp}" in w for w in shlex.split(cmd))
    done = (runs_dir, tuple(sorted(env.items())), tuple(words))
    if not fresh and done in _DONE:
        return _DONE[done]
    tag = hashlib.sha256(repr(done[1:]).encode()).hexdigest()[:10]
    out = runs_dir / name / f"{i}" if fresh else runs_dir / "runs" / tag
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = out.with_name(out.name + ".run.json")  # a finished run of this command, kept
    if not fresh and meta.is_file():
        RUNS[Path(json.loads(meta.read_text())["folder"])] = json.loads(meta.read_text())
        _DONE[done] = Path(json.loads(meta.read_text())["folder"])
        return _DONE[done]
    own.mkdir(parents=True, exist_ok=True)
    print(f"  {' '.join(f'{k}={v}' for k, v in env.items())} {shlex.join(words)}".strip(),
          flush=True)
    t0 = time.perf_counter()
    log = ""
    if words[0] == "dynslip" and not env:
        from dynslip.cli import build_parser, main

        if hasattr(build_parser().parse_args(words[1:]), "out"):
            words += ["--out", str(out)]
        rc = main(words[1:])
    else:
        if words[0] == "dynslip":
            argv = [sys.executable, "-m", "dynslip.cli", *words[1:], "--out", str(out)]
            cwd = ROOT
        elif words[0] == "python" and words[1].startswith(("docs/", "benchmarks/")):
            argv = [sys.executable, str(ROOT / words[1]), *words[2:]]
            out.mkdir(parents=True, exist_ok=True)
            cwd = out
        else:
            raise ValueError(f"{name}: not a dynslip command or a script of docs/, benchmarks/")
        proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, check=False,
                              env={**os.environ, "PYTHONPATH": str(ROOT), **env})
        rc, log = proc.returncode, proc.stdout + proc.stderr
    wall = time.perf_counter() - t0
    if rc == 3:
        kept = sorted(out.parent.glob(out.name + ".incomplete-*"))
        out = kept[-1] if kept else out
    if rc not in (0, 3) or not out.exists():
        raise RuntimeError(f"{name}: `{cmd}` exited {rc}\n{log[-3000:]}")
    RUNS[out] = {"rc": rc, "wall_s": wall, "log": log}
    if not fresh:
        _DONE[done] = out
        meta.write_text(json.dumps({**RUNS[out], "folder": str(out)}))
    return out


def measure(name: str, runs_dir: Path, small: bool = False) -> list[list[str]]:
    """Run table ``name``'s commands (the small variant's with its small arguments) and return
    its rows."""
    t = TABLES[name]
    commands = t.small_commands if small and t.small_commands is not None else t.commands
    folders: list[Path] = []
    for i, c in enumerate(commands):
        folders.append(run_command(c, t.small if small else "", runs_dir, name, i, folders))
    rows = t.rows(folders)
    if any(len(r) != len(t.header) for r in rows):
        raise ValueError(f"{name}: a row without {len(t.header)} cells: {rows}")
    return rows


def write(name: str, text: str) -> None:
    """Replace what lies between table ``name``'s markers in its file by ``text``."""
    path = ROOT / TABLES[name].doc
    doc = path.read_text()
    span = block(doc, name)
    if span is None:
        raise SystemExit(f"{path}: no <!-- results:{name} --> ... <!-- /results:{name} -->")
    start = doc.rfind("\n", 0, span[0] - 1) + 1  # the marker's line: its indentation
    indent = re.match(r"[ \t]*", doc[start:]).group(0)
    text = "".join(indent + line if line.strip() else line
                   for line in text.splitlines(keepends=True))
    path.write_text(doc[: span[0]] + text + doc[span[1] :])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", metavar="NAME", help=f"tables ({', '.join(TABLES)})")
    p.add_argument("--slow", action="store_true", help="run the slow tables too")
    p.add_argument("--small", action="store_true",
                   help="the small-mesh variant: print the tables, rewrite nothing")
    p.add_argument("--check", action="store_true", help="no run: list the stale tables")
    p.add_argument("--unmarked", action="store_true",
                   help="no run: list the tables of numbers not under the manifest")
    p.add_argument("--mark-outdated", action="store_true",
                   help="no run: say under each stale table (of NAMEs, default all) that it was "
                        "not measured again at today's code")
    p.add_argument("--runs", type=Path, default=None,
                   help="folder of the runs (default: a temporary folder)")
    args = p.parse_args(argv)
    unknown = sorted(set(args.names) - set(TABLES))
    if unknown:
        p.error(f"not in the manifest: {', '.join(unknown)}")
    if args.mark_outdated:
        for name in mark_outdated(args.names or list(TABLES)):
            print(f"{TABLES[name].doc}: {name} marked as not measured at today's code")
        return 0
    if args.check or args.unmarked:
        bad = {}
        if args.check:
            bad |= stale()
        if args.unmarked:
            bad |= {t.where(): "numbers outside the manifest" for t in unmarked_tables()}
        for what, why in bad.items():
            print(f"stale: {what}: {why}" if what in TABLES else f"unmarked: {what}")
        print(f"{len(bad)} found" if bad else "none found")
        return 1 if bad else 0
    wanted = args.names or [n for n, t in TABLES.items() if args.slow or not t.slow]
    with tempfile.TemporaryDirectory() as tmp:
        runs = args.runs or Path(tmp)
        for name in wanted:
            text = render(TABLES[name], measure(name, runs, args.small), name, args.small)
            if args.small:
                print(text)
            else:
                write(name, text)
                print(f"{TABLES[name].doc}: {name} rewritten", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
