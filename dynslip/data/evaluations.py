"""The evaluations of a window search, kept as each finishes, so a search that is stopped
(SIGINT, SIGTERM, SIGKILL, a power cut) resumes from them instead of running them again.

``<out>/evaluations.json`` holds a ``key`` (a hash of what decides each evaluation's value:
the resolved scenario, the field searched and the tied fields) and the evaluations in the
order they were made, each ``[mu, trapped or null, error or null]``; it is rewritten whole
(write then rename) after every evaluation. A log with another key is ignored (and replaced).
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

    def load(self) -> tuple[dict[float, bool | None], dict[float, str]]:
        """The evaluations kept by an earlier attempt of the same search: (known, errors)."""
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}, {}
        if not isinstance(data, dict) or data.get("key") != self.key:
            return {}, {}
        known, errors = {}, {}
        for row in data.get("evaluations", []):
            if not (
                isinstance(row, list)
                and len(row) == 3
                and isinstance(row[0], (int, float))
                and row[1] in (True, False, None)
            ):
                continue
            mu = float(row[0])
            known[mu] = row[1]
            if isinstance(row[2], str):
                errors[mu] = row[2]
            self.rows.append([mu, row[1], row[2] if isinstance(row[2], str) else None])
        return known, errors

    def record(self, mu: float, value: bool | None, error: str | None = None) -> None:
        self.rows.append([float(mu), value, error])
        write_json(self.path, {"key": self.key, "evaluations": self.rows})
