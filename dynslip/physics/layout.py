"""The slices of the whole sheet's flat state vector (:class:`Layout`), and the energy
accumulators' counts; :mod:`dynslip.physics.field` (the vector field) re-exports them."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

__all__ = ["N_ACC", "N_ACC_MOVED", "Layout", "f64", "traced"]


def f64(x):
    """A float64 JAX array (the package computes in double precision)."""
    return jnp.asarray(x, dtype=jnp.float64)


def traced(tree):
    """``tree`` with every Python ``float`` leaf a 0-d float64 array (:func:`f64`); ints,
    bools, strings and an equinox module's static fields are kept as they are. A model's
    physical parameters so converted are inputs of a compiled program, not constants compiled
    into it: a new value runs the same program, and a transformation (``jax.jvp``) reaches
    them. Leaves that are arrays already are kept (not copied)."""
    return jax.tree_util.tree_map(lambda x: f64(x) if isinstance(x, float) else x, tree)


N_ACC = 4  # work_clamp, work_ball, dissipation_drag, dissipation_friction
#: with bodies moved by the stages, a fifth: work_bodies, their work on the sheet
N_ACC_MOVED = 5


class Layout(eqx.Module):
    """Slices of the flat state vector for a sheet of ``n`` nodes.

    ``[rho_1 .. rho_{n-1}, z_0 .. z_{n-1}, zb, acc(n_acc), internal(n_int * n)]``: node
    ``n-1`` is the clamped edge (moved by the protocol, or free under a force when the
    clamp lets go); ``internal`` is the friction law's per-node state (the slip distance
    of :class:`dynslip.physics.friction.SlipWeakening`), absent for memoryless laws.
    ``n_acc``: 4 accumulators (:data:`N_ACC`), 5 when bodies are moved by the stages or free
    (their work on the sheet, :data:`N_ACC_MOVED`). ``n_free``: the heights of the held bodies
    free along the axis (R, relative to their reference placements), last. ``n_held_int``:
    the slip distances of the held bodies whose friction law has memory
    (:func:`dynslip.physics.bodies.held.n_memory`, in held order), ``n_held_int * n`` values
    after ``internal`` (body by body), before the free bodies' heights; absent (0) without such
    a body, so the state is then unchanged.
    """

    n: int = eqx.field(static=True)
    n_int: int = eqx.field(static=True, default=0)
    n_acc: int = eqx.field(static=True, default=N_ACC)
    n_free: int = eqx.field(static=True, default=0)
    n_held_int: int = eqx.field(static=True, default=0)

    @property
    def size(self) -> int:
        return ((self.n - 1) + self.n + 1 + self.n_acc + (self.n_int + self.n_held_int) * self.n
                + self.n_free)

    def free(self, y):
        """The free bodies' heights (n_free,), or None without any."""
        if self.n_free == 0:
            return None
        return y[self.size - self.n_free :]

    def with_free(self, y, zk):
        if self.n_free == 0:
            return y
        return y.at[self.size - self.n_free :].set(zk)

    @property
    def accumulators(self) -> slice:
        """Where the energy accumulators sit in the state."""
        return slice(2 * self.n, 2 * self.n + self.n_acc)

    @property
    def internal_start(self) -> int:
        return self.accumulators.stop

    def internal(self, y):
        """The friction law's per-node state, (n,), or None for a memoryless law."""
        if self.n_int == 0:
            return None
        return y[self.internal_start : self.internal_start + self.n]

    def with_internal(self, y, internal):
        if self.n_int == 0:
            return y
        return y.at[self.internal_start : self.internal_start + self.n].set(internal)

    @property
    def held_start(self) -> int:
        """Where the held bodies' slip distances start in the state."""
        return self.internal_start + self.n_int * self.n

    def held_internal(self, y):
        """The held bodies' slip distances, (n_held_int, n), or None without a held law with
        memory."""
        if self.n_held_int == 0:
            return None
        k = self.n_held_int * self.n
        return jnp.reshape(y[self.held_start : self.held_start + k], (self.n_held_int, self.n))

    def with_held_internal(self, y, delta):
        if self.n_held_int == 0:
            return y
        k = self.n_held_int * self.n
        return y.at[self.held_start : self.held_start + k].set(jnp.reshape(delta, (k,)))

    def unpack(self, y):
        n = self.n
        rho = jnp.concatenate([jnp.zeros(1), y[: n - 1]])
        z = y[n - 1 : 2 * n - 1]
        zb = y[2 * n - 1]
        acc = y[self.accumulators]
        return rho, z, zb, acc

    def pack(self, rho, z, zb, acc, internal=None, free=None, held=None):
        parts = [rho[1:], z, jnp.reshape(zb, (1,)), acc]
        if self.n_int:
            parts.append(jnp.zeros(self.n) if internal is None else internal)
        if self.n_held_int:
            k = self.n_held_int * self.n
            parts.append(jnp.zeros(k) if held is None else jnp.reshape(held, (k,)))
        if self.n_free:
            parts.append(jnp.zeros(self.n_free) if free is None else free)
        return jnp.concatenate(parts)
