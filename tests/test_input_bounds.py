"""Every bad input of issue 13 is one line and exit 2: non-finite and out-of-range numbers,
unbounded counts, binary and non-UTF-8 files, duplicate YAML keys, numbers given as text,
``kind`` as a list or a mapping; the error names the field the user wrote.

Everything goes through the in-process ``dynslip.cli.main`` (nothing is computed: each case
fails validation before any runner is reached).
"""

from __future__ import annotations

import json
import math
import shutil
import warnings
from pathlib import Path

import pytest
import yaml

from dynslip.cli import main
from dynslip.schema.base import kind_classes, parse_override, schema_reference, validate_data
from helpers import one_line

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
PINNED = "method2_pinned.yaml"  # the pinned-rim tube path: its stage fields are named below


def _cli(argv, capsys) -> tuple[int, str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as err:  # argparse
            rc = err.code
    err = capsys.readouterr().err
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [
        str(w.message) for w in caught
    ]
    return rc, err


def _bad(argv, capsys, *words) -> str:
    rc, err = _cli(argv, capsys)
    assert rc == 2, err
    line = one_line(err)
    for w in words:
        assert w in line, line
    return line


def _scenario(tmp_path: Path, name: str, edit=None, text: str | None = None) -> Path:
    """A copy of a shipped scenario (with the shipped files beside it for start_from), edited."""
    for f in SCENARIOS.glob("*.yaml"):
        if not (tmp_path / f.name).exists():
            shutil.copy(f, tmp_path / f.name)
    path = tmp_path / f"bad_{name}"
    if text is not None:
        path.write_text(text)
        return path
    data = yaml.safe_load((SCENARIOS / name).read_text())
    if edit is not None:
        edit(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _put(dotted: str, value):
    def edit(data):
        node = data
        keys = dotted.split(".")
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
        if isinstance(node, list):
            node[int(keys[-1])] = value
        else:
            node[keys[-1]] = value
    return edit


INF, NAN = math.inf, math.nan


# ---------------------------------------------------------------------------------------
# the cases named in the issue


@pytest.mark.parametrize(
    "name, field, value, named",
    [
        (
            PINNED,
            "physics.stages.1.duration_s",
            INF,
            "physics.stages.1.duration_s",
        ),  # OverflowError after 20 s
        ("cylinder.yaml", "numerics.seed", 2**70, "numerics.seed"),  # seed 2^70
        (
            "paper_gent.yaml",
            "numerics.mu_bracket",
            [0.1, INF],
            "numerics.mu_bracket",
        ),  # exit 0 with mu null
        (
            "release.yaml",
            "physics.stages.0.ball_velocity_mm_s",
            NAN,
            "physics.stages.0.ball_velocity_mm_s",
        ),  # step limit after 22 s
        (
            PINNED,
            "physics.stages.0.clamp_to_z_mm",
            NAN,
            "physics.stages.0.clamp_to_z_mm",
        ),  # named a stop rule
        (
            PINNED,
            "physics.ball_radius_mm",
            INF,
            "physics.ball_radius_mm",
        ),  # "rim inside the ball"
        ("paper_gent.yaml", "physics.ball_radius_mm", INF, "physics.ball_radius_mm"),
        (PINNED, "physics.material.jm", INF, "physics.material.jm"),
        (PINNED, "physics.thickness_um", -1e300, "physics.thickness_um"),
        (PINNED, "physics.friction.d_c_mm", 1e300, "physics.friction.d_c_mm"),
        (PINNED, "numerics.rtol", NAN, "numerics.rtol"),
        (PINNED, "numerics.drag_time_s", INF, "numerics.drag_time_s"),
        (PINNED, "numerics.penalty_stiffness", 1e300, "numerics.penalty_stiffness"),
        (PINNED, "numerics.max_steps", 10**12, "numerics.max_steps"),
        (PINNED, "numerics.nodes", 10**6, "numerics.nodes"),
        (
            PINNED,
            "physics.stages.0.clamp_speed_mm_s",
            INF,
            "physics.stages.0.clamp_speed_mm_s",
        ),
        (
            "method2_raise.yaml",
            "physics.stages.2.until.force_N",
            NAN,
            "physics.stages.2.until.force_N",
        ),
        (
            PINNED,
            "physics.stages.4.until.rate_mm_s",
            -INF,
            "physics.stages.4.until.rate_mm_s",
        ),
        ("paper_gent.yaml", "physics.material.jm", 1e300, "physics.material.jm"),
        ("paper_gent.yaml", "numerics.rest_velocity", INF, "numerics.rest_velocity"),
        ("paper_gent.yaml", "numerics.fv_tol", NAN, "numerics.fv_tol"),
        ("paper_gent.yaml", "numerics.switch_guess", [2.2, NAN, 0.25], "numerics.switch_guess"),
        ("paper_gent.yaml", "physics.youngs_modulus_MPa", -1e300, "physics.youngs_modulus_MPa"),
        ("paper_family.yaml", "physics.switch_to", INF, "physics.switch_to"),
        ("paper_figure4.yaml", "physics.jm", NAN, "physics.jm"),
        ("cylinder.yaml", "numerics.n_nodes", 10**9, "numerics.n_nodes"),
        ("cylinder.yaml", "physics.mu", NAN, "physics.mu"),
    ],
)
def test_non_finite_and_out_of_range_name_the_field(tmp_path, capsys, name, field, value, named):
    line = _bad(["validate", _scenario(tmp_path, name, _put(field, value))], capsys, f"'{named}")
    assert "Traceback" not in line


def test_material_model_names_the_model_field(tmp_path, capsys):
    for name in ("paper_gent.yaml", PINNED):
        line = _bad(
            ["validate", _scenario(tmp_path, name, _put("physics.material", {"model": "rubber"}))],
            capsys,
            "'physics.material.model'",
            "rubber",
        )
        assert "'kind'" not in line


@pytest.mark.parametrize("kind", [["forming"], {"a": 1}, 3, None, "teleport"])
def test_kind_of_the_wrong_type_in_a_scenario(tmp_path, capsys, kind):
    _bad(
        ["validate", _scenario(tmp_path, "cylinder.yaml", _put("kind", kind))],
        capsys,
        "'kind'",
        "allowed",
    )


@pytest.mark.parametrize("value", ["[forming]", "{a: 1}", "[1, [2]]"])
def test_kind_of_the_wrong_type_in_set(tmp_path, capsys, value):
    _bad(["validate", SCENARIOS / "cylinder.yaml", "--set", f"kind={value}"], capsys, "'kind'")


@pytest.mark.parametrize("values", [[["forming"], {"a": 1}], [{"a": 1}]])
def test_kind_of_the_wrong_type_in_a_sweep_grid(tmp_path, capsys, values):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    f = tmp_path / "s.yaml"
    f.write_text(yaml.safe_dump({"base": PINNED, "grid": {"kind": values}}))
    _bad(["validate", f], capsys, "'kind'")
    _bad(["sweep", f, "--out", tmp_path / "o"], capsys, "'kind'")
    assert not (tmp_path / "o").exists()


def test_schema_lists_the_bounds(capsys):
    rc, _ = _cli(["schema"], capsys)
    text = schema_reference()
    for field, bound in [
        ("physics.ball_radius_mm", "<= 10000"),
        ("numerics.seed", "<= 2147483646"),
        ("numerics.nodes", "<= 4000"),
        ("physics.stages[].duration_s", "<= 1e+06"),
        ("numerics.mu_bracket", "each >= 0, <= 100"),
        ("numerics.n_nodes", "<= 2000"),
    ]:
        assert any(ln.split()[:1] == [field] and bound in ln for ln in text.splitlines()), (
            field,
            bound,
        )
    assert rc == 0


def test_schema_lists_the_sweep_and_window_counts(capsys):
    rc = main(["schema"])
    out = capsys.readouterr().out
    assert rc == 0
    num = [ln for ln in out.splitlines() if ln.split()[:1] == ["num"]]
    coarse = [ln for ln in out.splitlines() if ln.split()[:1] == ["coarse"]]
    assert num and "<= 10000" in num[0]
    assert coarse and "<= 1000" in coarse[0]
    assert "--coarse 2..1000" in out


def _json_props(schema: dict, defs: dict, prefix: str = ""):
    """(dotted name, JSON schema of a number) for every number of a scenario schema."""
    for name, prop in schema.get("properties", {}).items():
        ref = prop.get("$ref") or (prop.get("allOf") or [{}])[0].get("$ref")
        items = prop.get("items") if isinstance(prop.get("items"), dict) else {}
        if ref:
            yield from _json_props(defs[ref.split("/")[-1]], defs, f"{prefix}{name}.")
        elif items.get("$ref"):
            yield from _json_props(defs[items["$ref"].split("/")[-1]], defs, f"{prefix}{name}[].")
        elif "anyOf" in prop and any("$ref" in p for p in prop["anyOf"]):
            for p in prop["anyOf"]:
                if "$ref" in p:
                    yield from _json_props(defs[p["$ref"].split("/")[-1]], defs, f"{prefix}{name}.")
        else:
            for i, p in enumerate(prop.get("prefixItems") or [prop]):
                for q in p.get("anyOf") or [p]:
                    if q.get("type") in ("number", "integer"):
                        yield (f"{prefix}{name}" + (f".{i}" if "prefixItems" in prop else ""), q)


def test_every_number_of_every_kind_has_a_stated_range():
    """Every numeric field: a lower and an upper bound in the schema (shown by `dynslip schema`)."""
    unbounded = []
    for kind, cls in kind_classes().items():
        sch = cls.model_json_schema()
        for name, p in _json_props(sch, sch.get("$defs", {})):
            lo = "minimum" in p or "exclusiveMinimum" in p
            hi = "maximum" in p or "exclusiveMaximum" in p
            if not (lo and hi):
                unbounded.append(f"{kind}: {name}")
    assert not unbounded, f"numeric fields without a stated range: {unbounded}"


# ---------------------------------------------------------------------------------------
# counts


def test_sweep_axis_num_is_bounded(tmp_path, capsys):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    f = tmp_path / "s.yaml"
    f.write_text(
        "base: method2_pinned.yaml\ngrid:\n  physics.friction.mu: {start: 0.3, stop: 2.0, num: "
        "1000000000}\n"
    )
    line = _bad(["sweep", f, "--out", tmp_path / "o"], capsys, "num", "1000000000", "10000")
    assert "grid" in line
    assert not (tmp_path / "o").exists()


def test_sweep_members_are_bounded(tmp_path, capsys):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    f = tmp_path / "s.yaml"
    f.write_text(
        "base: method2_pinned.yaml\n"
        "grid:\n  physics.friction.mu: {start: 0.3, stop: 2.0, num: 200}\n"
        "  physics.friction.mu_s: {start: 0.3, stop: 2.0, num: 200}\n"
    )
    _bad(["sweep", f, "--out", tmp_path / "o"], capsys, "40000 members", "10000")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "window, word",
    [
        ("{coarse: 100000000}", "coarse"),
        ("{tol: .nan}", "tol"),
        ("{hi: .inf}", "hi"),
        ("{lo: -1.0}", "lo"),
        ("{tol: '0.1'}", "tol"),
        ("{coarse: 5.5}", "coarse"),
    ],
)
def test_sweep_window_is_bounded(tmp_path, capsys, window, word):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    f = tmp_path / "s.yaml"
    f.write_text(f"base: {PINNED}\ngrid:\n  numerics.nodes: [20, 30]\nwindow: {window}\n")
    _bad(["sweep", f, "--out", tmp_path / "o"], capsys, f"window.{word}")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, word", [
    (["--coarse", "100000000"], "coarse"), (["--coarse", "1"], "coarse"), (["--tol", "nan"], "tol"),
    (["--tol", "inf"], "tol"), (["--tol", "1e-300"], "tol"), (["--lo", "nan"], "range"),
    (["--hi", "inf"], "range"), (["--hi", "1e300"], "range"), (["--hi", "50"], "mu"),
])
def test_window_arguments_are_bounded(tmp_path, capsys, args, word):
    out = tmp_path / "w"
    _bad(["window", SCENARIOS / PINNED, "--out", out, *args], capsys, word)
    assert not out.exists()


