"""Why a run stops as failed, in physics terms, with the quantities: the failures the driver
(:mod:`dynslip.physics.driver.simulate`) reports; the schema layer maps each kind to the settings a
user can change."""

from __future__ import annotations

__all__ = ["ContactUnresolved", "NonFinite", "RunFailure", "SolverFailure", "StepLimit"]


class SolverFailure(RuntimeError):
    """The solver did not reach the end of a segment (step limit, NaN, material range)."""


class RunFailure(SolverFailure):
    """Why a run stopped as failed, in physics terms, with the quantities (``Result.failure``;
    ``Result.failed`` is its message). The schema layer maps each kind to the settings a user
    can change (numerics.max_steps, numerics.nodes, ...): no setting names here."""

    def __init__(self, stage: str, t: float, what: str):
        self.stage, self.t, self.what = stage, t, what
        super().__init__(f"stage '{stage}' at t = {t:.6g} s: {what}")


class StepLimit(RunFailure):
    """A save segment from ``t`` to ``t1`` needed more than ``max_steps`` steps."""

    def __init__(self, stage: str, t: float, t1: float, max_steps: int):
        self.t1, self.max_steps = t1, max_steps
        super().__init__(
            stage,
            t,
            f"the solver did not reach t = {t1:.6g} s: step limit reached "
            f"({max_steps} steps per save segment)",
        )


class NonFinite(RunFailure):
    """A state or energy went non-finite (a stretch outside the material's range, or divergence)."""


class ContactUnresolved(RunFailure):
    """The mesh no longer resolves the contact: an element chord ``depth`` (R) inside the ball,
    or inside the held body named ``body`` (None: the ball), beyond ``limit`` (R), on the element
    of material radii ``element`` (R), or the pole passed through the ball (``pole_crossed``,
    depth 1; the ball's check only)."""

    def __init__(
        self, stage: str, t: float, depth: float, limit: float, element: tuple, pole_crossed: bool,
        body: str | None = None,
    ):
        self.depth, self.limit, self.element, self.pole_crossed, self.body = (
            depth,
            limit,
            element,
            pole_crossed,
            body,
        )
        inside = "the ball" if body is None else f"the held body {body!r}"
        why = (
            "the pole passed through the ball"
            if pole_crossed
            else f"the chord of the element on rbar [{element[0]:.4g}, {element[1]:.4g}] R "
            f"lies {depth:.3g} R "
            f"inside {inside} (limit {limit:g} R)"
        )
        super().__init__(
            stage,
            t,
            f"contact not resolved by the mesh: {why}; a finer mesh near the contact, or "
            "a larger chord-depth limit, is needed",
        )
