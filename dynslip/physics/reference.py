"""The paper's numbers, written once: plain constants, no JAX, so every layer may quote them.

:mod:`dynslip.analysis.paper` compares results with them; the schema's field
descriptions quote them (``dynslip schema``).

- :data:`PAPER_MU`: the friction coefficient the paper's static model returns (Fig. 4),
  per material model; Gent at :data:`PAPER_JM` only;
- :data:`PAPER_JM`: the Gent locking parameter $J_m$ of the paper's Fig. 4;
- :data:`PAPER_N_NODES`: the paper's grid, equally spaced points from the pole to $\\bar r_{max}$;
- :data:`ROUGH_END_STATE`: the formed pocket the paper reports, roughly: contact edge at
  $\\theta_{max} \\approx 1.8$ rad, material radius $\\bar r_{max} \\approx 0.9$ R;
- :data:`MEASURED_RELEASE_FORCE_N`: the measured force that pulls the ball out (N);
- :data:`MEASURED_MU_S`, :data:`MEASURED_MU_K`: the measured static and kinetic friction
  coefficients of latex on the ball (paper Section 2).
"""

from __future__ import annotations

__all__ = ["PAPER_MU", "PAPER_JM", "PAPER_N_NODES", "ROUGH_END_STATE", "MEASURED_RELEASE_FORCE_N",
           "MEASURED_MU_S", "MEASURED_MU_K"]

PAPER_MU = {
    "hookean": 1.47,
    "neo_hookean": 0.99,
    "gent": 1.1,
}  # paper Fig. 4 (Gent at J_m = PAPER_JM)
PAPER_JM = 50.0
PAPER_N_NODES = 100
ROUGH_END_STATE = {"theta_max": 1.8, "rbar_max": 0.9}
MEASURED_RELEASE_FORCE_N = 2.3
MEASURED_MU_S = 0.99  # latex on the ball, static (paper Section 2)
MEASURED_MU_K = 0.82  # kinetic
