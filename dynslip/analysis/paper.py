"""The paper's numbers that results are compared with (written once, in
:mod:`dynslip.physics.reference`, where the schema's descriptions quote them too).

- :data:`PAPER_MU`: the friction coefficient the paper's static model returns (Fig. 4),
  per material model; Gent at $J_m$ = :data:`PAPER_JM` only (:func:`paper_mu`);
- :data:`ROUGH_END_STATE`: the formed pocket the paper reports, roughly: contact edge at
  $\\theta_{max} \\approx 1.8$ rad, material radius $\\bar r_{max} \\approx 0.9$ R;
- :data:`MEASURED_RELEASE_FORCE_N`: the measured force that pulls the ball out (2.3 N);
- :data:`MEASURED_MU_S`, :data:`MEASURED_MU_K`: the measured static and kinetic friction;
- :data:`MODEL_LABELS`: the material models as the paper, the figures and the tables name them.
"""

from __future__ import annotations

from dynslip.physics.reference import (
    MEASURED_MU_K,
    MEASURED_MU_S,
    MEASURED_RELEASE_FORCE_N,
    PAPER_JM,
    PAPER_MU,
    ROUGH_END_STATE,
)

__all__ = [
    "PAPER_MU",
    "PAPER_JM",
    "paper_mu",
    "ROUGH_END_STATE",
    "MEASURED_RELEASE_FORCE_N",
    "MEASURED_MU_S",
    "MEASURED_MU_K",
    "MODEL_LABELS",
]


def paper_mu(model: str, jm: float | None = None) -> float | None:
    """The paper's mu for a model (Gent only at J_m = PAPER_JM), else None."""
    if model == "gent" and (jm is None or abs(jm - PAPER_JM) > 1e-12):
        return None
    return PAPER_MU.get(model)


MODEL_LABELS = {
    "hookean": "Hookean",
    "neo_hookean": "neo-Hookean",
    "gent": "Gent",
    "mooney_rivlin": "Mooney-Rivlin",
}
"""The material models (``model`` of a material section) as figures and tables name them."""
