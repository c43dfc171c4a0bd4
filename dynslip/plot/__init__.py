"""Figures from datasets (matplotlib only): each reads a dataset, so anything shown can be
redrawn from a saved file. The entry points below return a :class:`matplotlib.figure.Figure`
and import matplotlib only when called (``import dynslip`` stays light and never picks a
backend).

- :func:`meridian`, :func:`theta_rbar`, :func:`state_map`: a forming trajectory
  (:mod:`dynslip.plot.forming`);
- :func:`release_force`: the release test's force against the ball's displacement
  (:mod:`dynslip.plot.release`).
"""

from importlib import import_module

_EXPORTS = {
    "meridian": "dynslip.plot.forming",
    "theta_rbar": "dynslip.plot.forming",
    "state_map": "dynslip.plot.forming",
    "release_force": "dynslip.plot.release",
}
__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'dynslip.plot' has no attribute {name!r}")
