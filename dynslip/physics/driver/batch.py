r"""Members of a study run in lockstep: one ``jax.vmap``-ed segment step per save segment.

Members that differ only in floats (friction coefficients, speeds, pre-stretch, stage
durations, tolerances...) have identical array shapes: every leaf of
:class:`dynslip.physics.field.StageArgs` and of the model's and friction law's parameters
is an array. :func:`simulate_batch` runs B such members together through the one host
driver, :func:`dynslip.physics.driver.simulate.drive`, with the segment step vmapped
(:func:`dynslip.physics.driver.simulate.segment_step`). Each member keeps its own host state
(:class:`dynslip.physics.driver.member.MemberRun`: its stage, time, stop rule, frames); every
tick advances every member by one save segment, with one call of the step over the stacked
member states and stacked stage loads, so members may be in different stages and at
different times. A member that has finished (its last stage done, or failed) asks for a
zero-length segment: inside the vmapped ``while_loop`` its condition is false from the
start and its state is carried unchanged. Each member's frame (computed in the same call)
is then recorded and its own stop rule checked on it (:meth:`MemberRun.record`).

Cost. Under ``vmap`` a ``lax.while_loop`` runs while *any* member's condition holds, so
every tick costs the batch's largest number of load increments (and, inside each,
Newton iterations) in that segment, for all B members at once; members that are done
are masked, not skipped. What is gained is the per-call and per-operation overhead of
small (tens of nodes) problems, shared by B members. ``docs/sweeps.md`` has the
measurement.

Compiled once per (static key of the members, B): the key of
:func:`dynslip.physics.driver.member.static_key` (the solver object, the layout, the non-array
parts of model and loads), which must be equal for every member.
"""

from __future__ import annotations

from collections.abc import Sequence

from dynslip.physics.driver.member import MemberRun, Result
from dynslip.physics.driver.simulate import drive
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel

__all__ = ["simulate_batch", "batch_key"]


def batch_key(model: SheetModel, protocol: Protocol, kwargs: dict) -> tuple:
    """Members with equal keys can run in one batch: the compiled step's static key
    (:func:`dynslip.physics.driver.member.static_key`: the solver object, the layout, the structure,
    non-array leaves and array shapes of model and first stage's loads), a hashable value."""
    run = MemberRun(model, protocol, **{k: v for k, v in kwargs.items() if k != "on_frame"})
    return run.key


def simulate_batch(
    models: Sequence[SheetModel], protocols: Sequence[Protocol], kwargs: Sequence[dict]
) -> list[Result]:
    """Run B members in lockstep; ``kwargs[b]`` are member b's keyword arguments of
    :func:`dynslip.physics.driver.simulate.simulate` (``friction``, ``eps``, ``drag``, ``settings``,
    ``start``, ``on_frame``, ...). Returns one :class:`Result` per member, the same content as
    ``simulate`` returns for it alone (to rounding: the batched linear algebra may order
    sums differently). Raises ``ValueError`` when the members cannot share one compiled
    step (see :func:`batch_key`); B = 1 is :func:`simulate` itself.
    """
    if not (len(models) == len(protocols) == len(kwargs)) or not models:
        raise ValueError(
            "simulate_batch: give as many models, protocols and keyword sets, at least one"
        )
    runs = [MemberRun(m, p, **kw) for m, p, kw in zip(models, protocols, kwargs, strict=True)]
    return drive(runs)