def test_clamp_move_and_saved_frames_are_bounded(tmp_path, capsys):
    _bad(
        [
            "validate",
            _scenario(tmp_path, PINNED, _put("physics.stages.0.clamp_speed_mm_s", 1e-6)),
        ],
        capsys,
        "push_down",
        "1e6 s",
    )
    _bad(["validate", SCENARIOS / PINNED, "--set", "numerics.save_interval_s=1e-4"], capsys,
         "save_interval_s", "frames")
    _bad(["validate", SCENARIOS / "cylinder.yaml", "--set", "numerics.n_profiles=10000",
          "--set", "numerics.n_nodes=10000"], capsys, "n_profiles * n_nodes")


def test_stages_are_bounded(tmp_path, capsys):
    stages = [{"name": "push_down", "clamp_to_z_mm": -160.0, "clamp_speed_mm_s": 2.0}]
    stages += [{"name": f"hold{i}", "duration_s": 1.0} for i in range(200)]
    _bad(["validate", _scenario(tmp_path, PINNED, _put("physics.stages", stages))], capsys,
         "physics.stages")


# ---------------------------------------------------------------------------------------
# files


@pytest.mark.parametrize("content, word", [
    (b"\xff\xfe\x00k\x00i\x00n\x00d", "UTF-8"),
    ("kind: cylinder\nname: caf\u00e9\n".encode("latin-1"), "UTF-8"),
    (b"kind: cylinder\n\x00\x01\x02\x03", "binary"),
    (bytes(range(256)) * 4, "UTF-8"),
])
def test_binary_and_non_utf8_files(tmp_path, capsys, content, word):
    f = tmp_path / "bad.yaml"
    f.write_bytes(content)
    for cmd in (
        ["validate", f],
        ["run", f, "--out", tmp_path / "o"],
        ["sweep", f, "--out", tmp_path / "o"],
        ["window", f, "--out", tmp_path / "o"],
    ):
        _bad(cmd, capsys, word)
    assert not (tmp_path / "o").exists()


