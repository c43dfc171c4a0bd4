"""Animations of a forming run: the meridian section beside the space-time map of contact.

Each frame is drawn from one saved frame of ``trajectory.nc`` (nothing is interpolated or
recomputed): on the left the meridian section (rho, z), mirrored about the axis, with the
ball, the sheet coloured by its contact state (free, stuck, slipping toward the pole,
slipping toward the equator), the stick fronts (:mod:`dynslip.analysis.fronts`) as black diamonds
and the clamp; the title gives the stage, the time and the load (clamp force and the
force of the hold on the ball in newtons, from the scale ``force_scale_N``). On the right
the space-time map of the state with the front tracks and a cursor at the frame's time.

GIF is written through imageio's Pillow plugin, MP4 (H.264) through imageio-ffmpeg, whose
wheel ships its own ffmpeg binary.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import xarray as xr

from dynslip.analysis.front_summary import fronts_dataset, rest_speed_of
from dynslip.analysis.fronts import motion_state
from dynslip.data.trajectory import open_trajectory, stage_names, time_indices
from dynslip.errors import InputError
from dynslip.plot.forming import outcome_title
from dynslip.plot.fronts import draw_spacetime
from dynslip.plot.style import STATE_COLORS, STATE_LABELS, pyplot

if TYPE_CHECKING:
    from imageio.plugins.ffmpeg import FfmpegFormat
    from imageio.plugins.pillow import PillowPlugin
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.patches import Circle, Polygon

FORMATS = ("gif", "mp4")
DEFAULT_SIZE = (960, 432)
DEFAULT_FPS = 10.0
DEFAULT_MAX_FRAMES = 200


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` in pixels -> (W, H); :class:`InputError` unless both are in 160..3840."""
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise InputError(
            f"size: {text!r} is not WxH; allowed: two integers in pixels, e.g. 960x432"
        ) from None
    return _check_size((w, h))


def _check_size(size) -> tuple[int, int]:
    w, h = (int(v) for v in size)
    if not (160 <= w <= 3840 and 160 <= h <= 3840):
        raise InputError(f"size: {w}x{h} pixels; allowed: width and height between 160 and 3840")
    return w, h


def frame_indices(
    ds: xr.Dataset, t_range=None, max_frames: int | None = DEFAULT_MAX_FRAMES
) -> np.ndarray:
    """The saved frames an animation shows: those in ``t_range``, thinned evenly to at most
    ``max_frames`` (first and last kept). :class:`InputError` for a range outside the run."""
    idx = time_indices(ds, t_range)
    if max_frames is not None:
        if int(max_frames) < 1:
            raise InputError(f"max_frames: {max_frames!r}; allowed: a positive integer or None")
        if idx.size > max_frames:
            pick = np.unique(np.round(np.linspace(0, idx.size - 1, int(max_frames))).astype(int))
            idx = idx[pick]
    return idx


