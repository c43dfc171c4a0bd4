"""Result folders: which folders a run may replace, staging, and the markers of incomplete
and interrupted runs -- the one set of rules every command follows (files inside are written
by :mod:`dynslip.data.files`, whole or not at all).

Output folders (:func:`check_out`, checked before anything is computed or created): a
run may replace only a folder that is a dynslip result -- one that holds the marker
``.dynslip-result`` written with the results, or an earlier result recognised by its
files (a ``trajectory.nc``, ``result.nc`` or ``sweep.nc`` carrying the provenance
attributes, a ``window.json`` of a window search, the member files of a sweep). An
empty folder may be used; any other folder is refused unless ``--force`` is given; an
existing file is never replaced.

A run writes into a fresh staging folder ``<out>.staging-XXXXXXXX/`` that holds a file
``INCOMPLETE`` until the run succeeds; only then does the staging folder replace
``<out>/`` (the old folder is moved into a uniquely named hidden folder and deleted,
so no file of the user's, such as ``<out>.old``, is touched). A run that fails or is
interrupted (SIGINT, SIGTERM) is kept, readable, as ``<out>.incomplete-<UTC time>/``
with the reason in ``INCOMPLETE``; nothing of an earlier run is deleted.

One run at a time per output folder (:mod:`dynslip.data.lock`: a second one is refused,
exit 2, naming the holder).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import tempfile
import time
from pathlib import Path

from dynslip._version import FORMAT_VERSION, __version__
from dynslip.data.files import write_json, write_text
from dynslip.data.lock import out_lock
from dynslip.data.trajectory import TRAJECTORY_FILE
from dynslip.errors import InputError

INCOMPLETE = "INCOMPLETE"
#: the marker file written with the results into every result folder
RESULT_MARKER = ".dynslip-result"
#: netCDF files of earlier results, recognised by their provenance attributes
RESULT_DATASETS = (TRAJECTORY_FILE, "result.nc", "sweep.nc")


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled like SIGINT (partial results kept and marked; exit 143)."""

    signal_name = "SIGTERM"
    exit_code = 143


def signal_name(exc) -> str:
    """The signal an interruption came from: ``SIGTERM`` for :class:`Terminated`, else
    ``SIGINT``."""
    return getattr(exc, "signal_name", "SIGINT")


@contextlib.contextmanager
def sigterm_raises():
    """While inside: SIGTERM raises :class:`Terminated` (in the main thread only); SIGXFSZ is
    ignored, so a write past a file-size limit raises :class:`WriteFailed`."""

    def handler(signum, frame):
        raise Terminated("SIGTERM")

    try:
        previous = signal.signal(signal.SIGTERM, handler)
        # a file-size limit (RLIMIT_FSIZE) then fails the write with EFBIG (exit 3, earlier
        # results intact) instead of killing the process mid-write
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM held back (delivered on leaving) while folders are renamed."""
    sigs = {signal.SIGINT, signal.SIGTERM}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (AttributeError, OSError, ValueError):  # pragma: no cover - not POSIX
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _utc_stamp() -> str:
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())


def write_result_marker(folder, kind: str) -> Path:
    """Write the marker ``.dynslip-result`` that makes ``folder`` a dynslip result folder."""
    return write_json(Path(folder) / RESULT_MARKER, {
        "dynslip_result": True,
        "kind": kind,
        "dynslip_version": __version__,
        "format_version": FORMAT_VERSION,
        "written_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    })


def _nc_has_provenance(path: Path) -> bool:
    try:
        import netCDF4

        with netCDF4.Dataset(path, "r") as nc:
            names = set(nc.ncattrs())
        return bool(names & {"format_version", "dynslip_version"})
    except Exception:  # noqa: BLE001 - anything unreadable is simply not a dynslip dataset
        return False


def _json_object(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def is_result_folder(path) -> bool:
    """Whether ``path`` is a folder dynslip wrote: it holds the marker, or (an earlier result)
    a netCDF file with the provenance attributes, a window search's ``window.json`` or a
    sweep's member files."""
    p = Path(path)
    if not p.is_dir() or p.is_symlink():
        return False
    marker = _json_object(p / RESULT_MARKER) if (p / RESULT_MARKER).is_file() else None
    if marker is not None and marker.get("dynslip_result") is True:
        return True
    if any((p / n).is_file() and _nc_has_provenance(p / n) for n in RESULT_DATASETS):
        return True
    w = _json_object(p / "window.json") if (p / "window.json").is_file() else None
    if w is not None and {"scenario", "field", "tied"} <= set(w):
        return True
    members = p / "members"
    if members.is_dir():
        for f in members.glob("*.json"):
            rec = _json_object(f) if f.is_file() else None
            if rec is not None and {"fingerprint", "scenario", "status"} <= set(rec):
                return True
    return False


