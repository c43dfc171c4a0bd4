r"""The segment solvers, as objects built from the driver's :class:`Settings` (the schema's
``numerics``): load stepping by Newton on the motion alone
(:class:`dynslip.physics.solver.newton.MotionNewton`, the default) and stiff diffrax solvers
(:class:`TimeStepping`: Kvaerno5, the reference, and others). A solver object given as
``Settings.solver`` is used as it is (the full-state Newton baseline,
:class:`dynslip.physics.solver.loadstep.FullStateLoadStep`, in the tests). Every object has
``segment(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate) -> SegmentOutput``;
:mod:`dynslip.physics.driver.simulate` drives them.

diffrax (and :mod:`~dynslip.physics.solver.upstream`, built on it) is imported where a solver that
uses it is built or run: 0.2 s of every run's start that load stepping, the default, does not
need.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from dynslip.physics.field import Layout, heal, vector_field
from dynslip.physics.solver.linalg import BorderedBlockTridiagonal, sheet_structure
from dynslip.physics.solver.newton import MotionNewton, SegmentOutput, zero_rate
from dynslip.physics.solver.upstream import VeryChord

__all__ = ["DIFFRAX_METHODS", "SOLVERS", "Settings", "TimeStepping", "solver_for"]


@dataclasses.dataclass(frozen=True)
class Settings:
    """Numerics of the driver (nondimensional except times in s)."""

    solver: str = "kvaerno5"
    rtol: float = 1e-5
    atol: float = 1e-7
    pcoeff: float = 0.3
    icoeff: float = 0.3
    max_steps: int = 20000  # per segment
    save_interval: float = 1.0  # s
    contact_threshold: float = 1e-2  # G h0 / R
    heal_rate: float = (
        0.0  # R/s: a node heals (slip distance reset) where its slip rate is at most this
    )
    linear_solver: str = "structured"  # "structured" (block tridiagonal + border) or "dense" (LU)
    # solver "load_step" (dynslip.physics.solver.newton): Newton iteration limit per increment, and
    # the
    # increment bound in drag times, driven stages / stages with the ball or clamp under a force
    newton_max_iter: int = 20
    newton_backtrack: int = (
        4  # halvings of a Newton correction that would raise the residual (0: plain Newton)
    )
    # the complementarity parameter c (G h0) of the ball's friction law in its weighted form, in
    # which Newton iterates (dynslip.physics.solver.increment.weighted_slip: the law's roots for
    # every
    # c; a node's weight max(1, c dt / (eta A)); 0: the law's own form)
    newton_weight: float = 1e3
    max_increment: float = 20.0
    max_increment_free: float = 5.0
    # a run stops as failed when an element chord dips deeper than this into the ball or a held
    # body, or the pole passes through the ball (the mesh no longer resolves the contact);
    # None: never checked
    max_chord_depth: float | None = None
    # the held bodies' names (in held order), for the failure's message; () : "held body k"
    body_names: tuple = ()


class TimeStepping(eqx.Module):
    """A stiff diffrax solver (``method``: :class:`diffrax.Kvaerno5`, the reference, or another
    implicit one) with a PID controller over a save segment; at the segment's end the friction
    law's reset (healing, :func:`dynslip.physics.field.heal`, ``heal_rate``): a reset inside
    the steps would be a discontinuity in an adaptive error-controlled step."""

    method: type = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    linear_solver: str = eqx.field(static=True, default="structured")
    pcoeff: float = eqx.field(static=True, default=0.3)
    icoeff: float = eqx.field(static=True, default=0.3)
    heal_rate: float = eqx.field(static=True, default=0.0)

    @classmethod
    def from_settings(cls, s: Settings) -> TimeStepping:
        """The diffrax solver of ``s.solver`` (:data:`DIFFRAX_METHODS`) with the step limit,
        linear solver, PID coefficients and healing rate of ``s``."""
        import diffrax

        return cls(
            method=getattr(diffrax, DIFFRAX_METHODS[s.solver]),
            max_steps=s.max_steps,
            linear_solver=s.linear_solver,
            pcoeff=s.pcoeff,
            icoeff=s.icoeff,
            heal_rate=s.heal_rate,
        )

    def _diffrax_solver(self, layout: Layout):
        import diffrax


        # VeryChord with the termination fix of diffrax PR #754 (dynslip.physics.solver.upstream),
        # on
        # both paths: the dense path otherwise builds diffrax's own VeryChord.
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

#: The segment solver classes by the schema's ``numerics.solver`` name: each builds its solver
#: object from the :class:`Settings` (``from_settings``). Every object has ``segment(model,
#: layout, y0, t0, t1, dt0, args, rtol, atol, rate) -> SegmentOutput``.
SOLVERS: dict[str, type[MotionNewton] | type[TimeStepping]] = {
    "load_step": MotionNewton,
    **{name: TimeStepping for name in DIFFRAX_METHODS},
}


def solver_for(settings: Settings):
    """The segment solver object of ``settings.solver``: the object itself, or the one
    class :data:`SOLVERS` names builds from ``settings`` (``load_step``, the default,
    :class:`dynslip.physics.solver.newton.MotionNewton`; a diffrax solver,
    :class:`TimeStepping`)."""
    if not isinstance(settings.solver, str):
        return settings.solver
    try:
        cls = SOLVERS[settings.solver]
    except KeyError:
        raise ValueError(
            f"Settings.solver = {settings.solver!r}: allowed: {', '.join(SOLVERS)} or a solver "
            "object"
        ) from None
    return cls.from_settings(settings)


def counts_newton(solver) -> bool:
    """Whether the solver's ``newton_iterations`` count anything (load stepping)."""
    return not isinstance(solver, TimeStepping)
