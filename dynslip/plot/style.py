"""One palette and one set of labels for every figure and animation.

- :data:`STATE_COLORS`: the colours of the trajectory's ``state`` flags (free, stuck,
  slipping toward the pole, slipping toward the equator; :mod:`dynslip.data.trajectory`),
  :data:`STATE_LABELS` their labels, :func:`state_colormap` the colormap of the flags;
- :data:`MODEL_LABELS`: the material models as figures name them (from
  :mod:`dynslip.analysis.paper`).
"""

from __future__ import annotations

from dynslip.analysis.paper import MODEL_LABELS
from dynslip.data.trajectory import STATE_MEANINGS

__all__ = ["STATE_COLORS", "STATE_LABELS", "MODEL_LABELS", "pyplot", "state_colormap"]

STATE_COLORS = ("#d9d9d9", "#1f4e9c", "#e08a1e", "#c0282d")
"""Colours of the state flags free, stuck, slipping toward the pole, toward the equator."""
STATE_LABELS = tuple(m.replace("_", " ") for m in STATE_MEANINGS)
"""Labels of the state flags (their meanings in the contract, in words)."""


def state_colormap():
    """A categorical colormap and norm for the ``state`` flags 0-3."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    return ListedColormap(STATE_COLORS), BoundaryNorm([-0.5, 0.5, 1.5, 2.5, 3.5], 4)


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (figures are files), imported when a figure is
    drawn: ``import dynslip`` imports no plotting library."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
