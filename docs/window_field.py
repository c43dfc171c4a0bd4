"""``dynslip window --nodes`` over a friction field the command line does not search: the
pressure law's ``physics.friction.mu_ref`` (the command searches ``mu`` or ``mu_s``).

    python docs/window_field.py SCENARIO --field physics.friction.mu_ref --nodes 50,100,200 \
        --lo 2.2 --hi 2.6 --coarse 4 --tol 0.01 [--set FIELD=VALUE ...]

The search goes to ``window/`` in the working folder (``window.json`` with the critical value
per N, as ``dynslip window --nodes`` writes it). docs/results.py runs it for the pressure
law's table of docs/experiment.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", type=Path)
    p.add_argument("--field", required=True)
    p.add_argument("--nodes", required=True, help="N1,N2,...")
    p.add_argument("--lo", type=float, required=True)
    p.add_argument("--hi", type=float, required=True)
    p.add_argument("--coarse", type=int, default=4)
    p.add_argument("--tol", type=float, default=0.01)
    p.add_argument("--set", action="append", default=[], dest="sets")
    a = p.parse_args(argv)
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    from dynslip.app.window import run_window_nodes

    root = Path(__file__).resolve().parents[1]
    scenario = a.scenario if a.scenario.is_absolute() else root / a.scenario
    from dynslip.errors import ComputationError

    nodes = [int(n) for n in a.nodes.split(",")]
    try:
        run_window_nodes(scenario, nodes, a.sets, out=Path.cwd() / "window", force=True,
                         field=a.field, lo=a.lo, hi=a.hi, coarse=a.coarse, tol=a.tol)
    except ComputationError as err:  # every member failed: no critical value, exit 3 as dynslip
        (Path.cwd() / "window" / "window.json").write_text(json.dumps(
            {"nodes": nodes, "critical_mu": {str(n): None for n in nodes}, "failed": str(err)}))
        print(f"window_field: {err}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
