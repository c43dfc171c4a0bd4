"""The evaluations of a window search, kept as each finishes, so a search that is stopped
(SIGINT, SIGTERM, SIGKILL, a power cut) resumes from them instead of running them again.

``<out>/evaluations.json`` holds a ``key`` (a hash of what decides each evaluation's value:
the resolved scenario, the field searched and the tied fields) and the evaluations in the
order they were made, each ``[mu, trapped or null, error or null, deepest chord or null]``
(the mesh check's depth, so a resumed search reports the resolution of every member); it is
rewritten whole (write then rename) after every evaluation. A log with another key is
ignored (and replaced).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from dynslip.data.files import write_json

FILE = "evaluations.json"


def search_key(*parts) -> str:
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class EvaluationLog:
    """The evaluations of one window search in ``folder``, under ``key``."""

    def __init__(self, folder, key: str):
        self.path = Path(folder) / FILE
        self.key = key
        self.rows: list[list] = []

    def load(self) -> tuple[dict[float, bool | None], dict[float, str], dict[float, float]]:
        """The evaluations kept by an earlier attempt of the same search:
        (known, errors, depths)."""
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}, {}, {}
        if not isinstance(data, dict) or data.get("key") != self.key:
            return {}, {}, {}
        known, errors, depths = {}, {}, {}
        for row in data.get("evaluations", []):
            if not (
                isinstance(row, list)
                and len(row) == 4
                and isinstance(row[0], (int, float))
                and row[1] in (True, False, None)
            ):
                continue
            mu = float(row[0])
            known[mu] = row[1]
            error = row[2] if isinstance(row[2], str) else None
            depth = float(row[3]) if isinstance(row[3], (int, float)) else None
            if error is not None:
                errors[mu] = error
            if depth is not None:
                depths[mu] = depth
            self.rows.append([mu, row[1], error, depth])
        return known, errors, depths

    def record(
        self, mu: float, value: bool | None, error: str | None = None, depth: float | None = None
    ) -> None:
        self.rows.append([float(mu), value, error, depth])
        write_json(self.path, {"key": self.key, "evaluations": self.rows})
