"""``dynslip export TRAJECTORY``: a trajectory as files ParaView opens as a time series.

``--format vtu`` (default): ``sheet_NNNN.vtu`` and ``ball_NNNN.vtu`` per saved frame (meshio)
and ``trajectory.pvd``, the index ParaView reads (each time step: part 0 the sheet, part 1
the ball). ``--format xdmf``: ``sheet.xdmf`` and ``ball.xdmf`` (meshio's XDMF time series,
data inline): an XDMF time series has one geometry, so the points are those of the first
frame and the motion is the point field ``displacement [mm]`` (ParaView: Warp By Vector,
scale 1). Each held body of the run's world (the tube's wall, the bottle's parts,
``physics.bodies``) adds its own part, ``body<K>_NNNN.vtu`` (``body<K>.xdmf``), K its index in
``physics.named_bodies()`` (the names in the .pvd's ``name`` attribute); the ball is drawn with
its own outline when it is not the unit sphere (:mod:`dynslip.app.drawn`).
:mod:`dynslip.data.vtk` has the meshes and fields. The folder is written whole or not at all
(a staging folder renamed on success).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dynslip.app.drawn import drawn_bodies
from dynslip.data.files import write_text
from dynslip.data.folders import StagedRun
from dynslip.data.trajectory import open_trajectory
from dynslip.data.vtk import ball_mesh, revolved_mesh, scales, sheet_mesh
from dynslip.errors import InputError

FORMATS = ("vtu", "xdmf")


def _pvd(entries: list[tuple[float, int, str]], names=None) -> str:
    """The ParaView collection file (.pvd) indexing the frames (time, part, file); ``names``:
    part -> a name written as the data set's ``name`` attribute."""
    root = ET.Element("VTKFile", type="Collection", version="0.1")
    coll = ET.SubElement(root, "Collection")
    for t, part, name in entries:
        extra = {"name": names[part]} if names and part in names else {}
        ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part=str(part),
                      file=name, **extra)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def _parts(ds) -> list[tuple[str, str, Callable[[Any, int], Any]]]:
    """``(file stem, name, make(ds, k))`` of every part: the sheet, the ball, each held body."""

    drawn = drawn_bodies(ds) or {"ball": None, "held": []}
    r = scales(ds)["R"]
    parts: list[tuple[str, str, Callable[[Any, int], Any]]] = [
        ("sheet", "sheet", sheet_mesh),
        ("ball", "ball", lambda d, k: ball_mesh(d, k, outline=drawn["ball"]))]
    for i, (name, outline, shift) in enumerate(drawn["held"]):
        def make(d, k, outline=outline, shift=shift):
            return revolved_mesh(outline, r, 0.0 if shift is None else float(shift[k]))

        parts.append((f"body{i}", name, make))
    return parts


def _write_vtu(ds, folder: Path) -> list[Path]:
    import meshio


    entries = []
    parts = _parts(ds)
    for k, t in enumerate(ds["time"].values):
        for part, (stem, _, make) in enumerate(parts):
            name = f"{stem}_{k:04d}.vtu"
            meshio.write(folder / name, make(ds, k), file_format="vtu")
            entries.append((float(t), part, name))
    names = {i: n for i, (_, n, _) in enumerate(parts) if i >= 2}
    return [write_text(folder / "trajectory.pvd", _pvd(entries, names))]


def _write_xdmf(ds, folder: Path) -> list[Path]:
    import numpy as np
    from meshio.xdmf import TimeSeriesWriter

    paths = []
    for stem, _, make in _parts(ds):
        first = make(ds, 0)
        path = folder / f"{stem}.xdmf"
        with TimeSeriesWriter(path, data_format="XML") as w:
            w.write_points_cells(first.points, first.cells)
            for k, t in enumerate(ds["time"].values):
                m = make(ds, k)
                pd = {**m.point_data, "displacement [mm]": np.asarray(m.points - first.points)}
                w.write_data(float(t), point_data=pd, cell_data=m.cell_data or None)
        paths.append(path)
    return paths


def run_export(
    trajectory, out: Path | None = None, fmt: str = "vtu", console=None, force: bool = False
) -> Path:
    """Export ``trajectory`` into the folder ``out`` (default ``<trajectory folder>/paraview``);
    return the file to open (``trajectory.pvd`` or ``sheet.xdmf``)."""

    if fmt not in FORMATS:
        raise InputError(f"--format {fmt!r}: allowed: {', '.join(FORMATS)}")
    path = Path(trajectory)
    ds = open_trajectory(path)
    out = Path(out) if out is not None else path.parent / "paraview"
    with StagedRun(out, force=force, kind="export") as staging:
        (_write_vtu if fmt == "vtu" else _write_xdmf)(ds, staging)
    main = out / ("trajectory.pvd" if fmt == "vtu" else "sheet.xdmf")
    if console is not None:
        console.print(f"{ds.sizes['time']} frames of {path} -> {main}")
    return main
