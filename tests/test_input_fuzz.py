"""Property-based test of bad input (issue 13): scenario and sweep files generated from the
shipped ones, one field corrupted at a time (wrong type, non-finite, out of range, a number
given as text, unknown key, wrong kind).

Through the in-process ``dynslip.cli.main``: ``validate`` exits 2 with exactly one line on
stderr naming the corrupted field, no traceback and no numpy warning; ``run``, ``sweep`` and
``window``, with every runner replaced by a stub that fails the test, exit 2 and leave the
file tree unchanged. Nothing is compiled.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import io
import json
import math
import shutil
import tempfile
import warnings
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dynslip.cli import main
from dynslip.schema.base import kind_classes, load

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
#: one or more shipped scenarios per kind, together using every section of the schemas
SCENARIO_FILES = [
    "cylinder.yaml",
    "paper_gent.yaml",
    "paper_mooney_rivlin.yaml",
    "paper_hookean.yaml",
    "paper_figure4.yaml",
    "paper_family.yaml",
    "method1.yaml",
    "method2.yaml",
    "method2_pinned.yaml",
    "method2_raise.yaml",
    "release.yaml",
]
SWEEP_FILES = ["sweep_method2.yaml", "study_loading_path.yaml"]
BAD_KINDS = [["forming"], {"kind": "forming"}, 3, None, "teleport", "", True]
UNKNOWN = "no_such_field"


# ---------------------------------------------------------------------------------------
# the schema of a leaf of the data


def _resolve(node: dict, defs: dict) -> dict:
    while True:
        if "$ref" in node:
            node = defs[node["$ref"].split("/")[-1]]
        elif len(node.get("allOf") or []) == 1:
            node = node["allOf"][0]
        else:
            return node


def _branch(node: dict, defs: dict, key, data) -> dict:
    """The branch of a union (``X | None``, a discriminated union) that holds ``key``."""
    branches = node.get("oneOf") or node.get("anyOf")
    if not branches or "properties" in node or "items" in node or "prefixItems" in node:
        return node
    cands = [_resolve(b, defs) for b in branches if b.get("type") != "null"]
    if isinstance(key, int):
        cands = [c for c in cands if c.get("type") == "array"]
    else:
        cands = [c for c in cands if key in c.get("properties", {})]
        if isinstance(data, dict) and len(cands) > 1:
            for c in cands:
                for disc in ("model", "kind", "law", "rule"):
                    p = c["properties"].get(disc, {})
                    if disc in data and data[disc] in (p.get("const"), p.get("default")):
                        return c
    return cands[0]


@functools.cache
def _kind_schema(kind: str) -> dict:
    """The JSON schema of a scenario kind, made once (pydantic makes it anew on each call, and
    the cases below ask once per leaf: 16 s of each worker's collection)."""
    return kind_classes()[kind].model_json_schema()


def leaf_schema(kind: str, path: tuple, data: dict) -> dict:
    """The JSON schema of the number, string, ... at ``path`` of scenario ``data``."""
    sch = _kind_schema(kind)
    defs = sch.get("$defs", {})
    node, d = sch, data
    for k in path:
        node = _branch(_resolve(node, defs), defs, k, d)
        if isinstance(k, int):
            node = node["prefixItems"][k] if "prefixItems" in node else node["items"]
        else:
            node = node["properties"][k]
        d = d[k]
    node = _resolve(node, defs)
    for b in node.get("anyOf") or []:  # X | None: the X
        if b.get("type") in ("number", "integer"):
            return b
    return node


def _leaves(data, path=()):
    """Every scalar of the data (items of lists included), and every mapping (for unknown keys)."""
    if isinstance(data, dict):
        yield "mapping", path
        for k, v in data.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            yield from _leaves(v, (*path, i))
    else:
        yield "leaf", path


def _dotted(path) -> str:
    return ".".join(str(p) for p in path)


def _out_of_range(prop: dict) -> list:
    """Values just outside the stated range of a number (none when the range is unstated)."""
    integer = prop.get("type") == "integer"
    out = []
    for key in ("maximum", "exclusiveMaximum"):
        if key in prop:
            b = prop[key]
            out.append(
                b + 1 if integer else (b + max(1.0, abs(b)) if key == "maximum" else float(b))
            )
            out.append(10**30 if integer else 1e300)
    for key in ("minimum", "exclusiveMinimum"):
        if key in prop:
            b = prop[key]
            out.append(
                b - 1 if integer else (b - max(1.0, abs(b)) if key == "minimum" else float(b))
            )
            out.append(-(10**30) if integer else -1e300)
    return out


def _corruptions(name: str) -> list[tuple]:
    """(file, path, value, field named in the error) for every leaf of a resolved shipped
    scenario."""
    sc = load(SCENARIOS / name)
    data = json.loads(sc.to_json())
    cases = [(name, ("kind",), k, "kind") for k in BAD_KINDS]
    for what, path in _leaves(data):
        if what == "mapping":
            cases.append((name, (*path, UNKNOWN), 1, _dotted((*path, UNKNOWN))))
            continue
        if path == ("kind",):
            continue
        prop = leaf_schema(sc.kind, path, data)
        field = _dotted(path)
        cases.append((name, path, {"x": 1}, field))  # wrong type
        cases.append((name, path, [[1]], field))
        if prop.get("type") in ("number", "integer"):
            named = _dotted(path[:-1]) if isinstance(path[-1], int) else field  # an item: its tuple
            for v in (math.nan, math.inf, -math.inf, *_out_of_range(prop)):
                cases.append((name, path, v, named))
            cases.append((name, path, "0.5", named))  # a number given as text
            cases.append((name, path, True, named))
    return cases


def _put(data, path, value):
    data = copy.deepcopy(data)
    node = data
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return data


CASES = [c for f in SCENARIO_FILES for c in _corruptions(f)]
RESOLVED = {f: json.loads(load(SCENARIOS / f).to_json()) for f in SCENARIO_FILES}


# ---------------------------------------------------------------------------------------
# running the CLI in a fresh folder, with the runners stubbed


def _boom(*args, **kwargs):
    raise AssertionError("a runner was reached: bad input must be refused before")


@pytest.fixture
def stubbed(monkeypatch):
    """Every runner, preflight and member function replaced by one that fails the test."""
    import dynslip.app.kinds as kinds

    for k in list(kinds.RUNNERS):
        monkeypatch.setitem(kinds.RUNNERS, k, _boom)
    for k in list(kinds.PREFLIGHTS):
        monkeypatch.setitem(kinds.PREFLIGHTS, k, _boom)
    for cls in kind_classes().values():
        monkeypatch.setattr(cls, "run", _boom, raising=False)
        if hasattr(cls, "preflight"):
            monkeypatch.setattr(cls, "preflight", _boom)
    import dynslip.app.sweep as sweep_mod

    monkeypatch.setattr(sweep_mod, "default_member_fn", _boom, raising=False)
    import dynslip.app.members as members

    monkeypatch.setattr(members, "default_member_fn", _boom)
    return monkeypatch


def _tree(root: Path) -> dict:
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(root.rglob("*"))
    }


