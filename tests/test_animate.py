"""Animations and trajectory validation on small synthetic contract-conforming datasets."""

import json

import numpy as np
import pytest
import xarray as xr

from dynslip.data.files import write_netcdf
from dynslip.data.trajectory import open_trajectory
from dynslip.errors import InputError
from dynslip.plot.animate import animate, describe, frame_indices, parse_size, save_frame_png
from helpers import synthetic_trajectory

NT, NR = 8, 24


def _state():
    """A slipping edge region that sticks from the pole outward, contact growing."""
    s = np.zeros((NT, NR), dtype=np.int8)
    for k in range(NT):
        edge = 8 + k // 2
        s[k, :edge] = 1
        s[k, min(2 + k, edge) : edge] = 3 if k < NT // 2 else 2
    return s


@pytest.fixture(scope="module")
def traj(tmp_path_factory):
    ds = synthetic_trajectory(
        _state(),
        time=np.linspace(0.0, 3.5, NT),
        rbar=np.linspace(0.0, 2.54, NR),
        theta_of_rbar=1.0,
        clamp_z=np.linspace(-0.5, -2.0, NT),
        clamp_force=np.linspace(0.0, 0.5, NT),
    )
    return write_netcdf(ds, tmp_path_factory.mktemp("run") / "trajectory.nc")


def test_gif_has_one_frame_per_saved_frame_in_range(traj, tmp_path):
    out = animate(traj, tmp_path / "a.gif", fps=4, t_range=(0.5, 3.0), size=(400, 240))
    info = describe(out)
    t = np.linspace(0.0, 3.5, NT)
    assert info["frames"] == int(np.sum((t >= 0.5) & (t <= 3.0))) == 6
    assert (info["width"], info["height"]) == (400, 240)
    from PIL import Image

    with Image.open(out) as im:
        assert im.info["duration"] == 250  # ms per frame at 4 frames per second


def test_frames_differ_and_default_path(traj):
    import imageio.v3 as iio

    out = animate(traj, size=(320, 192))
    assert out == traj.parent / "animation.gif"
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == NT
    assert not np.array_equal(frames[0], frames[-1])


def test_mp4_through_imageio_ffmpeg(traj, tmp_path):
    out = animate(traj, tmp_path / "a.mp4", fps=5, size=(330, 200), fmt="mp4")
    info = describe(out)
    assert info["frames"] == NT
    assert (info["width"], info["height"]) == (336, 208)  # rounded up to multiples of 16


def test_max_frames_thins_evenly_keeping_ends(traj):
    ds = open_trajectory(traj)
    idx = frame_indices(ds, None, max_frames=3)
    assert list(idx) == [0, 4, 7]  # linspace(0, 7, 3) rounded half to even
    assert list(frame_indices(ds, (1.0, 2.0), max_frames=None)) == [2, 3, 4]


def test_single_frame_png(traj, tmp_path):
    from PIL import Image

    out = save_frame_png(traj, tmp_path / "f.png", time=2.0, size=(500, 250))
    with Image.open(out) as im:
        assert im.size == (500, 250)


def _rewrite(traj, tmp_path, **attrs):
    ds = xr.open_dataset(traj).load()
    ds.attrs.update(attrs)
    return write_netcdf(ds, tmp_path / "x.nc")


@pytest.mark.parametrize(
    "kind, match",
    [
        ("version", "format_version='2'"),
        ("kind", "kind='fronts'"),
        ("text", "is not a netCDF file"),
        ("missing", "does not exist"),
        ("lacks", "lacks the variable"),
    ],
)
def test_bad_files_raise_one_line_input_error(traj, tmp_path, kind, match):
    if kind == "version":
        path = _rewrite(traj, tmp_path, format_version="2")
    elif kind == "kind":
        path = _rewrite(traj, tmp_path, kind="fronts")
    elif kind == "text":
        path = tmp_path / "trajectory.nc"
        path.write_text(json.dumps({"not": "netcdf"}))
    elif kind == "missing":
        path = tmp_path / "nothing.nc"
    else:
        ds = xr.open_dataset(traj).load().drop_vars("state")
        path = write_netcdf(ds, tmp_path / "x.nc")
    for call in (lambda: animate(path, tmp_path / "a.gif"), lambda: open_trajectory(path)):
        with pytest.raises(InputError, match=match) as err:
            call()
        assert "\n" not in str(err.value)
    assert not (tmp_path / "a.gif").exists()


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"t_range": (-1.0, 2.0)}, "t_start"),
        ({"t_range": (0.0, 9.0)}, "t_end"),
        ({"t_range": (2.0, 1.0)}, "t_end"),
        ({"t_range": (1.1, 1.2)}, "holds no saved frame"),
        ({"fmt": "avi"}, "format"),
        ({"fps": 0}, "fps"),
        ({"size": (10, 10)}, "size"),
    ],
)
def test_bad_options_raise_input_error(traj, tmp_path, kw, match):
    with pytest.raises(InputError, match=match) as err:
        animate(traj, tmp_path / "a.gif", **kw)
    assert "\n" not in str(err.value)
    with pytest.raises(InputError, match="outside the run"):
        save_frame_png(traj, tmp_path / "f.png", time=99.0)


def test_parse_size():
    assert parse_size("640x360") == (640, 360)
    with pytest.raises(InputError, match="size"):
        parse_size("big")