def test_utf8_with_a_bom_and_accents_is_read(tmp_path, capsys):
    f = tmp_path / "ok.yaml"
    f.write_bytes("\ufeffkind: cylinder\nname: caf\u00e9 \u00e0 20\u00b0C\n".encode())
    rc, err = _cli(["validate", f], capsys)
    assert rc == 0, err


@pytest.mark.parametrize(
    "text, key",
    [
        ("kind: cylinder\nphysics: {mu: 0.5}\nphysics: {mu: 0.6}\n", "physics"),
        ("kind: cylinder\nphysics:\n  mu: 0.5\n  mu: 0.6\n", "mu"),
        (
            "kind: forming\nphysics:\n  stages:\n    - {name: a, duration_s: 1.0, duration_s: "
            "2.0}\n",
            "duration_s",
        ),
    ],
)
def test_duplicate_keys_in_a_scenario(tmp_path, capsys, text, key):
    f = tmp_path / "dup.yaml"
    f.write_text(text)
    _bad(["validate", f], capsys, "duplicate key", repr(key), "line")


def test_duplicate_keys_in_a_sweep(tmp_path, capsys):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    f = tmp_path / "s.yaml"
    f.write_text(f"base: {PINNED}\ngrid:\n  numerics.nodes: [20, 30]\n  numerics.nodes: [40]\n")
    _bad(["sweep", f, "--out", tmp_path / "o"], capsys, "duplicate key", "numerics.nodes")
    _bad(["validate", f], capsys, "duplicate key")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name, field, value", [
    ("cylinder.yaml", "physics.mu", "0.5"),
    ("cylinder.yaml", "numerics.seed", "3"),
    (PINNED, "physics.ball_radius_mm", "20"),
    (PINNED, "physics.stages.1.duration_s", "10.0"),
    ("paper_gent.yaml", "numerics.mu_bracket", ["0.1", 5.0]),
    (PINNED, "numerics.nodes", True),
])
def test_numbers_given_as_text_are_refused_in_files(tmp_path, capsys, name, field, value):
    _bad(["validate", _scenario(tmp_path, name, _put(field, value))], capsys, f"'{field}", "number")


