"""A body kind added from outside the package: one spec class (a ``ShapeSpec`` with its
``kind``, its sizes in mm and ``core``), one registration (``BODY_KINDS``). The scenario file
then names it for a held body, and the run uses it.

The kind here is a ring given by its inner and outer diameters (a washer with a round
section), built as the core's torus: the run with it is the run with the built-in ``kind:
torus`` of ring radius (d_o + d_i) / 4 and minor radius (d_o - d_i) / 4, every saved number to
1e-12, and the sheet pressed against it rests on its surface."""

from __future__ import annotations

from typing import Literal

import numpy as np
import pytest
from pydantic import Field

from dynslip.api import run
from dynslip.errors import InputError
from dynslip.schema.base import validate_data
from dynslip.schema.bodies import BODY_KINDS, ShapeSpec
from helpers import registered

INNER_MM, OUTER_MM, Z_MM = 40.0, 76.0, -8.0
R = 20.0  # ball_radius_mm at the defaults


class WasherSpec(ShapeSpec):
    """The scenario file's ``kind: washer``: a ring of round section by its two diameters."""

    kind: Literal["washer"] = "washer"
    inner_diameter_mm: float = Field(..., gt=0, le=1e4)
    outer_diameter_mm: float = Field(..., gt=0, le=1e4)

    def core(self, r: float, z: float = 0.0):
        from dynslip.physics.bodies import Torus

        return Torus((self.outer_diameter_mm + self.inner_diameter_mm) / 4 / r,
                     (self.outer_diameter_mm - self.inner_diameter_mm) / 4 / r, centre_z=z)


@pytest.fixture
def washer():
    with registered(BODY_KINDS, WasherSpec):
        yield WasherSpec


def _scenario(body: dict) -> dict:
    """The clamp pulled 40 mm down at N = 30 over a ring just below the flat sheet, outside
    the ball: the sheet wraps the ring's top."""
    return {
        "kind": "forming",
        "physics": {
            "friction": {"law": "coulomb", "mu": 0.5},
            "bodies": [{"name": "ring", "z_mm": Z_MM, **body}],
            "stages": [{"name": "push", "clamp_to_z_mm": -40.0, "clamp_speed_mm_s": 4.0},
                       {"name": "hold", "duration_s": 2.0}],
        },
        "numerics": {"nodes": 30, "save_interval_s": 1.0},
    }


WASHER = {"kind": "washer", "inner_diameter_mm": INNER_MM, "outer_diameter_mm": OUTER_MM}
TORUS = {"kind": "torus", "ring_radius_mm": (OUTER_MM + INNER_MM) / 4,
         "minor_radius_mm": (OUTER_MM - INNER_MM) / 4}


def test_a_kind_registered_from_outside_runs_as_the_builtin_kind_it_restates(washer):
    """``kind: washer`` (registered here) as a held body: the run is the built-in torus's run,
    every saved number to 1e-12; the nodes flagged in contact with the ring are those within
    the contact threshold of the torus's surface (the closed-form distance to its centre
    circle less the minor radius), and the contact's extent in s is theirs."""
    outside = validate_data(_scenario(WASHER))
    builtin = validate_data(_scenario(TORUS))
    assert isinstance(outside.physics.bodies[0], WasherSpec)
    assert outside.physics.bodies[0].name == "ring"
    a, b = run(outside).trajectory, run(builtin).trajectory
    assert a.sizes["time"] == b.sizes["time"] > 3
    for name in b.data_vars:
        va, vb = a[name].values, b[name].values
        if np.issubdtype(vb.dtype, np.number):
            np.testing.assert_allclose(va, vb, rtol=0, atol=1e-12, err_msg=name)
    contact = a["body_contact"].values[-1, 0].astype(bool)
    assert contact.sum() >= 3
    rho, z = a["rho"].values[-1], a["z"].values[-1]  # units of R
    ring, minor = (OUTER_MM + INNER_MM) / 4 / R, (OUTER_MM - INNER_MM) / 4 / R
    gap = np.hypot(rho - ring, z - Z_MM / R) - minor  # the closed-form distance to the torus
    thr = a.attrs["contact_threshold"]
    np.testing.assert_array_equal(contact, gap < thr)
    assert np.all(gap > -thr)  # pressed in by the penalty, less than the threshold
    s = a["body_s"].values[-1, 0][contact]
    assert a["body_s_min"].values[-1, 0] == s.min() and a["body_s_max"].values[-1, 0] == s.max()

def test_a_registered_kind_is_named_in_the_refusal_of_an_unknown_one(washer):
    """After registration the schema lists the new kind among the held bodies' kinds, its sizes
    are checked as the built-in ones, it may not be the ball (no ``can_be_ball``), and a tag
    already taken is refused; unregistered, the kind is unknown again."""
    with pytest.raises(InputError, match="'washer'") as err:
        validate_data(_scenario({**WASHER, "kind": "washr"}))
    assert "physics.bodies.0.kind" in str(err.value)
    with pytest.raises(InputError, match="a washer needs outer_diameter_mm"):
        validate_data(_scenario({"kind": "washer", "inner_diameter_mm": INNER_MM}))
    with pytest.raises(InputError, match="radius_mm is not a size of a washer"):
        validate_data(_scenario({**WASHER, "radius_mm": 3.0}))
    ball = _scenario(TORUS)
    ball["physics"]["ball"] = dict(WASHER)
    with pytest.raises(InputError, match="physics.ball.kind") as err:
        validate_data(ball)
    assert "allowed: 'sphere', 'disc'" in str(err.value)
    with pytest.raises(ValueError, match="already registered"):
        BODY_KINDS.register(type("Other", (WasherSpec,), {"__doc__": "another"}))
    BODY_KINDS.unregister(WasherSpec)
    with pytest.raises(InputError, match="physics.bodies.0.kind"):
        validate_data(_scenario(WASHER))
    BODY_KINDS.register(WasherSpec)
