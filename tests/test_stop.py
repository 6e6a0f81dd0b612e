"""Every long command stops within seconds of SIGTERM or Ctrl-C (SIGINT), wherever it is: exit 128 + the signal,
the one line, no lock, scratch or partial file, every file under a final name whole, and a rerun completes to the
outputs of a run that was never stopped. A run inside one long call of compiled code (the progressive filter's
kernel on a large tile, a 10-minute run) ends as fast: the command line's stop watchdog ends it GRACE seconds after
the signal.

Each command runs as a user runs it (``python -m gistools.cli.main ...`` in its own process); the moments are
fractions of the same command's clean run, measured first, so that a slower machine moves them with it.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from conftest import SAMPLE, repeated_block
from gistools.cli.main import GRACE, INTERRUPTED

GISTOOLS = [sys.executable, "-m", "gistools.cli.main"]
LIMIT = 5.0  # seconds from the signal to the exit


def _dem(path: Path, n: int) -> Path:
    """A rolling DEM of n x n 1 m cells, EPSG:32611 (metres, elevations in metres)."""
    y, x = np.mgrid[0:n, 0:n].astype(np.float32)
    z = 100 + 20 * np.sin(x / 150) + 15 * np.cos(y / 110) + 5 * np.sin((x + y) / 37)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32", crs="EPSG:32611",
                       transform=from_origin(500000, 4100000, 1.0, 1.0), nodata=-9999, tiled=True,
                       compress="deflate") as dst:
        dst.write(z, 1)
        dst.update_tags(1, units="m")
    return path


def _observers(k: int) -> list[str]:
    """k observers 75 m apart on the DEM's diagonal (at most 24 on its 2 km)."""
    args = []
    for i in range(k):
        args += ["--from", f"{500100 + 75 * i},{4099900 - 75 * i}"]
    return args