def test_numbers_given_as_text_are_refused_in_sweep_files(tmp_path, capsys):
    shutil.copy(SCENARIOS / PINNED, tmp_path / PINNED)
    for grid in ("{physics.friction.mu: {start: '0.3', stop: 2.0, num: 3}}",
                 "{physics.friction.mu: {start: 0.3, stop: 2.0, num: '3'}}",
                 "{physics.friction.mu: ['0.3', 0.5]}"):
        f = tmp_path / "s.yaml"
        f.write_text(f"base: method2_pinned.yaml\ngrid: {grid}\n")
        _bad(["sweep", f, "--out", tmp_path / "o"], capsys)
    f.write_text(
        "base: method2_pinned.yaml\noverrides: {numerics.nodes: '30'}\ngrid: {physics.friction.mu: "
        "[0.5]}\n"
    )
    _bad(["sweep", f, "--out", tmp_path / "o"], capsys, "numerics.nodes")
    assert not (tmp_path / "o").exists()


def test_set_values_are_parsed_as_yaml(capsys):
    assert parse_override("numerics.rtol=1e-5") == ("numerics.rtol", 1e-5)
    assert parse_override("numerics.nodes=30") == ("numerics.nodes", 30)
    rc, err = _cli(["validate", SCENARIOS / PINNED, "--set", "numerics.rtol=1e-5",
                    "--set", "numerics.nodes=30", "--set", "physics.ball_radius_mm=2e1"], capsys)
    assert rc == 0, err
    _bad(
        ["validate", SCENARIOS / PINNED, "--set", "numerics.nodes='30'"],
        capsys,
        "numerics.nodes",
    )
    _bad(
        ["validate", SCENARIOS / PINNED, "--set", "numerics.rtol=.nan"],
        capsys,
        "numerics.rtol",
    )


