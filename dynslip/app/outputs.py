"""Where a runner's results go: :class:`Outputs` of a folder writes them as the command line
has them (``trajectory.nc`` or ``result.nc``, ``summary.json``, the figures); ``Outputs(None)``
keeps the datasets and the summary in memory and writes nothing (:func:`dynslip.run` without
``out``), so that a run in memory makes no file round trip."""

from __future__ import annotations

import json
from pathlib import Path

from dynslip.data import files as io
from dynslip.data.trajectory import TRAJECTORY_FILE

__all__ = ["Outputs", "IN_MEMORY"]

#: what a message names instead of a file when the results are kept in memory
IN_MEMORY = "<in memory: err.partial>"


class Outputs:
    """The datasets (by file name) and the summary of one run, written into ``folder`` as they
    come, or only kept (``folder=None``). The summary is kept as ``summary.json`` reads back
    (NaN and inf as None)."""

    def __init__(self, folder=None):
        self.folder = None if folder is None else Path(folder)
        self.datasets: dict = {}
        self.summary: dict | None = None

    @classmethod
    def of(cls, out) -> Outputs:
        """``out`` as outputs: an :class:`Outputs` as it is, a folder path written into."""
        return out if isinstance(out, Outputs) else cls(out)

    @property
    def writes(self) -> bool:
        """Whether files (and figures) are written."""
        return self.folder is not None

    def where(self, name: str) -> str:
        """Where ``name`` is kept, for a message."""
        return str(self.folder / name) if self.writes else IN_MEMORY

    def netcdf(self, ds, name: str) -> None:
        self.datasets[name] = ds
        if self.writes:
            io.write_netcdf(ds, self.folder / name)

    def json(self, data: dict, name: str = "summary.json") -> None:
        self.summary = json.loads(json.dumps(io.jsonable(data)))
        if self.writes:
            io.write_json(self.folder / name, data)

    def dataset(self):
        """The run's dataset: ``trajectory.nc`` of a forming run, else ``result.nc`` (None if
        the run made none)."""
        return self.datasets.get(TRAJECTORY_FILE, self.datasets.get("result.nc"))
