"""One dotted path everywhere (dynslip/schema/paths.py): the same path sets the same field
in ``--set``, ``dynslip.load(set=)``, a sweep and a window search."""

import json

import pytest
import yaml

from dynslip.app.members import resolve
from dynslip.app.sweep import expand
from dynslip.errors import InputError
from dynslip.schema.base import load, load_data
from dynslip.schema.paths import get_path, set_path
from dynslip.schema.sweep import friction_field, load_spec, member_at

STAGE = "physics.stages.push_down.clamp_speed_mm_s"
BY_INDEX = "physics.stages.0.clamp_speed_mm_s"


def test_lists_by_index_or_by_name():
    data = {"a": {"items": [{"name": "x", "v": 1}, {"name": "y", "v": 2}]}}
    assert get_path(data, "a.items.y.v") == get_path(data, "a.items.1.v") == 2
    set_path(data, "a.items.x.v", 5)
    set_path(data, "a.items.1", {"name": "z"})
    assert data["a"]["items"] == [{"name": "x", "v": 5}, {"name": "z"}]
    set_path(data, "b.c.d", 1)  # missing sections are created
    assert data["b"] == {"c": {"d": 1}}
    for bad, needle in [
        ("a.items.w.v", "'a.items.w' not found"),
        ("a.items.7", "'7' is not an item"),
        ("a.items.x.v.q", "'v' is not a section"),
        ("a..b", "not a dotted path"),
    ]:
        with pytest.raises(InputError, match=needle):
            set_path(data, bad, 0, "src")
    with pytest.raises(KeyError):
        get_path(data, "a.items.w")


@pytest.mark.parametrize("path", [STAGE, BY_INDEX])
def test_the_same_path_sets_the_same_field_everywhere(path, tmp_path):
    # a forming scenario that lists its stages (the defaults: push_down first)
    stages = resolve({"kind": "forming"}, "defaults")["physics"]["stages"]
    base = tmp_path / "forming.yaml"
    base.write_text(yaml.safe_dump({"kind": "forming", "physics": {"stages": stages}}))

    def speed(scn_or_resolved) -> float:
        d = (
            scn_or_resolved
            if isinstance(scn_or_resolved, dict)
            else json.loads(scn_or_resolved.to_json())
        )
        return d["physics"]["stages"][0]["clamp_speed_mm_s"]

    # --set and dynslip.load(set=)
    assert speed(load(base, [f"{path}=1.25"])) == 1.25
    assert speed(load(base, values={path: 1.25})) == 1.25
    # a sweep: grid and overrides
    sweep = tmp_path / "s.yaml"
    sweep.write_text(
        yaml.safe_dump(
            {"base": str(base), "overrides": {path: 1.5}, "grid": {"numerics.nodes": [20]}}
        )
    )
    assert speed(expand(load_spec(sweep), sweep)[0].resolved) == 1.5
    sweep.write_text(yaml.safe_dump({"base": str(base), "grid": {path: [1.25, 1.75]}}))
    assert [speed(m.resolved) for m in expand(load_spec(sweep), sweep)] == [1.25, 1.75]
    # a window search over that field
    data = load_data(base)
    resolved = resolve(data, str(base))
    field, tied = friction_field(resolved, path)
    assert (field, tied) == (path, [])
    assert speed(resolve(member_at(data, resolved, field, tied, 1.25), "member")) == 1.25