def test_exponent_without_a_dot_is_a_number_in_files(tmp_path, capsys):
    f = tmp_path / "e.yaml"
    f.write_text("kind: forming\nnumerics:\n  rtol: 1e-5\n  atol: 1E-7\n")
    rc, err = _cli(["validate", f], capsys)
    assert rc == 0, err
    sc = validate_data(
        yaml.load(f.read_text(), Loader=__import__("dynslip.schema.base").schema.base.Loader)
    )
    assert sc.numerics.rtol == 1e-5 and sc.numerics.atol == 1e-7


def test_a_newline_in_a_value_staysone_line(tmp_path, capsys):
    stages = [
        {"name": "a\nb\nc", "clamp_to_z_mm": 20.4, "clamp_speed_mm_s": 2.0}
    ]  # empty stage: named
    _bad(
        ["validate", _scenario(tmp_path, PINNED, _put("physics.stages", stages))],
        capsys,
        "empty stage",
    )
    _bad(["validate", SCENARIOS / PINNED, "--set", 'name=[1, "x\\ny"]'], capsys, "name")


def test_no_numpy_warnings_on_the_way(tmp_path, capsys):
    """The issue saw numpy warnings printed during validate of huge values: none now."""
    for name, field, value in [(PINNED, "physics.ball_radius_mm", 1e308),
                               (PINNED, "physics.stages.1.clamp_velocity_mm_s", -1e308),
                               ("paper_gent.yaml", "physics.thickness_mm", 1e308),
                               ("cylinder.yaml", "physics.theta_max_to", 1e308)]:
        _bad(
            ["validate", _scenario(tmp_path, name, _put(field, value))], capsys
        )  # _cli asserts no warnings


def test_messages_quote_what_was_given(tmp_path, capsys):
    line = _bad(
        ["validate", _scenario(tmp_path, "cylinder.yaml", _put("numerics.seed", 2**70))], capsys
    )
    assert json.dumps(2**70) in line and "2147483646" in line
