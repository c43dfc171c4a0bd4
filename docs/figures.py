"""Make every figure of docs/ and the README from the shipped scenarios: one command.

    python docs/figures.py                 # the shipped settings (N = 50): about 2 min on 2 cores
    python docs/figures.py --fast          # numerics.nodes = 30 everywhere: a check that all draw
    python docs/figures.py --only fronts_let_go.png
    python docs/figures.py --stale         # only the figures whose key is not today's
    python docs/figures.py --check         # list those, draw nothing (exit 1 if any)

:data:`RUNS` are the runs the figures are drawn from (the scenario, the fields set, and the
command line that makes the same run); :data:`FIGURES` is the manifest: every image under
docs/img/, the run it is drawn from and the command that draws it. ``tests/test_docs.py``
checks that every image the docs show is in the manifest, that every image of the manifest
is shown, and that docs/img holds nothing else, so a figure cannot outlive the code that
made it. The runs are written to ``outputs/figures/<run>/`` (``--runs DIR``), the
figures to docs/img/ (``--img DIR``); a run folder of an earlier call is reused with
``--reuse``.

Each figure carries, in a tEXt chunk of its PNG (``dynslip-key``; Pillow's
``Image.open(p).text`` reads it), the key of what drew it (:func:`figure_key`): the package's
physics (the files a measured table depends on, docs/results.py's ``PACKAGE`` less
``NOT_PHYSICS``), the plotting code (:data:`PLOTTING`), the scenario files of its run
(``start_from`` followed) and the run's ``--set`` fields, each file hashed and combined in
sorted path order as docs/results.py does for a table. A figure whose key is not today's is
stale: ``--check`` lists them, ``--stale`` redraws exactly those, ``tests/test_docs.py``
names them. The chunk is written after drawing (:func:`stamp`), whatever drew the PNG
(matplotlib here, or a copy of the run's own figure).
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import sys
import tempfile
import textwrap
import zlib
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
#: the plotting code every figure depends on, beside the package's physics
PLOTTING = ("dynslip/plot/**/*.py", "docs/figures.py")
#: the tEXt keyword of the key in a figure's PNG
KEY_FIELD = "dynslip-key"


def _results():
    """docs/results.py, beside this file (loaded by path: docs/ is not a package), whose key
    the figures share."""
    name = "docs_results"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name("results.py"))
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod  # dataclasses look their module up by name
        spec.loader.exec_module(mod)
    return sys.modules[name]


#: the fast settings of ``--fast``: 30 nodes, the fewest at which these paths' contact stays
#: resolved (the tube path with fed material needs its shipped 50: ``fast=False``)
FAST = {"numerics.nodes": 30}


@dataclass(frozen=True)
class Run:
    scenario: str
    set: dict = field(default_factory=dict)
    fast: bool = True  # --fast applies FAST to this run

    def fields(self, fast: bool = False) -> dict:
        return {**self.set, **(FAST if fast and self.fast else {})}

    def command(self, fast: bool = False) -> str:
        return " ".join(
            [
                "dynslip run",
                self.scenario,
                *(f"--set {k}={v}" for k, v in self.fields(fast).items()),
            ]
        )


RUNS = {
    "method2": Run("scenarios/method2.yaml"),
    "method2_pinned": Run("scenarios/method2_pinned.yaml"),
    "method2_let_go": Run("scenarios/method2_let_go.yaml", {"numerics.save_interval_s": 0.5}),
    "method1": Run("scenarios/method1.yaml", {"numerics.save_interval_s": 0.5}),
    "method2_rim_feed": Run("scenarios/method2_rim_feed.yaml", fast=False),
    "release_pull_tube": Run("scenarios/release_pull_tube.yaml", fast=False),
    "method2_adhesive": Run("scenarios/method2_adhesive.yaml", fast=False),
    "release_pull_tube_adhesive": Run("scenarios/release_pull_tube_adhesive.yaml", fast=False),
    "coin": Run("scenarios/coin.yaml", {"physics.friction.mu_s": 0.99,
                                        "physics.friction.mu_k": 0.82}),
    "method2_rim80": Run(
        "scenarios/method2_pinned.yaml",
        {"numerics.nodes": 100, "physics.stages.0.clamp_to_z_mm": -80.0},
    ),
}


@dataclass(frozen=True)
class Figure:
    run: str
    command: str  # what draws it from the run folder DIR (the run's own command first)
    draw: str  # the function of this module that draws it: draw(run_dir, out_path)


FIGURES = {
    "export_paraview.png": Figure(
        "method2_let_go",
        "dynslip run scenarios/method2_let_go.yaml; dynslip export DIR/trajectory.nc; the last "
        "frame's .vtu files read back with meshio and drawn with matplotlib's 3D axes",
        "export_view",
    ),
    "meridian_method2.png": Figure(
        "method2", "dynslip run scenarios/method2.yaml (DIR/meridian.png)", "copy_meridian"
    ),
    "state_map_method2.png": Figure(
        "method2", "dynslip run scenarios/method2.yaml (DIR/state_map.png)", "copy_state_map"
    ),
    "world_method2.png": Figure(
        "method2", "dynslip run scenarios/method2.yaml (DIR/world.png)", "copy_world"
    ),
    "state_map_tube_wall_method2.png": Figure(
        "method2",
        "dynslip run scenarios/method2.yaml; "
        "dynslip fronts DIR/trajectory.nc --body 'tube wall' (DIR/state_map_tube_wall.png)",
        "body_state_tube_wall",
    ),
    "animation_frame_method2_bodies.png": Figure(
        "method2",
        "dynslip run scenarios/method2.yaml; "
        "dynslip.plot.animate.save_frame_png(DIR / 'trajectory.nc', PATH, time=<widest contact>, "
        "bodies=dynslip.app.drawn.drawn_bodies_at(DIR / 'trajectory.nc'))",
        "animation_frame_bodies",
    ),
    "fronts_method2_tube.png": Figure(
        "method2_pinned", "dynslip fronts DIR/trajectory.nc (DIR/fronts.png)", "fronts"
    ),
    "animation_frame_let_go.png": Figure(
        "method2_let_go",
        "dynslip.plot.animate.save_frame_png(DIR / 'trajectory.nc', PATH, time=<let_go + 4 s>, "
        "rest_speed=1e-4)",
        "animation_frame",
    ),
    "fronts_let_go.png": Figure(
        "method2_let_go", "dynslip fronts DIR/trajectory.nc (DIR/fronts.png)", "fronts"
    ),
    "fronts_let_go_rest_speed.png": Figure(
        "method2_let_go", "dynslip fronts DIR/trajectory.nc --rest-speed 1e-4", "fronts_rest_speed"
    ),
    "fronts_method1_rest_speed.png": Figure(
        "method1", "dynslip fronts DIR/trajectory.nc --rest-speed 1e-4", "fronts_rest_speed"
    ),
    "meridian_rim_feed.png": Figure(
        "method2_rim_feed",
        "dynslip run scenarios/method2_rim_feed.yaml (DIR/meridian.png)",
        "copy_meridian",
    ),
    "release_force_tube.png": Figure(
        "release_pull_tube",
        "dynslip run scenarios/release_pull_tube.yaml (DIR/release_force.png)",
        "copy_release_force",
    ),
    "meridian_method2_adhesive.png": Figure(
        "method2_adhesive",
        "dynslip run scenarios/method2_adhesive.yaml (DIR/meridian.png)",
        "copy_meridian",
    ),
    "release_force_tube_adhesive.png": Figure(
        "release_pull_tube_adhesive",
        "dynslip run scenarios/release_pull_tube_adhesive.yaml (DIR/release_force.png)",
        "copy_release_force",
    ),
    "meridian_coin.png": Figure(
        "coin",
        "dynslip run scenarios/coin.yaml --set physics.friction.mu_s=0.99 "
        "--set physics.friction.mu_k=0.82 (DIR/meridian.png)",
        "copy_meridian",
    ),
    "state_map_coin.png": Figure(
        "coin",
        "dynslip run scenarios/coin.yaml --set physics.friction.mu_s=0.99 "
        "--set physics.friction.mu_k=0.82 (DIR/state_map.png)",
        "copy_state_map",
    ),
    "world_method2_rim80.png": Figure(
        "method2_rim80",
        "dynslip run scenarios/method2_pinned.yaml --set numerics.nodes=100 "
        "--set physics.stages.0.clamp_to_z_mm=-80; dynslip.plot.world.plot_world(ds, frames, "
        "held=bottle(20.0), with_clamp=(tube_wall(20.0),))",
        "world",
    ),
}


def figure_key(name: str, fast: bool = False) -> str:
    """The key of what draws figure ``name``: physics, plotting code, its run's scenario files
    and ``--set`` fields (``fast``: those of ``--fast``), and the function that draws it."""
    res = _results()
    fig = FIGURES[name]
    run = RUNS[fig.run]
    files = [*res.source_files(), *res.source_files(PLOTTING, ()),
             *res.scenario_files([run.scenario])]
    return res.files_key(files, extra=f"{run.command(fast)}\n{fig.draw}")


_PNG = b"\x89PNG\r\n\x1a\n"


def _chunks(data: bytes):
    """(start, type, body, end) of each chunk of a PNG file's bytes."""
    i = len(_PNG)
    while i + 8 <= len(data):
        n = int.from_bytes(data[i : i + 4], "big")
        yield i, data[i + 4 : i + 8], data[i + 8 : i + 8 + n], i + 12 + n
        i += 12 + n


