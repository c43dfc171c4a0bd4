"""Work done in a thread beside the compute (:class:`Beside`): XLA's executions and compiles
release the GIL and, on this machine's two cores, leave one free. Used while the segment step
compiles (the warm-ups, :func:`dynslip.physics.simulate.compile_step`), while each save
segment computes (the held bodies' mesh check, :mod:`dynslip.physics.meshcheck`) and while a
run writes its partial trajectory (:func:`dynslip.app.forming.run_forming`)."""

from __future__ import annotations

import threading

__all__ = ["Beside"]


class Beside:
    """``fn(*args)`` run in a thread of its own from construction; :meth:`result` waits for it
    and returns its value or raises its exception. A thread per call, not a pool: nothing is
    left behind for a forked child (the fault tests fork) or at the interpreter's exit."""

    def __init__(self, fn, *args, name: str = "dynslip-beside"):
        self._value = self._error = None
        self._thread = threading.Thread(target=self._run, args=(fn, args), name=name,
                                        daemon=True)
        self._thread.start()

    def _run(self, fn, args):
        try:
            self._value = fn(*args)
        except BaseException as e:  # noqa: BLE001 - handed to the caller by result()
            self._error = e

    def result(self):
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value