_ALLOWED = "allowed: a new folder, an empty folder or an earlier dynslip result folder"


def check_out(out, *, force: bool = False, in_place: bool = False, what: str = "--out",
              force_hint: bool = True) -> str:
    """Check an output folder before anything is computed or created.

    Returns ``"new"``, ``"empty"``, ``"result"`` or ``"forced"``; raises :class:`InputError`
    (one line naming ``what``, the path and what is allowed) for an existing file, a folder
    that is not a dynslip result (unless ``force``), the current folder or one above it, a
    parent that is a file or not writable. ``in_place``: the results are written into the
    folder (sweep, window) rather than swapped in for it (a run).
    """
    out = Path(out)
    name = f"{what} {str(out)!r}"
    if not force_hint:
        force_word = "or move this folder away"
    else:
        force_word = "or --force to write into it" if in_place else "or --force to replace it"
    try:
        resolved = out.resolve()
        cwd = Path.cwd().resolve()
    except (OSError, RuntimeError) as err:
        raise InputError(f"{name}: cannot be resolved ({err}); {_ALLOWED}") from None
    if resolved == cwd or resolved in cwd.parents or resolved.parent == resolved:
        raise InputError(
            f"{name}: the current folder or one above it; {_ALLOWED} below the current folder")
    # the nearest folder that exists must be a folder we can write to
    anc = out.parent
    while not os.path.lexists(anc) and anc != anc.parent:
        anc = anc.parent
    if os.path.lexists(anc) and not anc.is_dir():
        raise InputError(
            f"{name}: {str(anc)!r} is a file, not a folder; allowed: a path whose parents are "
            f"folders"
        )
    if out.is_symlink():
        if in_place and out.is_dir():
            pass  # written through the link
        else:
            raise InputError(f"{name}: a symbolic link; {_ALLOWED} (a link is never replaced)")
    if os.path.lexists(out) and not out.is_dir():
        raise InputError(
            f"{name}: an existing file; {_ALLOWED} (a file is never replaced, not even with "
            f"--force)"
        )
    exists = out.is_dir()
    # in place: files are written into the folder; swapped: it is renamed (its parent and,
    # when it exists, the folder itself must be writable)
    must_write = [out] if (exists and in_place) else [out.parent, out] if exists else [anc]
    for d in must_write:
        if not os.access(d, os.W_OK | os.X_OK):
            raise InputError(
                f"{name}: folder {str(d)!r} is not writable; allowed: a folder you can write to")
    if not exists:
        return "new"
    try:
        entries = sorted(os.listdir(out))
    except OSError as err:
        raise InputError(f"{name}: cannot be read ({err.strerror}); {_ALLOWED}") from None
    if not entries:
        return "empty"
    if is_result_folder(out):
        return "result"
    if force:
        return "forced"
    shown = ", ".join(repr(e) for e in entries[:3]) + (", ..." if len(entries) > 3 else "")
    raise InputError(
        f"{name}: a folder that is not a dynslip result (it holds {shown}); {_ALLOWED}, "
        f"{force_word}"
    )


def annotate_kept(exc, folder) -> None:
    """Record on an exception the folder where the partial results are kept (first one wins)."""
    if exc is not None and getattr(exc, "dynslip_kept", None) is None:
        with contextlib.suppress(AttributeError, TypeError):
            exc.dynslip_kept = Path(folder)


@contextlib.contextmanager
def kept_on_error(folder):
    """Any exception leaving the block names ``folder`` as the place partial results are kept."""
    try:
        yield
    except BaseException as exc:
        annotate_kept(exc, folder)
        raise


