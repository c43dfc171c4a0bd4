"""The docs against the code: every figure the docs show is made by docs/figures.py (its
manifest), and nothing else lies in docs/img; each figure names the command that makes it;
no heading cites an issue number; every command the docs give parses with the command
line's own parser and names scenario files that validate; the Python API page has no
example the suite skips. Every table of numbers is under docs/results.py's manifest, whose
commands parse and run at a small mesh, and no table or figure was made before a change to
the code it depends on (its recorded key is today's)."""

import importlib.util
import re
import shlex
import shutil
import sys
from pathlib import Path

import pytest

import dynslip
from dynslip.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
IMG = ROOT / "docs" / "img"


def _figures_module():
    spec = importlib.util.spec_from_file_location("docs_figures", ROOT / "docs" / "figures.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up by name
    spec.loader.exec_module(mod)
    return mod


FIG = _figures_module()
RES = FIG._results()  # docs/results.py, the tables' manifest and the key figures share

def _image_refs() -> dict[str, list[tuple[Path, int]]]:
    """Image name -> (doc, line of the reference's end) of every ``![...](.../img/NAME)`` in
    the docs (the alt text may run over lines)."""
    refs: dict[str, list[tuple[Path, int]]] = {}
    for doc in DOCS:
        text = doc.read_text()
        for m in re.finditer(r"!\[[^\]]*\]\((?:docs/)?img/([^)]+)\)", text):
            refs.setdefault(m.group(1), []).append((doc, text.count("\n", 0, m.end())))
    return refs


def test_every_shown_image_is_made_by_the_script_and_every_made_one_is_shown():
    refs = _image_refs()
    assert refs, "no image found in the docs"
    assert set(refs) == set(FIG.FIGURES), (
        sorted(set(refs) - set(FIG.FIGURES)),
        sorted(set(FIG.FIGURES) - set(refs)),
    )
    on_disk = {p.name for p in IMG.iterdir()}
    assert on_disk == set(FIG.FIGURES), ("stale or missing:", sorted(on_disk ^ set(FIG.FIGURES)))
    for name, fig in FIG.FIGURES.items():
        assert fig.run in FIG.RUNS and callable(getattr(FIG, fig.draw)), name
        assert (ROOT / FIG.RUNS[fig.run].scenario).is_file(), name


def test_every_image_names_the_command_that_makes_it():
    """Within three lines of each image: ``docs/figures.py`` (the one command)."""
    for name, places in _image_refs().items():
        for doc, i in places:
            lines = doc.read_text().splitlines()
            near = "\n".join(lines[max(0, i - 3) : i + 4])
            assert "docs/figures.py" in near, f"{doc.name}:{i + 1}: {name} without its command"


def test_no_doc_cites_an_issue_number():
    for doc in DOCS:
        if doc.name in ("speed.md", "export.md", "evidence.md"):
            continue
        hits = re.findall(r".{0,30}\(issue \d+.{0,10}|.{0,30}issue-\d+.{0,10}", doc.read_text())
        assert not hits, (doc.name, hits)


def _commands() -> list[tuple[str, str]]:
    """(doc, command) of every ``dynslip ...`` in the docs: inline code spans, and the lines of
    ```bash blocks."""
    out = []
    for doc in DOCS:
        text = doc.read_text()
        for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE):
            for line in block.splitlines():
                for part in line.split("&&"):
                    if part.strip().startswith("dynslip "):
                        out.append((doc.name, part.strip()))
        text = re.sub(r"^```.*?^```", "", text, flags=re.DOTALL | re.MULTILINE)
        out += [(doc.name, " ".join(c.split())) for c in re.findall(r"`(dynslip [^`]+)`", text)]
    return out


#: placeholders the docs write for a value or file the reader chooses (SCENARIO, DIR, S,
#: 63.5L): a command with one is a synopsis of a family of runs, parsed, not validated
PLACEHOLDER = re.compile(r"(?<![\w.])[0-9.]*[A-Z][A-Z_0-9]*(?:\.yaml)?(?![\w.])")


def test_every_command_in_the_docs_parses_and_its_scenario_validates():
    """A synopsis (``[...]`` optional parts) and a bare command or option name are references,
    not commands; every other command parses with ``dynslip``'s parser, and a scenario file it
    names loads with its ``--set`` fields (the shipped scenarios themselves are run at tiny
    meshes by tests/test_shipped.py)."""
    parser = build_parser()
    checked = 0
    for doc, cmd in _commands():
        words = shlex.split(cmd)[1:]
        if (
            "[" in cmd
            or len(words) < 2
            or words[1].startswith("--")
            or words[0] in ("--help", "--version")
        ):
            if words and words[0] not in ("--help", "--version") and not words[0].isupper():
                assert words[0] in parser._subparsers._group_actions[0].choices, (doc, cmd)
            continue
        args = parser.parse_args(words)
        checked += 1
        if PLACEHOLDER.search(" ".join(words[1:])):
            continue
        scenario = getattr(args, "scenario", None)
        if scenario and scenario.startswith("scenarios/"):
            sets = dict(s.split("=", 1) for s in (args.set or []))
            dynslip.load(ROOT / scenario, set={k: _value(v) for k, v in sets.items()})
        sweep = getattr(args, "sweep", None)
        if sweep:
            assert (ROOT / sweep).is_file(), (doc, cmd)
    assert checked >= 20