class _Renderer:
    """A figure whose artists are updated in place for each saved frame."""

    def __init__(
        self,
        ds: xr.Dataset,
        fronts: xr.Dataset,
        frames: np.ndarray,
        size,
        map_frames=None,
        outcome=None,
        bodies=None,
    ):
        from matplotlib.collections import LineCollection
        from matplotlib.colors import to_rgba
        from matplotlib.lines import Line2D
        from matplotlib.patches import Circle, Polygon

        plt = pyplot()
        self.ds, self.fronts = ds, fronts
        self.plt = plt
        w, h = size
        self.fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
        gs = self.fig.add_gridspec(
            1, 2, width_ratios=[1.25, 1.0], left=0.07, right=0.98, bottom=0.2, top=0.84, wspace=0.2
        )
        self.ax = self.fig.add_subplot(gs[0])
        self.ax_map = self.fig.add_subplot(gs[1])
        self.t = np.asarray(ds["time"].values, dtype=float)
        self.state = motion_state(ds, rest_speed_of(fronts))
        self.rho = np.asarray(ds["rho"].transpose("time", "rbar").values, dtype=float)
        self.z = np.asarray(ds["z"].transpose("time", "rbar").values, dtype=float)
        self.names = stage_names(ds)
        self.stage = np.asarray(ds["stage"].values).astype(int)
        self.scale_n = float(ds.attrs.get("force_scale_N", np.nan))
        self.front_node = (
            np.asarray(fronts["front_node"].values)
            if fronts.sizes["track"]
            else np.zeros((0, self.t.size))
        )
        self.colors = np.array([to_rgba(c) for c in STATE_COLORS])

        sel = frames
        cz, cr, bz = (
            np.asarray(ds[v].values, dtype=float)[sel] for v in ("clamp_z", "clamp_rho", "ball_z")
        )
        xmax = np.nanmax(np.r_[np.abs(self.rho[sel]).ravel(), cr, 1.0]) * 1.08
        zlo = np.nanmin(np.r_[self.z[sel].ravel(), cz, bz - 1.0])
        zhi = np.nanmax(np.r_[self.z[sel].ravel(), cz, bz + 1.0])
        pad = 0.08 * (zhi - zlo)
        self.ax.set_xlim(-xmax, xmax)
        self.ax.set_ylim(zlo - pad, zhi + pad)
        self.ax.set_aspect("equal", adjustable="box")
        self.ax.set_xlabel(r"$\rho / R$")
        self.ax.set_ylabel(r"$z / R$")
        self.ax.axvline(0, color="0.8", lw=0.6, zorder=0)
        # the ball: the unit circle, or its own outline (both halves), moved by ball_z; each
        # held body's outline, drawn once, or moved by its shift (``bodies``: dynslip.app.drawn)
        bodies = bodies or {}
        style = dict(facecolor="#f4efe1", edgecolor="0.35", lw=1.0, zorder=1)
        if bodies.get("ball") is None:
            self.ball_parts: list[tuple[Circle | Polygon, np.ndarray | None]] = [
                (Circle((0.0, 0.0), 1.0, **style), None)]
        else:
            self.ball_parts = [(Polygon(h, closed=True, **style), h)
                               for h in _halves(bodies["ball"])]
        self.moving = []
        for _, outline, shift in bodies.get("held", ()):
            for h in _halves(outline):
                patch = Polygon(h, closed=True, facecolor="#cfd6dc", edgecolor="0.45", lw=0.8,
                                zorder=1)
                self.ax.add_patch(patch)
                if shift is not None:
                    self.moving.append((patch, h, shift))
        for part, _ in self.ball_parts:
            self.ax.add_patch(part)
        self.ball = self.ball_parts[0][0]
        self.sheet = LineCollection([], linewidths=2.6, capstyle="round", zorder=3)
        self.ax.add_collection(self.sheet)
        (self.front_pts,) = self.ax.plot(
            [], [], "D", ms=5, mfc="k", mec="w", mew=0.6, zorder=5, ls="none"
        )
        (self.clamp,) = self.ax.plot([], [], "s", ms=8, color="k", zorder=4, ls="none")
        handles = [
            Line2D([], [], color=c, lw=3, label=m)
            for c, m in zip(STATE_COLORS, STATE_LABELS, strict=True)
        ]
        handles += [
            Line2D([], [], marker="D", mfc="k", mec="w", ls="none", label="stick front"),
            Line2D([], [], marker="s", color="k", ls="none", label="clamp"),
        ]
        self.fig.legend(handles=handles, fontsize=7, loc="lower center", ncol=6, frameon=False)
        self.title = self.fig.suptitle("", fontsize=10, x=0.02, ha="left")

        mf = sel if map_frames is None else map_frames
        draw_spacetime(self.ax_map, ds.isel(time=mf), fronts.isel(time=mf), legend=False)
        import textwrap


        end = "\n".join(textwrap.wrap(outcome_title(ds, outcome), 60))
        self.ax_map.set_title(
            f"contact state; fronts in black\n{end}", fontsize=8
        )
        self.cursor = self.ax_map.axhline(self.t[sel[0]], color="#2ca02c", lw=1.8)
        # blitting: the static parts are drawn once, the moving artists on top for each frame
        self.dynamic = [*(p for p, *_ in self.moving + self.ball_parts), self.sheet, self.clamp,
                        self.front_pts, self.cursor, self.title]
        for a in self.dynamic:
            a.set_animated(True)
        self.fig.canvas.draw()
        # the Agg backend's canvas (plot.style.pyplot chose it)
        self.background = cast("FigureCanvasAgg", self.fig.canvas).copy_from_bbox(self.fig.bbox)

    def _segments(self, k: int):
        """Two half-segments per node (to the midpoints with its neighbours), mirrored."""
        p = np.stack([self.rho[k], self.z[k]], axis=1)  # (n, 2)
        mid = 0.5 * (p[1:] + p[:-1])  # (n-1, 2)
        left = np.concatenate([p[:1], mid])  # start of each node's polyline
        right = np.concatenate([mid, p[-1:]])
        segs = np.concatenate([np.stack([left, p], 1), np.stack([p, right], 1)])  # (2n, 2, 2)
        segs = np.concatenate([segs, segs * np.array([-1.0, 1.0])])  # mirrored half
        cols = np.tile(self.colors[self.state[k]], (4, 1))
        ok = np.isfinite(segs).all(axis=(1, 2))
        return segs[ok], cols[ok]

    def draw(self, k: int) -> np.ndarray:
        ds = self.ds
        segs, cols = self._segments(k)
        self.sheet.set_segments(segs)
        self.sheet.set_color(cols)
        zb = float(ds["ball_z"].values[k])
        for part, h in self.ball_parts:
            if h is None:  # the unit circle
                cast("Circle", part).set_center((0.0, zb))
            else:
                cast("Polygon", part).set_xy(h + np.array([0.0, zb]))
        for patch, h, shift in self.moving:
            patch.set_xy(h + np.array([0.0, float(shift[k])]))
        nodes = self.front_node[:, k]
        nodes = nodes[nodes >= 0].astype(int)
        fx = 0.5 * (self.rho[k, nodes] + self.rho[k, nodes + 1])
        fz = 0.5 * (self.z[k, nodes] + self.z[k, nodes + 1])
        self.front_pts.set_data(np.r_[fx, -fx], np.r_[fz, fz])
        cr, cz = float(ds["clamp_rho"].values[k]), float(ds["clamp_z"].values[k])
        self.clamp.set_data([-cr, cr], [cz, cz])
        s = int(self.stage[k])
        name = self.names[s] if 0 <= s < len(self.names) else str(s)
        fc = float(ds["clamp_force"].values[k])
        text = (
            f"stage {s}: {name}    t = {self.t[k]:.4g} s    "
            f"clamp force {fc * self.scale_n:.3g} N ({fc:.3g} G h0 R)"
        )
        if "ball_reaction" in ds:
            text += f"    hold on ball {float(ds['ball_reaction'].values[k]) * self.scale_n:.3g} N"
        text += (
            f"\nclamp at z = {cz:.3g} R    "
            f"contact to theta = {float(ds['theta_max'].values[k]):.3g} rad"
        )
        self.title.set_text(text)
        self.cursor.set_ydata([self.t[k], self.t[k]])
        canvas = cast("FigureCanvasAgg", self.fig.canvas)  # the Agg backend's
        canvas.restore_region(self.background)
        for a in self.dynamic:
            self.fig.draw_artist(a)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def close(self):
        self.plt.close(self.fig)


