"""The memory a forming run would hold, estimated before it starts, and the machine's bound.

Every saved frame is held in memory until the trajectory is written (the driver's records
and the dataset built from them), so the estimate is

    2 x nodes x frames x fields x 8 bytes  +  32 x (3 nodes)^2 bytes

with ``fields`` the per-node variables of the trajectory contract (and ``state``), ``frames``
the loading path at its longest over ``numerics.save_interval_s``, and the second term the
solver's working set (a dense Jacobian of the 3 unknowns per node, its factors and copies:
a bound, the structured solver needs less). A run over the machine's physical memory is
refused (exit 2) before anything is computed or written.
"""

from __future__ import annotations

import os

from dynslip.data.trajectory import PER_NODE
from dynslip.errors import InputError

#: bytes held per node, frame and field (the records and the dataset: two copies of float64)
BYTES_PER_VALUE = 2 * 8
#: the solver's working set, bytes per (3 nodes)^2
SOLVER_BYTES = 32


def n_fields() -> int:

    return len(PER_NODE) + 1  # and state


def machine_memory() -> int:
    """The machine's physical memory in bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def estimate(nodes: int, frames: float) -> float:
    return BYTES_PER_VALUE * nodes * frames * n_fields() + SOLVER_BYTES * (3 * nodes) ** 2


def describe() -> str:
    """The bound in words, for ``dynslip schema``."""
    return (
        f"memory of a forming run: ~ 2 x nodes x frames x {n_fields()} fields x 8 bytes + "
        f"{SOLVER_BYTES} x (3 nodes)^2 bytes (frames: the loading path at its longest / "
        f"numerics.save_interval_s); refused (exit 2) above this machine's {machine_memory() / 2**30:.1f} GiB"  # noqa: E501
    )


def check_forming(world) -> None:
    """Raise :class:`InputError` when the forming run of ``world``
    (:class:`~dynslip.schema.world.World`) would hold more than the machine."""
    nodes = int(world.limits.nodes)
    every = world.settings.save_interval
    frames = sum(s.max_duration for s in world.protocol.stages) / every + 1
    need = estimate(nodes, frames)
    have = machine_memory()
    if need > have:
        raise InputError(
            f"numerics.nodes = {nodes}, numerics.save_interval_s = {every:g}: the run would "
            f"hold ~{need / 2**30:.3g} GiB ({nodes} nodes x {frames:.3g} frames x {n_fields()} "
            f"fields x 16 bytes + solver), this machine has {have / 2**30:.3g} GiB; allowed: "
            f"fewer nodes or a larger save_interval_s"
        )