def _cli(argv) -> tuple[int, str]:
    err, out = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(out):
        warnings.simplefilter("always")
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as e:  # argparse
            rc = e.code
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [
        str(w.message) for w in caught
    ]
    return rc, err.getvalue()


def _one_line_exit_2(rc, err) -> str:
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err and lines[0].startswith("dynslip: error: "), err
    return lines[0]


@contextlib.contextmanager
def _workdir(monkeypatch):
    """A fresh folder holding the shipped scenarios, as the working directory."""
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for f in SCENARIOS.glob("*.yaml"):
            shutil.copy(f, d / f.name)
        with monkeypatch.context() as m:
            m.chdir(d)
            yield d


def _write(d: Path, data, name="bad.yaml") -> Path:
    path = d / name
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    path.write_text(yaml.dump(data, Dumper=dumper, sort_keys=False, allow_unicode=True))
    return path


def _check_validate(d: Path, case) -> None:
    name, path, value, named = case
    f = _write(d, _put(RESOLVED[name], path, value))
    line = _one_line_exit_2(*_cli(["validate", f]))
    assert f"'{named}" in line, (case, line)


# ---------------------------------------------------------------------------------------
# the tests


def test_the_resolved_shipped_scenarios_validate(stubbed):
    """The corruptions start from valid files (the resolved scenarios, every default filled in)."""
    with _workdir(stubbed) as d:
        for name, data in RESOLVED.items():
            rc, err = _cli(["validate", _write(d, data)])
            assert rc == 0, (name, err)


def test_every_field_non_finite_out_of_range_and_as_text(stubbed):
    """Every numeric field of every kind (stages once), each non-finite, outside its range and
    as text: exit 2, one line naming the field."""
    seen = set()
    cases = []
    for case in CASES:
        name, path, value, named = case
        if (
            value is True
            or value == [[1]]
            or (isinstance(value, (int, float)) and abs(value) >= 1e30)
        ):
            continue  # the extremes (and a second wrong type) are left to the random test below
        kind = RESOLVED[name]["kind"]
        kind = (
            "static" if kind in ("figure4", "family") else kind
        )  # their sections are static's (Geometry ...)
        key = (kind, tuple("[]" if isinstance(p, int) and "stages" in path else p for p in path),
               repr(value) if not isinstance(value, float) or not math.isnan(value) else "nan")
        if key not in seen:
            seen.add(key)
            cases.append(case)
    with _workdir(stubbed) as d:
        for case in cases:
            _check_validate(d, case)
    assert len(cases) > 300  # every field of the five kinds, several corruptions each


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(case=st.sampled_from(CASES))
def test_a_corrupted_scenario_is_one_line_and_writes_nothing(stubbed, case):
    name, path, value, named = case
    with _workdir(stubbed) as d:
        _check_validate(d, case)
        f = d / "bad.yaml"
        before = _tree(d)
        for argv in (["run", f, "--out", d / "out"], ["run", f],
                     ["window", f, "--out", d / "w", "--coarse", "3"]):
            _one_line_exit_2(*_cli(argv))
            assert _tree(d) == before, argv


