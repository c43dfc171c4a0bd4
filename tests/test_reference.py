"""The paper's numbers are written once (dynslip/physics/reference.py): the analysis compares
with them and the schema's descriptions quote them, so no copy can drift."""

import math

import pytest

from dynslip.physics import reference as ref


def test_analysis_paper_is_the_reference():
    from dynslip.analysis import paper

    for name in (
        "PAPER_MU",
        "PAPER_JM",
        "ROUGH_END_STATE",
        "MEASURED_RELEASE_FORCE_N",
        "MEASURED_MU_S",
        "MEASURED_MU_K",
    ):
        assert getattr(paper, name) is getattr(ref, name)
    assert paper.paper_mu("gent", ref.PAPER_JM) == ref.PAPER_MU["gent"]
    assert paper.paper_mu("gent", 2 * ref.PAPER_JM) is None


@pytest.mark.parametrize(("module", "cls", "field", "quoted"), [
    ("friction", "SlipWeakeningSpec", "mu_s", f"(paper: {ref.MEASURED_MU_S:g})"),
    ("friction", "SlipWeakeningSpec", "mu_k", f"(paper: {ref.MEASURED_MU_K:g})"),
    ("static", "CylinderPhysics", "mu", f"(paper: static {ref.MEASURED_MU_S:g})"),
    ("static", "Figure4Physics", "jm", f"(paper: {ref.PAPER_JM:g})"),
    ("static", "StaticNumerics", "n_nodes", f"(paper: {ref.PAPER_N_NODES})"),
])
def test_schema_descriptions_quote_the_reference(module, cls, field, quoted):
    from importlib import import_module

    model = getattr(import_module(f"dynslip.schema.{module}"), cls)
    assert quoted in model.model_fields[field].description


def test_release_analysis_uses_the_runs_ball_drag():
    """One eta_b formula (physics.protocols), used by the world's builder to build the run and by
    the release analysis to read it back: eta_b = tau 4 pi ball_drag."""
    from dynslip.analysis import release
    from dynslip.physics import protocols
    from dynslip.schema import world

    assert release.ball_drag_coefficient is protocols.ball_drag_coefficient
    assert world.ball_drag_coefficient is protocols.ball_drag_coefficient
    for drag_time_s, ball_drag in [(0.1, 1.0), (0.02, 3.5), (1.0, 0.0)]:
        assert (
            release.ball_drag_coefficient(drag_time_s, ball_drag)
            == protocols.ball_drag_coefficient(drag_time_s, ball_drag)
            == drag_time_s * 4 * math.pi * ball_drag
        )
