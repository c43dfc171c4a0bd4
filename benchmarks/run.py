"""The one benchmark entry point: ``python benchmarks/run.py [PART ...]``.

Each part is a module ``benchmarks/<part>.py`` exposing ``run() -> dict``; speeds are
reported as ratios against baselines run in the same process (see each part). Results
go to ``outputs/benchmarks/<part>.json`` and a table on the terminal. Parts: static
(the paper's model), forming (the whole-sheet simulator), sweep (study throughput).
"""

from __future__ import annotations

import importlib.util
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PARTS = ["static", "forming", "speed", "driver", "sweep", "newton_parts", "bodies", "corners"]


def _load(part: str):
    path = HERE / f"{part}.py"
    if not path.exists():
        return None
    spec = importlib.util.spec_from_file_location(f"dynslip_bench_{part}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _flatten(d: dict, prefix: str = "") -> list[tuple[str, object]]:
    rows = []
    for k, v in d.items():
        if isinstance(v, dict):
            rows += _flatten(v, f"{prefix}{k}.")
        else:
            rows.append((prefix + k, v))
    return rows


def main(argv: list[str]) -> int:
    from rich.console import Console
    from rich.table import Table

    import dynslip  # noqa: F401  (x64, compilation cache)
    from dynslip.data.files import write_json

    console = Console()
    parts = argv or PARTS
    out_dir = Path("outputs") / "benchmarks"
    for part in parts:
        mod = _load(part)
        if mod is None:
            console.print(f"[yellow]benchmark part {part!r} not available[/yellow]")
            continue
        t0 = time.perf_counter()
        result = mod.run()
        result["wall_s"] = time.perf_counter() - t0
        write_json(out_dir / f"{part}.json", result)
        table = Table(title=f"benchmark: {part}")
        table.add_column("quantity")
        table.add_column("value", justify="right")
        for k, v in _flatten(result):
            table.add_row(k, f"{v:.4g}" if isinstance(v, float) else json.dumps(v))
        console.print(table)
    return 0


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    sys.exit(main(sys.argv[1:]))