def read_key(path: Path) -> str | None:
    """The ``dynslip-key`` text of a PNG file; None without one (or no such file)."""
    data = path.read_bytes() if path.is_file() else b""
    if not data.startswith(_PNG):
        return None
    for _, kind, body, _ in _chunks(data):
        word, _, text = body.partition(b"\0")
        if kind == b"tEXt" and word == KEY_FIELD.encode():
            return text.decode("latin-1")
    return None


def stamp(path: Path, key: str) -> None:
    """Write ``key`` as the PNG's ``dynslip-key`` tEXt chunk (before IEND; an earlier one
    replaced); the image itself is not touched."""
    data = path.read_bytes()
    body = KEY_FIELD.encode() + b"\0" + key.encode("latin-1")
    text = len(body).to_bytes(4, "big") + b"tEXt" + body
    text += zlib.crc32(b"tEXt" + body).to_bytes(4, "big")
    out = [_PNG]
    for start, kind, old, end in _chunks(data):
        if kind == b"tEXt" and old.partition(b"\0")[0] == KEY_FIELD.encode():
            continue
        out += [text] if kind == b"IEND" else []
        out.append(data[start:end])
    path.write_bytes(b"".join(out))


def stale_figures(img: Path = IMG, fast: bool = False, names=None) -> dict[str, str]:
    """Each figure (of ``names``, default all) in ``img`` whose key is not today's, with what
    is wrong."""
    out = {}
    for name in names or sorted(FIGURES):
        now, was = figure_key(name, fast), read_key(img / name)
        if was != now:
            why = ("missing" if not (img / name).is_file() else "no key" if was is None
                   else f"drawn with key {was}")
            out[name] = f"{why}, today's key {now}"
    return out