class StagedRun:
    """A run folder written through a fresh ``<out>.staging-XXXXXXXX/`` and swapped in on success.

    ``<out>`` is checked (:func:`check_out`) on entering, before anything is created. On
    failure or interruption the staging folder is renamed ``<out>.incomplete-<UTC time>/``
    (``kept``), with the reason in ``INCOMPLETE``; the exception names it
    (``dynslip_kept``). A staging folder the run wrote nothing into is removed. ``force``: a folder
    at ``<out>`` that is not a dynslip result may
    be replaced (a file never).
    """

    def __init__(self, out: Path, *, force: bool = False, what: str = "--out", kind: str = "run",
                 force_hint: bool = True):
        self.out = Path(out)
        self.force = force
        self.what = what
        self.kind = kind
        self.force_hint = force_hint
        self.staging: Path | None = None
        self.kept: Path | None = None
        self._lock = contextlib.ExitStack()

    def check(self) -> str:
        return check_out(self.out, force=self.force, what=self.what, force_hint=self.force_hint)

    def __enter__(self) -> Path:

        self.check()
        self._lock.enter_context(out_lock(self.out, self.what))  # one run per --out at a time
        try:
            self.check()  # again, now that no other run can change it
            self.staging = Path(
                tempfile.mkdtemp(prefix=f"{self.out.name}.staging-", dir=self.out.parent)
            )
            os.chmod(self.staging, 0o777 & ~_umask())
            write_text(self.staging / INCOMPLETE, "run in progress\n")
            write_result_marker(self.staging, self.kind)
        except BaseException:
            if self.staging is not None:
                shutil.rmtree(self.staging, ignore_errors=True)
            self._lock.close()
            raise
        return self.staging

    def __exit__(self, exc_type, exc, tb):
        with self._lock:
            return self._exit(exc_type, exc, tb)

    def _exit(self, exc_type, exc, tb):
        if exc_type is None:
            self._swap_in()
            return False
        if issubclass(exc_type, KeyboardInterrupt):
            why = f"interrupted by {signal_name(exc)}"
        else:
            why = f"run did not complete: {exc_type.__name__}: {exc}".replace(str(self.staging), "this folder")  # noqa: E501
        with _signals_held():
            with contextlib.suppress(OSError):
                if set(os.listdir(self.staging)) <= {INCOMPLETE, RESULT_MARKER}:
                    shutil.rmtree(self.staging)  # nothing was computed: nothing to keep
                    return False
            with contextlib.suppress(OSError):
                write_text(
                    self.staging / INCOMPLETE,
                    f"{why}\nfiles here hold what was computed before it stopped\n",
                )
            self.kept = self._keep()
            if exc is not None:
                if self.kept != self.staging:  # messages name the folder where the files now are
                    with contextlib.suppress(AttributeError, TypeError):
                        exc.args = tuple(
                            a.replace(str(self.staging), str(self.kept))
                            if isinstance(a, str)
                            else a
                            for a in exc.args
                        )
                annotate_kept(exc, self.kept)
        return False

    def _keep(self) -> Path:
        """Rename the staging folder ``<out>.incomplete-<UTC time>`` (a fresh name)."""
        assert self.staging is not None  # set by __enter__, which __exit__ follows
        base = f"{self.out.name}.incomplete-{_utc_stamp()}"
        for i in range(1000):
            target = self.out.with_name(base if i == 0 else f"{base}-{i}")
            if os.path.lexists(target):
                continue
            try:
                os.rename(self.staging, target)
                return target
            except OSError:
                break
        return self.staging

    def _swap_in(self) -> None:
        assert self.staging is not None  # set by __enter__, which __exit__ follows
        try:
            self.check()
        except InputError as err:
            raise InputError(f"{err}; it changed during the run: the finished result is kept in "
                             f"{str(self.staging)!r}") from None
        (self.staging / INCOMPLETE).unlink()
        write_result_marker(self.staging, self.kind)
        with _signals_held():
            trash = None
            if os.path.lexists(self.out):
                trash = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.old-", dir=self.out.parent))
                os.rename(self.out, trash / self.out.name)
            try:
                os.rename(self.staging, self.out)
            except OSError:
                if trash is not None:  # put the old result back; the new one stays in staging
                    with contextlib.suppress(OSError):
                        os.rename(trash / self.out.name, self.out)
                        trash.rmdir()
                raise
            if trash is not None:
                shutil.rmtree(trash, ignore_errors=True)


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask
