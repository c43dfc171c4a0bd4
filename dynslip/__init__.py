"""dynslip: stick-slip forming of an elastic sheet over a rigid ball.

The paper's static contact-region model (:mod:`dynslip.physics.sphere`, :mod:`dynslip.physics.cylinder`)
and a whole-sheet forming simulator. Importing the package turns on float64 JAX and
its persistent compilation cache (:mod:`dynslip._jaxconfig`).
"""

from dynslip import _jaxconfig  # noqa: F401  (side effect: x64 + compilation cache)

__version__ = "0.1.0"
FORMAT_VERSION = "1"