def copy_meridian(run_dir: Path, out: Path) -> None:
    shutil.copyfile(run_dir / "meridian.png", out)


def copy_state_map(run_dir: Path, out: Path) -> None:
    shutil.copyfile(run_dir / "state_map.png", out)


def copy_world(run_dir: Path, out: Path) -> None:
    shutil.copyfile(run_dir / "world.png", out)


def copy_release_force(run_dir: Path, out: Path) -> None:
    shutil.copyfile(run_dir / "release_force.png", out)


def fronts(run_dir: Path, out: Path, rest_speed: float | None = None) -> None:
    from dynslip.app.fronts import run_fronts

    with tempfile.TemporaryDirectory() as tmp:
        png = next(
            p
            for p in run_fronts(run_dir / "trajectory.nc", Path(tmp), rest_speed=rest_speed)
            if p.suffix == ".png"
        )
        shutil.copyfile(png, out)


def fronts_rest_speed(run_dir: Path, out: Path) -> None:
    fronts(run_dir, out, rest_speed=1e-4)


def body_state_tube_wall(run_dir: Path, out: Path) -> None:
    from dynslip.app.fronts import run_fronts

    with tempfile.TemporaryDirectory() as tmp:
        (png,) = run_fronts(run_dir / "trajectory.nc", Path(tmp), body="tube wall")
        shutil.copyfile(png, out)


