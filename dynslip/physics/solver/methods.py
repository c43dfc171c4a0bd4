r"""The driver's numerics (:class:`Settings`) and the stiff diffrax segment solver
(:class:`TimeStepping`: Kvaerno5, the reference, and others). ``Settings.solver`` is a solver
object: load stepping by Newton on the motion alone
(:class:`dynslip.physics.solver.newton.MotionNewton`, the scenarios' default), a
:class:`TimeStepping`, or the full-state Newton baseline of the tests
(:class:`dynslip.physics.solver.loadstep.FullStateLoadStep`). The schema's ``numerics`` builds
it; the physics never chooses a solver by name. Every solver object is a
:class:`~dynslip.physics.solver.newton.AbstractSegmentSolver` (``segment(model, layout, y0,
t0, t1, dt0, args, rtol, atol, rate) -> SegmentOutput``, ``max_steps``, ``name``,
``counts_newton``); :mod:`dynslip.physics.driver.simulate` drives them.

diffrax (and :mod:`~dynslip.physics.solver.upstream`, built on it) is imported where a solver that
uses it is run: 0.2 s of every run's start that load stepping, the default, does not
need.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from dynslip.physics.field import Layout, heal, vector_field
from dynslip.physics.solver.linalg import BorderedBlockTridiagonal, sheet_structure
from dynslip.physics.solver.newton import AbstractSegmentSolver, SegmentOutput, zero_rate
from dynslip.physics.solver.upstream import VeryChord

__all__ = ["DIFFRAX_METHODS", "Settings", "TimeStepping"]


class TimeStepping(AbstractSegmentSolver):
    """A stiff diffrax solver (``scheme``: a name of :data:`DIFFRAX_METHODS`; ``kvaerno5``,
    :class:`diffrax.Kvaerno5`, the reference) with a PID controller over a save segment, at
    most ``max_steps`` steps; at the segment's end the friction law's reset (healing,
    :func:`dynslip.physics.field.heal`, ``heal_rate``): a reset inside the steps would be a
    discontinuity in an adaptive error-controlled step."""

    scheme: str = eqx.field(static=True, default="kvaerno5")
    max_steps: int = eqx.field(static=True, default=20000)
    linear_solver: str = eqx.field(static=True, default="structured")
    pcoeff: float = eqx.field(static=True, default=0.3)
    icoeff: float = eqx.field(static=True, default=0.3)
    heal_rate: float = eqx.field(static=True, default=0.0)

    counts_newton: ClassVar[bool] = False

    def __check_init__(self):
        if self.scheme not in DIFFRAX_METHODS:
            raise ValueError(
                f"TimeStepping.scheme = {self.scheme!r}: allowed: {', '.join(DIFFRAX_METHODS)}"
            )

    @property
    def name(self) -> str:
        """The run's ``method`` in its statistics: the scheme."""
        return self.scheme

    @property
    def method(self) -> type:
        """The diffrax solver class of ``scheme``, imported when a run needs it."""
        import diffrax

        return getattr(diffrax, DIFFRAX_METHODS[self.scheme])

    def _diffrax_solver(self, layout: Layout):
        import diffrax

        # VeryChord with the termination fix of diffrax PR #754
        # (dynslip.physics.solver.upstream), on both paths: the dense path otherwise builds
        # diffrax's own VeryChord.
        chord = diffrax.with_stepsize_controller_tols(VeryChord)
        if self.linear_solver == "dense":
            return self.method(root_finder=chord())
        lin = BorderedBlockTridiagonal(sheet_structure(layout))
        return self.method(root_finder=chord(linear_solver=lin))

    def segment(self, model, layout, y0, t0, t1, dt0, args, rtol, atol, rate=None) -> SegmentOutput:
        import diffrax

        term = diffrax.ODETerm(vector_field(model, layout))
        ctrl = diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=self.pcoeff, icoeff=self.icoeff)
        sol = diffrax.diffeqsolve(
            term,
            self._diffrax_solver(layout),
            t0,
            t1,
            dt0,
            y0,
            args=args,
            stepsize_controller=ctrl,
            max_steps=self.max_steps,
            throw=False,
            saveat=diffrax.SaveAt(t1=True),
        )
        y1 = sol.ys[-1]
        ok = (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(y1))
        # a zero-length segment (a run's first frame, a finished batch member) is not healed
        y1 = jnp.where(t1 > t0, heal(model, layout, y1, args, self.heal_rate, t1), y1)
        st = sol.stats
        return SegmentOutput(
            y=y1,
            ok=ok,
            steps=st["num_steps"],
            accepted=st["num_accepted_steps"],
            rejected=st["num_rejected_steps"],
            newton_iterations=jnp.zeros((), jnp.int32),
            rate=zero_rate(layout.n),
        )


#: The diffrax solver class of each of the schema's ``numerics.solver`` names that
#: :class:`TimeStepping` runs.
DIFFRAX_METHODS = {
    "kvaerno5": "Kvaerno5",
    "kvaerno4": "Kvaerno4",
    "kvaerno3": "Kvaerno3",
    "implicit_euler": "ImplicitEuler",
}


@dataclasses.dataclass(frozen=True)
class Settings:
    """Numerics of the driver (nondimensional except times in s): the segment solver (an
    :class:`~dynslip.physics.solver.newton.AbstractSegmentSolver`), its tolerances, the save
    interval and the checks on each saved frame. The schema's ``numerics`` builds the solver
    (:meth:`dynslip.schema.forming.FormingNumerics.build_solver`)."""

    solver: AbstractSegmentSolver = dataclasses.field(default_factory=TimeStepping)
    rtol: float = 1e-5
    atol: float = 1e-7
    save_interval: float = 1.0  # s
    contact_threshold: float = 1e-2  # G h0 / R
    # a run stops as failed when an element chord dips deeper than this into the ball or a held
    # body, or the pole passes through the ball (the mesh no longer resolves the contact);
    # None: never checked
    max_chord_depth: float | None = None
    # the held bodies' names (in held order), for the failure's message; () : "held body k"
    body_names: tuple = ()
