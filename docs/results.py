"""Make every measured table of docs/ and the README from the code: one command.

    python docs/results.py                     # rerun every table that is not slow, rewrite it
    python docs/results.py selection_rule      # only this one (a named table runs, slow or not)
    python docs/results.py --slow              # the window searches at N = 200 too
    python docs/results.py --small             # each at a small mesh: printed, nothing rewritten
    python docs/results.py --check             # no run: the tables measured before a code change
    python docs/results.py --unmarked          # no run: tables of numbers outside the manifest

:data:`TABLES` is the manifest: each measured table of the docs, the markdown file it lies
in, the ``dynslip`` commands that measure it, the function of this module that turns their
output folders into the table's rows, the arguments that make the small-mesh variant the
suite runs, whether it is slow, and the files of the package it depends on. In its file a
table lies between two markers, with its provenance line under it::

    <!-- results:NAME -->
    | ... the table ... |

    Measured at 876967b, 2026-01-02 10:00 UTC, by `python docs/results.py NAME`
    (`dynslip run scenarios/...`); key: 0123456789ab.
    <!-- /results:NAME -->

Everything between the markers is rewritten. The key is :func:`key` of what the table
depends on: the package's source files (:data:`PACKAGE`, less :data:`NOT_PHYSICS`: the
plotting, the command line and the end-of-run table print nothing into a table) and the
scenario files its commands read, each file hashed, combined in sorted path order. A table
whose recorded key differs from today's is stale (``--check``; ``tests/test_docs.py``).
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
            digest = hashlib.sha256(p.read_bytes()).hexdigest()
        except FileNotFoundError:  # removed since it was listed: not part of the code now
            continue
        h.update(f"{p.relative_to(ROOT).as_posix()}\0{digest}\n".encode())
    h.update(extra.encode())
    return h.hexdigest()[:KEY_LEN]


def commit() -> str:
    """``git rev-parse --short HEAD``, with ``-dirty`` when a tracked file differs from it."""
    def git(*a):
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True)

    head = git("rev-parse", "--short", "HEAD").stdout.strip() or "unknown"
    return head + ("-dirty" if git("diff", "--quiet", "HEAD").returncode else "")


# --- the manifest --------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    doc: str  # the markdown file, from the root
    header: tuple[str, ...]  # the table's columns
    commands: tuple[str, ...]  # the dynslip commands that measure it, each run with --out DIR
    rows: Callable[[list[Path]], list[list[str]]]  # run folders -> the rows, one cell a string
    small: str  # appended to each command for the small-mesh variant the suite runs
    slow: bool = False  # run only when asked (--slow or by name)
    depends: tuple[str, ...] = PACKAGE  # the package files it depends on (globs) ...
    exclude: tuple[str, ...] = NOT_PHYSICS  # ... less these
    reads: tuple[str, ...] = ()  # other files it reads, when no command names them

    def scenarios(self) -> list[str]:
        """The scenario and sweep files its commands name."""
        from dynslip.cli import build_parser

        parser, out = build_parser(), []
        for cmd in self.commands:
            args = parser.parse_args(shlex.split(cmd)[1:])
            out += [v for a in ("scenario", "sweep") if (v := getattr(args, a, None))]
        return out

    def key(self) -> str:
        files = source_files(self.depends, self.exclude)
        return files_key([*files, *scenario_files([*self.scenarios(), *self.reads])])


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


TABLES: dict[str, Table] = {
    "selection_rule": Table(
        doc="docs/static-model.md",
        header=("model", "mu (rule)", "paper", "difference", "switch angle", "pole stretch",
                "peak lambda_theta (grid)"),
        commands=("dynslip run scenarios/paper_figure4.yaml",),
        rows=selection_rule_rows,
        small="--set numerics.n_nodes=30",
    ),
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
    ("docs/trajectory-contract.md", "| name | meaning |"): "the dataset's attributes",
    ("docs/trajectory-contract.md", "| name | dims | units | meaning |"):
        "the dataset's variables and their units",
    ("docs/trajectory-contract.md", "| name | units | meaning |"):
        "the dataset's variables and their units",
    ("docs/evidence.md", "| variant | caught by |"):
        "which test caught a defect planted in a scratch copy: a record of an experiment on "
        "code that is not the package's",
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
    m = re.search(rf"^<!-- results:{re.escape(name)} -->[^\n]*\n(.*?)^<!-- /results:"
                  rf"{re.escape(name)} -->", text, flags=re.DOTALL | re.MULTILINE)
    return m.span(1) if m else None


def recorded_key(name: str) -> str | None:
    """The key in table ``name``'s provenance line, None without markers or key."""
    text = (ROOT / TABLES[name].doc).read_text()
    span = block(text, name)
    m = PROVENANCE.search(text[span[0] : span[1]]) if span else None
    return m.group(1) if m else None


def stale() -> dict[str, str]:
    """Each table of the manifest whose recorded key is not today's, with what is wrong."""
    out = {}
    for name, t in TABLES.items():
        now, was = t.key(), recorded_key(name)
        if was != now:
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


def measure(name: str, runs_dir: Path, small: bool = False) -> list[list[str]]:
    """Run table ``name``'s commands (each with ``--out`` a folder under ``runs_dir``) and
    return its rows."""
    from dynslip.cli import build_parser, main

    t, parser, folders = TABLES[name], build_parser(), []
    for i, cmd in enumerate(t.commands):
        words = shlex.split(cmd)[1:] + (shlex.split(t.small) if small else [])
        out = runs_dir / name / str(i)
        if hasattr(parser.parse_args(words), "out"):
            words += ["--out", str(out)]
        print(f"  dynslip {shlex.join(words)}", flush=True)
        rc = main(words)
        if rc:
            raise RuntimeError(f"{name}: `dynslip {shlex.join(words)}` exited {rc}")
        folders.append(out)
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
    p.add_argument("--runs", type=Path, default=None,
                   help="folder of the runs (default: a temporary folder)")
    args = p.parse_args(argv)
    unknown = sorted(set(args.names) - set(TABLES))
    if unknown:
        p.error(f"not in the manifest: {', '.join(unknown)}")
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