def animation_frame_bodies(run_dir: Path, out: Path) -> None:
    """The main job's frame at the widest contact on the ball: every body drawn (the tube's
    wall at rest, the bottle moving with the ball)."""
    import json

    import numpy as np
    import xarray as xr

    from dynslip.app.drawn import drawn_bodies_at
    from dynslip.plot.animate import save_frame_png

    with xr.open_dataset(run_dir / "trajectory.nc", engine="netcdf4") as ds:
        theta = ds["theta_max"].values
        t = float(ds["time"].values[int(np.nanargmax(theta)) if np.isfinite(theta).any() else -1])
    outcome = json.loads((run_dir / "summary.json").read_text()).get("outcome")
    save_frame_png(run_dir / "trajectory.nc", out, time=t, outcome=outcome,
                   bodies=drawn_bodies_at(run_dir / "trajectory.nc"))


def animation_frame(run_dir: Path, out: Path) -> None:
    """The frame 4 s into let_go: the cap at rest while the sheet near the edge slips back."""
    import json

    import numpy as np
    import xarray as xr

    from dynslip.plot.animate import save_frame_png

    with xr.open_dataset(run_dir / "trajectory.nc", engine="netcdf4") as ds:
        names = json.loads(ds.attrs["stage_names"])
        t = ds["time"].values[np.flatnonzero(ds["stage"].values == names.index("let_go"))[0]] + 4.0
    outcome = json.loads((run_dir / "summary.json").read_text()).get("outcome")
    save_frame_png(run_dir / "trajectory.nc", out, time=float(t), rest_speed=1e-4, outcome=outcome)


def world(run_dir: Path, out: Path) -> None:
    """The meridian with the apparatus: the sheet at the bottom of the push-down and at the
    end, the ball, the tube's wall (moving with the clamp) and the assumed bottle."""
    import json

    import numpy as np
    import xarray as xr

    from dynslip.data.files import save_figure
    from dynslip.physics.bodies.apparatus import bottle, tube_wall
    from dynslip.plot.world import plot_world

    outcome = json.loads((run_dir / "summary.json").read_text()).get("outcome", "")
    with xr.open_dataset(run_dir / "trajectory.nc", engine="netcdf4") as ds:
        ds = ds.load()
    bottom = int(np.flatnonzero(ds["stage"].values == 0)[-1])
    frames = {"bottom of the push-down": bottom, "end": ds.sizes["time"] - 1}
    end = "\n".join(textwrap.wrap(f"end: {outcome}", 55))
    fig = plot_world(
        ds,
        frames,
        held=bottle(20.0),
        with_clamp=(tube_wall(20.0),),
        title=f"the tube path, rim to -80 mm (N = 100)\n{end}",
    )
    save_figure(fig, out, dpi=120)


