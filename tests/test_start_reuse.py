"""``start_from`` naming a scenario reuses the saved run in ``outputs/<stem>/`` only where that
run can stand for a run now (:func:`dynslip.app.release.reusable`): it finished, and the same
resolved scenario was run by the same dynslip version at the same commit."""

from dynslip.app.release import reusable
from dynslip.data.files import provenance

SCENARIO = '{"kind": "forming", "physics": {"pre_stretch": 1.1}}'


def test_a_saved_start_is_reused_only_by_the_same_scenario_version_and_commit():
    saved = {**provenance(SCENARIO, "forming"), "complete": 1}
    assert reusable(saved, SCENARIO)
    assert not reusable({**saved, "complete": 0}, SCENARIO)
    assert not reusable(saved, SCENARIO.replace("1.1", "1.2"))
    assert not reusable({**saved, "git_commit": "0" * 40}, SCENARIO)
    assert not reusable({**saved, "dynslip_version": saved["dynslip_version"] + ".post1"},
                        SCENARIO)
    assert not reusable({k: v for k, v in saved.items() if k != "git_commit"}, SCENARIO)
