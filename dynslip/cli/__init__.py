"""The ``dynslip`` command line.

Exit status: 0 success; 2 bad input (one line naming the field, the value and what is
allowed; nothing written); 3 a computation that ran and failed (what was computed is
kept in ``<out>.incomplete-<UTC time>/`` marked ``INCOMPLETE``); 130 interrupted by
SIGINT, 143 terminated by SIGTERM (likewise kept, the marker naming the signal).

``--out`` of ``run``, ``sweep`` and ``window`` may be a new folder, an empty one or an
earlier dynslip result (replaced only once the new run succeeded); a folder that is not
a dynslip result needs ``--force``; an existing file is never replaced.

The package: the commands (:mod:`dynslip.cli.commands`), their parser with every option's help
line and every command's examples (:mod:`dynslip.cli.parser`), and here :func:`main`, which
turns errors into exit statuses.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dynslip.cli import parser as _parser
from dynslip.errors import ComputationError, InputError, MaterialRangeError

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The command line's parser (:func:`dynslip.cli.parser.build_parser`), described by the
    first line of this package's docstring."""
    return _parser.build_parser(__doc__.splitlines()[0].replace("``", ""))


def _kept(err) -> str:
    """Where the partial results of a failed or interrupted run are (from the exception)."""
    from dynslip.data.folders import INCOMPLETE

    kept = getattr(err, "dynslip_kept", None)
    if kept is None:
        return ""
    marked = ", marked INCOMPLETE" if (Path(kept) / INCOMPLETE).is_file() else ""
    return f"{kept}/{marked}"


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    # the platform, XLA's flags, equinox's error mode and the compilation cache: set before
    # any JAX computation (``import dynslip`` sets none of them)
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    from dynslip.data.folders import signal_name, sigterm_raises

    try:
        with sigterm_raises():  # SIGTERM raises like SIGINT: partial results kept and marked
            return args.fn(args)
    except InputError as err:  # one line, whatever text of the user's the message quotes
        text = str(err).replace("\r", "\\r").replace("\n", "\\n")
        print(f"dynslip: error: {text}", file=sys.stderr)
        return 2
    except (ComputationError, MaterialRangeError) as err:
        print(f"dynslip: computation failed: {err}", file=sys.stderr)
        kept = _kept(err)
        if kept:
            print(f"dynslip: what was computed is kept in {kept}", file=sys.stderr)
        return 3
    except KeyboardInterrupt as err:
        name = signal_name(err)
        kept = _kept(err)
        print(
            f"dynslip: interrupted by {name}"
            + (f"; partial results kept in {kept}" if kept else ""),
            file=sys.stderr,
        )
        return getattr(err, "exit_code", 130)
    except Exception as err:  # a bug: the traceback follows, and where the partial results are
        kept = _kept(err)
        if kept:
            print(
                f"dynslip: unexpected error; what was computed is kept in {kept}", file=sys.stderr
            )
        raise
