"""Work done in a thread beside the compute (:class:`Beside`): XLA's executions and compiles
release the GIL and, on this machine's two cores, leave one free. Used while the segment step
compiles (the warm-ups, :func:`dynslip.physics.simulate.compile_step`), while each save
segment computes (the held bodies' mesh check, :mod:`dynslip.physics.meshcheck`) and while a
run writes its partial trajectory (:func:`dynslip.app.forming.run_forming`).

One worker thread for the process, started on first use: starting a thread per call cost
2 ms each beside a running segment (0.18 s of the main job's 84 frames), a hand-over to a
waiting worker about 0.05 ms. The worker takes the calls in order; nothing it runs waits on
another call beside. A forked child (the fault tests fork) starts its own worker."""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

__all__ = ["Beside"]

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dynslip-beside")
        return _POOL


def _forget_pool() -> None:  # the parent's worker thread is not in a forked child
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


class Beside:
    """``fn(*args)`` handed to the worker thread now; :meth:`result` waits for it and returns
    its value or raises its exception."""

    def __init__(self, fn, *args):
        self._future = _pool().submit(fn, *args)

    def result(self):
        return self._future.result()
