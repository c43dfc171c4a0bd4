"""A lock on an output folder, so two runs never write one ``--out`` at once.

The lock is ``fcntl.flock`` on a file beside the folder, ``<parent>/.<name>.lock`` (beside,
not inside: a run's folder is swapped in by renaming it). The operating system releases
the lock when its holder exits, however it exits (SIGKILL included), so a stale lock file
never blocks the next run: only a live holder does. The file records the holder (pid,
host, start time) for the one-line refusal (exit 2) of a second run. The holder removes the
file when it is done (a killed holder leaves it, to be reused and removed by the next run).
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
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 512, 0).decode("utf-8", "replace").strip() or "unknown process"
            os.close(fd)
            raise InputError(
                f"{what} {str(out)!r}: in use by another dynslip run ({holder}); "
                "allowed: one run per output folder at a time"
            ) from None
        try:  # the file may have been removed by a holder releasing it: lock the one at the path
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        text = f"pid {os.getpid()} on host {socket.gethostname()}, started {stamp}\n".encode()
        os.ftruncate(fd, 0)
        os.pwrite(fd, text, 0)
        yield path
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)  # removed while still held: a waiting run then locks a fresh file
        os.close(fd)