def export_view(run_dir: Path, out: Path) -> None:
    """The exported VTU files of the run's last frame, read back with meshio, the sheet coloured
    by its contact pressure over the ball (half the revolution cut away to show the ball)."""
    import xml.etree.ElementTree as ET

    import meshio
    import numpy as np
    from matplotlib import cm
    from matplotlib.figure import Figure as MplFigure

    from dynslip.app.export import run_export

    pvd = run_export(run_dir / "trajectory.nc", run_dir / "paraview", force=True)
    files = [e.get("file") for e in ET.parse(pvd).getroot().iter("DataSet")]
    sheet = meshio.read(pvd.parent / [f for f in files if "sheet" in f][-1])
    ball = meshio.read(pvd.parent / [f for f in files if "ball" in f][-1])
    fig = MplFigure(figsize=(6.4, 5.6), constrained_layout=True)
    ax = fig.add_subplot(projection="3d")
    name = next(k for k in sheet.point_data if k.startswith("pressure"))
    p = np.asarray(sheet.point_data[name])
    for mesh, colour in ((ball, None), (sheet, p)):
        pts, quads = mesh.points, mesh.cells_dict["quad"]
        keep = pts[quads].mean(axis=1)[:, 1] <= 1e-9  # the half y <= 0
        polys = pts[quads[keep]]
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        if colour is None:
            col = Poly3DCollection(polys, facecolor="0.75", edgecolor="none", alpha=0.6)
        else:
            c = colour[quads[keep]].mean(axis=1)
            col = Poly3DCollection(
                polys, facecolor=cm.viridis(c / max(c.max(), 1e-300)), edgecolor="none"
            )
        ax.add_collection3d(col)
    lim = float(np.abs(sheet.points).max())
    ax.set(
        xlim=(-lim, lim),
        ylim=(-lim, lim),
        zlim=(-lim, lim),
        xlabel="x (mm)",
        ylabel="y (mm)",
        zlabel="z (mm)",
    )
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=15, azim=-60)
    ax.set_title(
        f"dynslip export, last frame, read back with meshio: sheet coloured by\n"
        f"{name} (0 to {p.max():.3g}), ball grey",
        fontsize=9,
    )
    fig.savefig(out, dpi=110)


def make_run(name: str, runs_dir: Path, fast: bool, reuse: bool) -> Path:
    import dynslip

    out = runs_dir / name
    if reuse and (out / "trajectory.nc").is_file():
        return out
    r = RUNS[name]
    scn = dynslip.load(ROOT / r.scenario, set=r.fields(fast))
    print(f"  {r.command(fast)} --out {out}", flush=True)
    try:
        dynslip.run(scn, out=out, force=True)
    except dynslip.ComputationError as err:
        kept = getattr(err, "dynslip_kept", None)
        if kept is None or "trapped: unknown" not in str(err):
            raise
        # a run whose answer is unknown (a --fast mesh that does not resolve a body) still
        # draws: its figures say so in their titles
        import shutil

        shutil.rmtree(out, ignore_errors=True)
        Path(kept).rename(out)
        print(f"  (trapped unknown: {str(err)[:120]}...)", flush=True)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--fast", action="store_true", help=f"set {FAST} on every run (a check that all draw)"
    )
    p.add_argument("--only", action="append", choices=sorted(FIGURES), help="make only this figure")
    p.add_argument(
        "--runs", type=Path, default=ROOT / "outputs" / "figures", help="folder of the runs"
    )
    p.add_argument("--img", type=Path, default=IMG, help="folder of the figures (default docs/img)")
    p.add_argument("--reuse", action="store_true", help="reuse a run folder of an earlier call")
    p.add_argument("--stale", action="store_true",
                   help="draw only the figures whose key is not today's")
    p.add_argument("--check", action="store_true",
                   help="list the figures whose key is not today's, draw nothing")
    args = p.parse_args(argv)
    wanted = args.only or sorted(FIGURES)
    if args.check or args.stale:
        stale = stale_figures(args.img, args.fast, wanted)
        if args.check:
            for name, why in stale.items():
                print(f"stale: {name}: {why}")
            print(f"{len(stale)} of {len(wanted)} stale")
            return 1 if stale else 0
        wanted = [n for n in wanted if n in stale]
        print(f"{len(wanted)} stale: {', '.join(wanted) or 'nothing to draw'}", flush=True)
    args.img.mkdir(parents=True, exist_ok=True)
    done: dict[str, Path] = {}
    for name in wanted:
        fig = FIGURES[name]
        if fig.run not in done:
            done[fig.run] = make_run(fig.run, args.runs, args.fast, args.reuse)
        globals()[fig.draw](done[fig.run], args.img / name)
        stamp(args.img / name, figure_key(name, args.fast))
        print(f"{args.img / name}: {fig.command}", flush=True)
    return 0


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    raise SystemExit(main())