# name -> (arguments with OUT for the output folder, the input it needs)
CASES = {
    "ground-smrf": (["ground", "TILES", "--out", "OUT", "--jobs", "1"], "many"),
    "ground-smrftin": (["ground", "TILES", "--out", "OUT", "--method", "smrftin", "--jobs", "2"], "many"),
    "ground-csf": (["ground", "TILES", "--out", "OUT", "--method", "csf", "--jobs", "1"], "tiles"),
    "metrics": (["metrics", "TILES", "--out", "OUT", "--cell-size", "3ft", "--metrics", "count,z_max,z_p95,z_sd",
                 "--jobs", "1"], "many"),
    "fuels": (["fuels", "TILES", "--out", "OUT", "--jobs", "1"], "ground"),
    "terrain": (["terrain", "DEM", "--out", "OUT"], "big"),
    "viewshed": (["viewshed", "DEM", "--out", "OUT", *_observers(24)], "dem"),  # ~6 s: well past a stop at 0.6
    "travel-whole": (["travel", "OUT", "--dem", "DEM", "--from", "501000,4099000"], "dem"),
    "travel-blocks": (["travel", "OUT", "--dem", "DEM", "--from", "501000,4099000", "--max-memory", "0.5"], "dem"),
}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("stop_inputs")
    tiles = root / "tiles"
    tiles.mkdir()
    for p in sorted(SAMPLE.glob("*.la[sz]")):
        shutil.copy(p, tiles / p.name)
    many = repeated_block(root / "many")
    ground = root / "ground"  # fuels needs ground points: the tiles classified once
    done = subprocess.run(GISTOOLS + ["ground", str(many), "--out", str(ground), "-q"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return {"tiles": tiles, "many": many, "ground": ground, "dem": _dem(root / "dem.tif", 2000),
            "big": _dem(root / "big.tif", 5000)}


def _args(case: str, inputs: dict, out: Path) -> list[str]:
    args, kind = CASES[case]
    source = inputs[kind]
    return [str(out) if a == "OUT" else str(source) if a in ("TILES", "DEM") else a for a in args]


def _snapshot(out: Path) -> dict:
    """What a folder's outputs hold: each raster's cells, each point file's classes and heights."""
    found = {}
    for path in sorted(out.rglob("*")):
        if path.suffix == ".tif":
            with rasterio.open(path) as src:
                found[path.relative_to(out).as_posix()] = src.read()
        elif path.suffix in (".laz", ".las"):
            las = laspy.read(path)
            found[path.relative_to(out).as_posix()] = np.stack([np.asarray(las.classification, np.float64),
                                                               np.asarray(las.z, np.float64)])
    return found


def _leftovers(out: Path) -> list[str]:
    if not out.exists():
        return []
    return sorted(p.relative_to(out).as_posix() for p in out.rglob("*")
                  if p.name == ".gistools.lock" or ".partial" in p.name or p.name.startswith(".gistools-scratch-"))


def _whole(out: Path) -> None:
    """Every raster and point file under a final name opens and reads whole."""
    for path in out.rglob("*") if out.exists() else ():
        if path.suffix == ".tif":
            with rasterio.open(path) as src:
                src.read()
        elif path.suffix in (".laz", ".las"):
            laspy.read(path)


@pytest.fixture(scope="module")
def clean(inputs, tmp_path_factory) -> dict:
    """Each case run once, never stopped: its outputs and its wall time."""
    runs = {}
    for case in CASES:
        out = tmp_path_factory.mktemp("clean") / case
        started = time.monotonic()
        done = subprocess.run(GISTOOLS + _args(case, inputs, out) + ["-q"], capture_output=True, text=True)
        assert done.returncode == 0, f"{case}: {done.stderr}"
        runs[case] = (_snapshot(out), time.monotonic() - started)
        print(f"{case}: clean run {runs[case][1]:.1f} s")
    return runs


def _stop_at(args: list[str], after: float, signum) -> tuple[int, str, float]:
    """Run ``args``, send ``signum`` ``after`` seconds in; (exit status, stderr, seconds from the signal to the exit)."""
    proc = subprocess.Popen(GISTOOLS + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(after)
    assert proc.poll() is None, f"the run ended before the signal ({after:.1f} s): {proc.communicate()[1]}"
    proc.send_signal(signum)
    sent = time.monotonic()
    try:
        _, stderr = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError(f"{args[0]} still ran 60 s after the signal") from None
    return proc.returncode, stderr, time.monotonic() - sent


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("moment,signum", [(0.25, signal.SIGINT), (0.6, signal.SIGTERM)])
def test_a_long_command_stops_within_seconds_and_the_rerun_completes(case, moment, signum, inputs, clean, tmp_path):
    expected, seconds = clean[case]
    out = tmp_path / "out"
    code, stderr, took = _stop_at(_args(case, inputs, out) + ["-q"], max(1.0, moment * seconds), signum)
    assert code == 128 + signum and took < LIMIT, (code, took, stderr)
    assert "Traceback" not in stderr and stderr.strip().splitlines()[-1] == INTERRUPTED, stderr
    assert _leftovers(out) == []
    _whole(out)
    again = subprocess.run(GISTOOLS + _args(case, inputs, out) + ["-q"], capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    got = _snapshot(out)
    assert sorted(got) == sorted(expected)
    for name, cells in expected.items():
        np.testing.assert_array_equal(got[name], cells, err_msg=f"{case}: {name}")


def _big_tile(path: Path) -> Path:
    """One 1.6 km tile of 2.6 M points (a point every 1 m), UTM metres: SMRF's grid of 1,600 x 1,600 cells."""
    rng = np.random.default_rng(1)
    n = 1600 * 1600
    x = 500000 + rng.uniform(0, 1600, n)
    y = 4100000 + rng.uniform(0, 1600, n)
    z = 100 + 10 * np.sin(x / 90) + rng.normal(0, 0.05, n)
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales, header.offsets = [0.01] * 3, [500000, 4100000, 0]
    header.add_crs(__import__("pyproj").CRS.from_epsg(32611))
    las = laspy.LasData(header)
    las.x, las.y, las.z = x, y, z
    las.write(path)
    return path


@pytest.mark.parametrize("method,window", [("smrf", "100m"), ("smrftin", "295m")])
def test_a_run_inside_one_long_kernel_call_ends_within_seconds(tmp_path, method, window):
    """The progressive filter with its widest window on a large tile: one kernel call of minutes (a 10-minute run),
    stopped in it. The watchdog ends the run GRACE seconds after the signal: the one line, no lock, no partial file,
    no output."""
    tile = _big_tile(tmp_path / "big.las")
    out = tmp_path / "out"
    args = ["ground", str(tile), "--out", str(out), "--method", method, "--noise", "none", "--jobs", "1", "-q",
            "--window" if method == "smrf" else "--smrftin-window", window]
    if method == "smrf":  # 0.5 m cells: a grid of 3,200 x 3,200 and radii to 200, a kernel call of half a minute
        args += ["--cell", "0.5m"]
    for signum in (signal.SIGTERM, signal.SIGINT):
        code, stderr, took = _stop_at(args, 8.0, signum)
        assert code == 128 + signum and took < LIMIT, (code, took, stderr)
        if method == "smrf":  # 8 s in, SMRF is in the kernel's filter: only the watchdog ends it, GRACE s later
            assert took > GRACE - 0.5, took
        assert "Traceback" not in stderr and stderr.strip().splitlines()[-1] == INTERRUPTED, stderr
        assert _leftovers(out) == [] and not (out / "big.laz").exists()