def _value(text: str):
    """A ``--set`` value read as the command line reads it (YAML 1.2: ``1e4`` is a number)."""
    from dynslip.schema.base import parse_value

    return parse_value(text)


def test_python_api_page_skips_no_example():
    text = (ROOT / "docs" / "python-api.md").read_text()
    assert "```python skip" not in text
    blocks = re.findall(r"^```python\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE)
    failing = [b for b in blocks if "except dynslip.ComputationError" in b]
    assert failing and all("else:\n    raise AssertionError" in b for b in failing), (
        "the failure example must fail"
    )


@pytest.mark.slow
def test_figures_script_makes_every_figure(tmp_path):
    """``python docs/figures.py --fast``: every figure of the manifest is drawn (about 3 min)."""
    assert (
        FIG.main(["--fast", "--runs", str(tmp_path / "runs"), "--img", str(tmp_path / "img")]) == 0
    )
    made = {p.name: p.stat().st_size for p in (tmp_path / "img").iterdir()}
    assert set(made) == set(FIG.FIGURES) and all(v > 10_000 for v in made.values()), made
    assert not FIG.stale_figures(tmp_path / "img", fast=True)  # each stamped with its key


# --- measured tables and figures with a key (docs/results.py, docs/figures.py) -----------


def test_every_table_of_numbers_is_under_the_results_manifest():
    """A table "holds numbers" when a body cell has a digit outside code spans and link
    targets; each is between results markers unless docs/results.py's REFERENCE lists it
    (the commands, the schema's fields and units, ...) with its reason."""
    missing = RES.unmarked_tables()
    if missing:
        pytest.fail(f"{len(missing)} tables of numbers under no results marker:\n"
                    + "\n".join(t.where() for t in missing))


def test_results_markers_and_manifest_agree():
    """Each manifest entry has one pair of markers in its file, around one table with the
    manifest's header; every marker of the docs names an entry of that file; every
    REFERENCE entry is a table of the docs."""
    tables = [t for p in RES.doc_files() for t in RES.doc_tables(p)]
    for name, entry in RES.TABLES.items():
        text = (ROOT / entry.doc).read_text()
        assert text.count(f"<!-- results:{name} -->") == 1, (name, entry.doc)
        assert RES.block(text, name) is not None, f"{entry.doc}: {name}'s markers do not close"
        under = [t for t in tables if t.marker == name]
        assert [t.doc for t in under] == [entry.doc], (name, [t.where() for t in under])
        assert under[0].header == "| " + " | ".join(entry.header) + " |", (name, under[0].header)
    for doc in RES.doc_files():
        for name in re.findall(r"<!-- /?results:([\w.-]+) -->", doc.read_text()):
            entry = RES.TABLES.get(name)
            where = doc.relative_to(ROOT).as_posix()
            assert entry is not None and entry.doc == where, f"{where}: marker {name}"
    known = {(t.doc, t.header) for t in tables}
    assert set(RES.REFERENCE) <= known, sorted(set(RES.REFERENCE) - known)


def test_every_results_command_parses():
    """Each command of the manifest is a ``dynslip`` command that parses with the command
    line's parser, as given and with its small-mesh arguments, or a script of docs/ or
    benchmarks/ that exists; its scenario files exist; its rows come from a function."""
    parser = build_parser()
    for name, entry in RES.TABLES.items():
        assert entry.commands and callable(entry.rows), name
        small_env, small = RES.split_command(entry.small)
        for cmd in (*entry.commands, *(entry.small_commands or ())):
            env, words = RES.split_command(cmd)
            assert all(re.fullmatch(r"[A-Z_][A-Z0-9_]*", k) for k in {**env, **small_env}), name
            if words[0] == "python":
                assert words[1].startswith(("docs/", "benchmarks/")), (name, cmd)
                assert (ROOT / words[1]).is_file(), (name, cmd)
                continue
            assert words[0] == "dynslip", (name, cmd)
            words = [re.sub(r"\{run:\d+\}", "RUN", w) for w in words]  # an earlier run's folder
            parser.parse_args(words[1:])
            parser.parse_args(words[1:] + RES.accepted(words[1], small))
        for scenario in entry.scenarios():
            assert (ROOT / scenario).is_file(), (name, scenario)
        assert re.fullmatch(r"[0-9a-f]{12}", entry.key()), name


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory):
    """One folder for every table's small runs: a command two tables share runs once."""
    return tmp_path_factory.mktemp("results_runs")


