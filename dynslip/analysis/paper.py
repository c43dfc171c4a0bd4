"""The paper's numbers that results are compared with, written once.

- :data:`PAPER_MU`: the friction coefficient the paper's static model returns (Fig. 4),
  per material model; Gent at $J_m = 50$ only (:func:`paper_mu`);
- :data:`ROUGH_END_STATE`: the formed pocket the paper reports, roughly: contact edge at
  $\\theta_{max} \\approx 1.8$ rad, material radius $\\bar r_{max} \\approx 0.9$ R;
- :data:`MEASURED_RELEASE_FORCE_N`: the measured force that pulls the ball out (2.3 N).
"""

from __future__ import annotations

__all__ = ["PAPER_MU", "paper_mu", "ROUGH_END_STATE", "MEASURED_RELEASE_FORCE_N", "MEASURED_MU_S", "MEASURED_MU_K"]

PAPER_MU = {"hookean": 1.47, "neo_hookean": 0.99, "gent": 1.1}  # paper Fig. 4 (Gent at J_m = 50)
ROUGH_END_STATE = {"theta_max": 1.8, "rbar_max": 0.9}
MEASURED_RELEASE_FORCE_N = 2.3
MEASURED_MU_S = 0.99  # latex on the ball, static (paper Section 2)
MEASURED_MU_K = 0.82  # kinetic


def paper_mu(model: str, jm: float | None = None) -> float | None:
    """The paper's mu for a model (Gent only at J_m = 50), else None."""
    if model == "gent" and (jm is None or abs(jm - 50.0) > 1e-12):
        return None
    return PAPER_MU.get(model)
