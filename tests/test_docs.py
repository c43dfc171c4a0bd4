"""The docs against the code: every figure the docs show is made by docs/figures.py (its
manifest), and nothing else lies in docs/img; each figure names the command that makes it;
no heading cites an issue number; every command the docs give parses with the command
line's own parser and names scenario files that validate; the Python API page has no
example the suite skips."""

import importlib.util
import re
import shlex
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
    import yaml

    return yaml.safe_load(text)


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