# --- sweep files


def _sweep_corruptions(name: str) -> list[tuple]:
    """(sweep file, path, value) of a corrupted field of a shipped sweep file."""
    data = yaml.safe_load((SCENARIOS / name).read_text())
    cases = [
        (name, (UNKNOWN,), 1),
        (name, ("base",), ["method2_pinned.yaml"]),
        (name, ("base",), 3),
        (name, ("grid",), {}),
        (name, ("grid", "kind"), [["forming"], {"a": 1}]),
        (name, ("grid", "physics.no_such_field"), [1.0, 2.0]),
        (name, ("overrides", "kind"), ["forming"]),
        (name, ("overrides", "numerics.nodes"), "30"),
        (name, ("overrides", "numerics.nodes"), math.nan),
        (name, ("overrides", "numerics.nodes"), 10**9),
        (name, ("mode",), "warp"),
        (name, ("list",), [{"numerics.nodes": 20}]),
    ]  # grid and list both
    if "base" not in data["grid"]:  # (a swept base replaces the sweep's own)
        cases.append((name, ("base",), "missing.yaml"))
    for key, axis in data["grid"].items():
        if key == "base":
            cases += [(name, ("grid", key, 0), "missing.yaml"), (name, ("grid", key, 0), {"a": 1})]
        elif isinstance(axis, dict):
            for v in (math.nan, math.inf, "0.3", 1e300, [1.0]):
                cases += [(name, ("grid", key, "start"), v), (name, ("grid", key, "stop"), v)]
            for v in (10**9, 0, -1, 2.5, "8", True, math.nan):
                cases.append((name, ("grid", key, "num"), v))
            cases.append((name, ("grid", key, UNKNOWN), 1))
        else:
            for v in (math.nan, -math.inf, "0.3", 1e300, -1e300, {"x": 1}):
                cases.append((name, ("grid", key, 0), v))
    window = {
        "lo": (math.nan, -1.0, math.inf, "1.0", 1e300),
        "hi": (math.nan, -1.0, math.inf, 1e300),
        "coarse": (10**8, 1, 5.5, "5", math.nan),
        "tol": (math.nan, 0.0, -1.0, math.inf, 1e-300, "0.1"),
        UNKNOWN: (1,),
    }
    for key, values in window.items():
        cases += [(name, ("window", key), v) for v in values]
    return cases


SWEEP_CASES = [c for f in SWEEP_FILES for c in _sweep_corruptions(f)]


def _put_sweep(name, path, value):
    data = yaml.safe_load((SCENARIOS / name).read_text())
    data.setdefault("window", {"lo": 1.0, "hi": 2.6, "coarse": 3, "tol": 0.2}) if path[
        0
    ] == "window" else None
    node = data
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return data


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(case=st.sampled_from(SWEEP_CASES))
def test_a_corrupted_sweep_is_one_line_and_writes_nothing(stubbed, case):
    name, path, value = case
    with _workdir(stubbed) as d:
        f = _write(d, _put_sweep(name, path, value), "bad_sweep.yaml")
        before = _tree(d)
        line = _one_line_exit_2(*_cli(["validate", f]))
        for argv in (["sweep", f, "--out", d / "o"], ["sweep", f]):
            line = _one_line_exit_2(*_cli(argv))
            assert _tree(d) == before, argv
        assert any(p in line for p in path if isinstance(p, str)), (
            case,
            line,
        )  # the field, or its section


@pytest.mark.parametrize("text", [
    "{[[[[", "kind: forming\nkind: static\n", "- a\n- b\n", "kind: forming\nphysics: 3\n",
    "kind: forming\nphysics:\n  stages: {a: 1}\n", "kind: forming\nphysics:\n  stages: [1, 2]\n",
    "kind: forming\nphysics:\n  stages: []\n", "'\\x00'", "kind: !!python/object:os.system x\n",
    "kind: forming\nnumerics: &a {nodes: *a}\n",
])
def test_odd_files_are_one_line_and_write_nothing(stubbed, text):
    with _workdir(stubbed) as d:
        f = d / "odd.yaml"
        f.write_text(text)
        before = _tree(d)
        for argv in (
            ["validate", f],
            ["run", f, "--out", d / "out"],
            ["sweep", f, "--out", d / "o"],
            ["window", f, "--out", d / "w"],
        ):
            _one_line_exit_2(*_cli(argv))
            assert _tree(d) == before, argv
