"""Bad input of the tube and band (issue 22 item 1's schema): one line, exit 2, nothing written.

Also: the band scenario builds the tube as a held body with its friction and the band's grip
in G h0 (the file's N/mm divided by G h0 = 0.1 N/mm at the defaults).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynslip.schema.base import load
from helpers import run_refused, set_field

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
BAND = SCENARIOS / "method2_band.yaml"


@pytest.mark.parametrize(
    "dotted, value, words",
    [
        ("physics.tube.wall_mm", 60.0, ("tube.wall_mm", "thicker than the tube")),
        ("physics.tube.wall_mm", 0.0, ("wall_mm",)),
        ("physics.tube.wall_mm", -3.0, ("wall_mm",)),
        ("physics.tube.height_mm", 0.0, ("height_mm",)),
        ("physics.tube.mu", -0.1, ("mu",)),
        ("physics.band_grip_N_per_mm", -1.0, ("band_grip_N_per_mm",)),
        ("physics.tube", None, ("clamp: band", "physics.tube")),
        ("physics.stages.3.force_threshold_N", None, ("ball_reaction_below", "force_threshold_N")),
        ("physics.stages.3.ball", "support", ("ball_reaction_below", "ball: hold")),
    ],
)
def test_bad_tube_and_band_input(tmp_path, capsys, dotted, value, words):
    run_refused(tmp_path, capsys, BAND, set_field(dotted, value), *words)


def test_band_scenario_builds_the_tube_and_the_grip():
    from dynslip.app.forming import build_core
    from dynslip.physics.bodies.held import Held
    from dynslip.physics.protocols import CLAMP_BAND

    sc = load(BAND)
    model, protocol, _ = build_core(sc)
    (tube,) = model.bodies
    assert isinstance(tube, Held)
    np.testing.assert_allclose(float(tube.friction.mu), 0.5)
    wall = tube.body
    r = 20.0
    np.testing.assert_allclose(wall.radius, 50.8 / r)
    np.testing.assert_allclose(wall.edge_radius, 1.5 / r)
    np.testing.assert_allclose(wall.z_bottom, (20.0 + 0.4 + 0.2) / r)  # 0.2 mm above the sheet
    np.testing.assert_allclose(float(model.band_grip), 1.0)  # 0.1 N/mm over G h0 = 0.1 N/mm
    assert [s.clamp_mode for s in protocol.stages].count(CLAMP_BAND) == 5
    # the flat sheet starts below the rim, outside the wall
    z0 = (20.0 + 0.4) / r
    rbar = np.asarray(model.mesh.rbar)
    x = np.stack([sc.physics.pre_stretch * rbar, np.full_like(rbar, z0)], -1)
    assert float(np.min(np.asarray(wall.distance(x)))) > 0.0
