"""dynslip: stick-slip forming of an elastic sheet over a rigid ball.

The paper's static contact-region model (:mod:`dynslip.physics.static`: the ball, and the
2D argument in :mod:`dynslip.physics.static.plane_strain`) and a whole-sheet forming simulator.

Importing the package changes one global setting, and only one: ``jax_enable_x64`` is turned
on, because the package's numerics are float64: its tolerances (Newton's down to 1e-12, the
energy balance's) and its stored results assume it, and a process whose other code runs in
float32 would give dynslip arrays of the wrong precision. The import chooses
no device, edits no environment variable, creates no folder and imports no plotting library.
What a run of the command line needs besides (the CPU platform unless ``JAX_PLATFORMS`` says
otherwise, XLA's flags, equinox's error mode, the persistent compilation cache) is set by
:func:`dynslip._jaxconfig.configure_runtime`, which :func:`dynslip.cli.main` calls before any
JAX computation; a script or notebook may call it too.

The Python API (:mod:`dynslip.api`, docs/python-api.md): :func:`load`, :func:`run`,
:func:`sweep`, :func:`window`, :func:`sensitivities` (docs/sensitivities.md), the figures in
:mod:`dynslip.plot`, and the errors :class:`InputError` and :class:`ComputationError`.
"""

from dynslip import (
           _jaxconfig,  # noqa: F401  (jax_enable_x64, the one setting made at import)
           plot,
)
from dynslip._version import FORMAT_VERSION, __version__
from dynslip.api import RunResult, load, run, sensitivities, sweep, window
from dynslip.errors import ComputationError, InputError

__all__ = ["load", "run", "sensitivities", "sweep", "window", "plot", "RunResult", "InputError",
           "ComputationError", "__version__", "FORMAT_VERSION"]