#: tables whose small variant is slow although the table is not: a fresh process's run and
#: compile (about 40 s, the heaviest test of the quick loop), whose scenario a quick test runs
#: in the suite's process (its reading of the run folder into rows is checked by CI)
SMALL_SLOW = {"selection_rule": "tests/test_static_runs.py::test_figure4_scenario"}


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=[pytest.mark.slow]
                  if (t.slow and not t.small_quick) or n in SMALL_SLOW else [])
     for n, t in RES.TABLES.items()],
)
def test_results_small_variant_runs(name, runs_dir):
    """The table's commands at a small mesh (its ``small`` arguments, or its small commands)
    run and give a row of the table's width for each row of its file. The quick suite runs
    the tables that are not slow and those marked ``small_quick``, less :data:`SMALL_SLOW`; the
    others are slow."""
    entry = RES.TABLES[name]
    rows = RES.measure(name, runs_dir, small=True)
    text = (ROOT / entry.doc).read_text()
    span = RES.block(text, name)
    shown = [t for t in RES.doc_tables(ROOT / entry.doc) if t.marker == name]
    assert span and shown and len(rows) == len(shown[0].body), (name, rows)
    assert all(len(r) == len(entry.header) and all(r) for r in rows), rows
    assert RES.PROVENANCE.search(RES.render(entry, rows, name, small=True))


def test_no_table_was_measured_before_a_change_to_its_code():
    """Every table is measured at today's code, or says under its provenance line that it is
    not, naming today's key (``python docs/results.py --mark-outdated``)."""
    stale = RES.stale()
    if stale:
        pytest.fail("stale tables (rerun `python docs/results.py NAME`, or say they are not "
                    "today's: `--mark-outdated NAME`):\n"
                    + "\n".join(f"{name}: {why}" for name, why in stale.items()))


def test_no_committed_figure_was_drawn_before_a_change_to_its_code():
    stale = FIG.stale_figures()
    if stale:
        pytest.fail("stale figures (redraw: `python docs/figures.py --stale`):\n"
                    + "\n".join(f"docs/img/{name}: {why}" for name, why in stale.items()))


def test_figure_key_is_a_png_text_chunk(tmp_path):
    """stamp writes the key as a tEXt chunk that Pillow reads, replaces an earlier one, and
    leaves the image's pixels as they were."""
    from PIL import Image

    png = tmp_path / "f.png"
    shutil.copyfile(IMG / "fronts_let_go.png", png)
    FIG.stamp(png, "0123456789ab")
    FIG.stamp(png, "ba9876543210")
    assert FIG.read_key(png) == "ba9876543210"
    with Image.open(png) as new, Image.open(IMG / "fronts_let_go.png") as old:
        assert new.text[FIG.KEY_FIELD] == "ba9876543210"
        assert new.tobytes() == old.tobytes()
    assert png.read_bytes().count(FIG.KEY_FIELD.encode()) == 1


def test_a_change_to_the_physics_or_the_plotting_makes_its_tables_and_figures_stale(
    tmp_path, monkeypatch
):
    """In a copy of the package, the docs and the scenarios, with every table and figure
    recorded at today's key: a constant of a material changed makes every table and figure
    stale; a change to the plotting code, the figures only; a change to the command line,
    nothing."""
    for part in ("dynslip", "docs", "scenarios"):
        shutil.copytree(ROOT / part, tmp_path / part, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copyfile(ROOT / "README.md", tmp_path / "README.md")
    monkeypatch.setattr(RES, "ROOT", tmp_path)
    img = tmp_path / "docs" / "img"
    for name in RES.TABLES:
        RES.write(name, f"key: {RES.TABLES[name].key()}\n")
    for name in FIG.FIGURES:
        FIG.stamp(img / name, FIG.figure_key(name))
    assert not RES.stale() and not FIG.stale_figures(img)

    def edit(rel: str):
        path = tmp_path / rel
        path.write_text(path.read_text() + "\n# edited\n")

    edit("dynslip/cli/__init__.py")
    assert not RES.stale() and not FIG.stale_figures(img)
    edit("dynslip/plot/style.py")
    assert not RES.stale() and set(FIG.stale_figures(img)) == set(FIG.FIGURES)
    for name in FIG.FIGURES:
        FIG.stamp(img / name, FIG.figure_key(name))
    edit("dynslip/physics/materials.py")
    assert set(RES.stale()) == set(RES.TABLES)
    assert set(FIG.stale_figures(img)) == set(FIG.FIGURES)
    # a stale table that says so, naming today's key, is shown as outdated, not as today's;
    # a further change makes it stale again, and measuring it drops the line
    assert set(RES.mark_outdated(RES.TABLES)) == set(RES.TABLES)
    assert not RES.stale() and set(RES.outdated()) == set(RES.TABLES)
    name = next(iter(RES.TABLES))
    assert RES.OUTDATED.search((tmp_path / RES.TABLES[name].doc).read_text())
    edit("dynslip/physics/sheet.py")
    assert set(RES.stale()) == set(RES.TABLES) and not RES.outdated()
    RES.write(name, f"key: {RES.TABLES[name].key()}\n")
    assert name not in RES.stale() and name not in RES.outdated()
    assert RES.outdated_key(name) is None
