"""A lock on an output folder, so two runs never write one ``--out`` at once.

The lock is ``fcntl.flock`` on a file beside the folder, ``<parent>/.<name>.lock`` (beside,
not inside: a run's folder is swapped in by renaming it). The operating system releases
the lock when its holder exits, however it exits (SIGKILL included), so a stale lock file
never blocks the next run: only a live holder does. The file records the holder (pid,
host, start time) for the one-line refusal (exit 2) of a second run.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import time
from pathlib import Path

from dynslip.errors import InputError


def lock_path(out) -> Path:
    out = Path(out)
    return out.parent / f".{out.name}.lock"


@contextlib.contextmanager
def out_lock(out, what: str = "--out"):
    """Hold the lock of the output folder ``out`` while inside; raise :class:`InputError` (one
    line naming the holder) when another live process holds it."""
    path = lock_path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 512, 0).decode("utf-8", "replace").strip() or "unknown process"
            raise InputError(f"{what} {str(out)!r}: in use by another dynslip run ({holder}); "
                             "allowed: one run per output folder at a time") from None
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        text = f"pid {os.getpid()} on host {socket.gethostname()}, started {stamp}\n".encode()
        os.ftruncate(fd, 0)
        os.pwrite(fd, text, 0)
        try:
            yield path
        finally:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