def _halves(outline) -> list[np.ndarray]:
    """A meridian outline (M, 2), rho >= 0, and its mirror image about the axis."""
    o = np.asarray(outline, float)
    return [o, o * np.array([-1.0, 1.0])]


def _prepare(trajectory_path, t_range, size, max_frames):
    ds = open_trajectory(trajectory_path)
    size = _check_size(size)
    frames = frame_indices(ds, t_range, max_frames)
    return ds, size, frames


def animate(
    trajectory_path,
    out_path=None,
    fps: float = DEFAULT_FPS,
    t_range=None,
    size=DEFAULT_SIZE,
    fmt: str = "gif",
    max_frames: int | None = DEFAULT_MAX_FRAMES,
    rest_speed: float | None = None,
    bodies: dict | None = None,
) -> Path:
    """Write an animation of a run; one frame per saved frame shown; returns its path.

    ``t_range``: ``(t_start, t_end)`` in seconds (either may be ``None``); ``size``:
    (width, height) in pixels (rounded up to multiples of 16 for MP4); ``fmt``: ``"gif"``
    or ``"mp4"``; ``out_path`` defaults to ``animation.<fmt>`` beside the trajectory;
    ``max_frames`` thins the saved frames evenly when the range holds more; ``rest_speed``
    (R/s, optional) colours slipping nodes slower than this as stuck
    (:func:`dynslip.analysis.fronts.motion_state`; default: the state flags as saved);
    ``bodies``: the outlines to draw (:func:`dynslip.app.drawn.drawn_bodies`: the ball's, None
    for the unit circle, and each held body's; default: the unit circle only). Bad options,
    a
    file that is not a trajectory of this format version, or a range outside the run raise
    :class:`~dynslip.errors.InputError`.
    """
    fmt = str(fmt).lower()
    if fmt not in FORMATS:
        raise InputError(f"format: {fmt!r}; allowed: {', '.join(FORMATS)}")
    if not (np.isfinite(fps) and 0 < fps <= 100):
        raise InputError(f"fps: {fps!r}; allowed: 0 < fps <= 100 frames per second")
    w, h = _check_size(size)
    if fmt == "mp4":
        w, h = 16 * -(-w // 16), 16 * -(-h // 16)
    ds, size, frames = _prepare(trajectory_path, t_range, (w, h), max_frames)
    out_path = (
        Path(trajectory_path).parent / f"animation.{fmt}" if out_path is None else Path(out_path)
    )
    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(f".{out_path.stem}.tmp{out_path.suffix}")
    fronts = fronts_dataset(ds, rest_speed)
    renderer = _Renderer(ds, fronts, frames, size, map_frames=time_indices(ds, t_range),
                         bodies=bodies)
    try:
        if fmt == "gif":
            _write_gif(renderer, frames, tmp, fps)
        else:
            _write_mp4(renderer, frames, tmp, fps)
        tmp.replace(out_path)
    finally:
        renderer.close()
        tmp.unlink(missing_ok=True)
    return out_path


def _write_gif(renderer: _Renderer, frames, path: Path, fps: float) -> None:
    import imageio.v3 as iio

    with iio.imopen(path, "w", plugin="pillow", extension=".gif") as f:
        gif = cast("PillowPlugin", f)  # its write takes GIF's duration and loop
        for k in frames:
            gif.write(renderer.draw(int(k)), duration=1000.0 / fps, loop=0)


def _write_mp4(renderer: _Renderer, frames, path: Path, fps: float) -> None:
    import imageio.v2 as iio2

    writer = iio2.get_writer(
        path,
        format="FFMPEG",
        mode="I",
        fps=fps,
        codec="libx264",
        pixelformat="yuv420p",
        macro_block_size=16,
        quality=7,
    )
    try:
        for k in frames:
            writer.append_data(renderer.draw(int(k)))
    finally:
        writer.close()


def save_frame_png(
    trajectory_path,
    out_path,
    time: float | None = None,
    size=DEFAULT_SIZE,
    rest_speed: float | None = None,
    outcome: str | None = None,
    bodies: dict | None = None,
) -> Path:
    """Write the animation frame at the saved frame nearest ``time`` (s; default the last)
    as a PNG; ``outcome``: the run's answer in words for the map's title (summary.json's);
    ``bodies``: as :func:`animate`'s.
    :class:`InputError` for a time outside the run."""
    ds = open_trajectory(trajectory_path)
    size = _check_size(size)
    t = np.asarray(ds["time"].values, dtype=float)
    if time is None:
        k = t.size - 1
    else:
        time_indices(ds, (float(time), None))  # InputError for a time outside the run
        k = int(np.argmin(np.abs(t - float(time))))
    fronts = fronts_dataset(ds, rest_speed)
    renderer = _Renderer(
        ds, fronts, np.array([k]), size, map_frames=np.arange(t.size), outcome=outcome,
        bodies=bodies,
    )
    try:
        from PIL import Image

        out_path = Path(out_path)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        tmp = out_path.with_name(f".{out_path.stem}.tmp.png")
        Image.fromarray(renderer.draw(k)).save(tmp, format="PNG", optimize=True)
        tmp.replace(out_path)
        return out_path
    finally:
        renderer.close()


def describe(path) -> dict:
    """Frame count and size of a written animation (read back with imageio)."""
    import imageio.v3 as iio

    path = Path(path)
    if path.suffix.lower() == ".gif":
        arr = iio.imread(path, index=None, plugin="pillow")
        return {
            "frames": int(arr.shape[0]),
            "height": int(arr.shape[1]),
            "width": int(arr.shape[2]),
        }
    import imageio.v2 as iio2

    reader = cast("FfmpegFormat.Reader", iio2.get_reader(path, format="FFMPEG"))
    try:
        n = reader.count_frames()
        h, w = reader.get_data(0).shape[:2]
        return {
            "frames": int(n),
            "height": int(h),
            "width": int(w),
            "fps": float(reader.get_meta_data()["fps"]),
        }
    finally:
        reader.close()
