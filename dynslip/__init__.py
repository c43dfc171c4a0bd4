"""dynslip: stick-slip forming of an elastic sheet over a rigid ball.

The paper's static contact-region model (:mod:`dynslip.physics.sphere`,
:mod:`dynslip.physics.cylinder`)
and a whole-sheet forming simulator. Importing the package turns on float64 JAX and
its persistent compilation cache (:mod:`dynslip._jaxconfig`).

The Python API (:mod:`dynslip.api`, docs/python-api.md): :func:`load`, :func:`run`,
:func:`sweep`, :func:`window`, the figures in :mod:`dynslip.plot`, and the errors
:class:`InputError` and :class:`ComputationError`.
"""

from dynslip import (
           _jaxconfig,  # noqa: F401  (side effect: x64 + compilation cache)
           plot,
)
from dynslip._version import FORMAT_VERSION, __version__
from dynslip.api import RunResult, load, run, sweep, window
from dynslip.errors import ComputationError, InputError

__all__ = ["load", "run", "sweep", "window", "plot", "RunResult", "InputError", "ComputationError",
           "__version__", "FORMAT_VERSION"]
