"""Faults and bad input across every command: nothing lost, nothing silent.

Every case asserts the exit code, that no traceback is printed, the one line that says what happened, and
that the inputs and the earlier outputs are byte-identical afterwards. Full disks come from a small tmpfs
(RLIMIT_FSIZE when mounting is not allowed), header lies are written with laspy and then patched bytes.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import os
import resource
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from conftest import SAMPLE
from gistools.cli.main import cli
from gistools.engine.resume import tile_report_file
from gistools.io.raster import read_raster

B = SAMPLE / "breaklines.gpkg"
SHRUB_VECTORS = ["--roads", f"{B}:ROADBREAKLINE", "--hydro", f"{B}:HYDROGRAPHICFEATURE", "--waterbodies",
                 f"{B}:WATERBODY", "--wetlands", f"{B}:WETLAND", "--tile-index", f"{B}:FOOTPRINT"]
GISTOOLS = [sys.executable, "-m", "gistools.cli.main"]


# ------------------------------------------------------------------ helpers

def snapshot(folder: Path) -> dict:
    """{relative path: sha256} of every file under ``folder`` (hidden ones included)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def invoke(args) -> tuple[int, str]:
    """The CLI in this process: (exit code, everything it printed); an uncaught exception is a traceback."""
    result = CliRunner().invoke(cli, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"traceback: {type(result.exception).__name__}: {result.exception}\n{result.output}")
    return result.exit_code, result.output


def run(args, timeout=300, **kw) -> subprocess.CompletedProcess:
    """The CLI as a user runs it (its own process): tracebacks and signals are real."""
    return subprocess.run(GISTOOLS + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, **kw)


def one_line(text: str, *needles: str) -> str:
    """The single 'gistools: ...' line of ``text`` (no traceback), holding every needle."""
    assert "Traceback" not in text, text
    lines = [line for line in text.splitlines() if line.startswith("gistools:")]
    assert len(lines) == 1, text
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def no_partial_under_final_names(out: Path) -> None:
    """Every raster under a final name reads whole; no partial file of this program is left."""
    from gistools.io.atomic import is_partial

    for tif in out.rglob("*.tif"):
        read_raster(tif)
    assert not [p for p in out.rglob("*") if is_partial(p)]
    assert not list(out.glob(".gistools-scratch-*"))


@pytest.fixture
def tiles(tmp_path, sample_tiles) -> Path:
    """A copy of the four sample tiles."""
    folder = tmp_path / "tiles"
    folder.mkdir()
    for p in sample_tiles:
        shutil.copy(p, folder / p.name)
    return folder


@pytest.fixture(scope="module")
def shrub_done(tmp_path_factory, sample_tiles) -> Path:
    """A finished shrub chain on the sample tiles (copied by each test that changes it)."""
    out = tmp_path_factory.mktemp("faults") / "out"
    code, text = invoke(["shrub", SAMPLE, "--out", out, "-q", *SHRUB_VECTORS])
    assert code == 0, text
    return out


@pytest.fixture
def shrub_out(shrub_done, tmp_path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(shrub_done, out)
    return out


@contextlib.contextmanager
def small_disk(tmp_path: Path, size: str):
    """A tmpfs of ``size`` (root, mount allowed); None when it cannot be mounted."""
    mnt = tmp_path / f"disk{size}"
    mnt.mkdir()
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], capture_output=True).returncode == 0
    try:
        yield mnt if ok else None
    finally:
        if ok:
            subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def las12(path: Path, n: int = 2000, seed: int = 0, cls=None) -> Path:
    """A small LAS 1.2 tile (EPSG:2882, half ground) written by laspy, for patching its header bytes."""
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([500000.0, 1700000.0, 0.0])
    import pyproj

    header.add_crs(pyproj.CRS(2882))
    las = laspy.LasData(header)
    las.x = 500000 + rng.uniform(0, 500, n)
    las.y = 1700000 + rng.uniform(0, 500, n)
    las.z = rng.uniform(10, 20, n)
    las.classification = np.where(np.arange(n) % 2 == 0, 2, 1).astype(np.uint8) if cls is None else np.full(n, cls, np.uint8)
    las.return_number = np.ones(n, np.uint8)
    las.number_of_returns = np.ones(n, np.uint8)
    las.write(path)
    return path


def patch(path: Path, offset: int, fmt: str, value) -> None:
    data = bytearray(path.read_bytes())
    struct.pack_into(fmt, data, offset, value)
    path.write_bytes(bytes(data))


# LAS 1.2 public header offsets
POINT_COUNT, X_SCALE, X_OFFSET, MAX_X, MIN_X = 107, 131, 155, 179, 187


# ------------------------------------------------------------------ user files are never deleted

def test_user_files_named_partial_are_kept_and_only_own_leftovers_go(tiles, tmp_path):
    out = tmp_path / "project"
    (out / "sub").mkdir(parents=True)
    (out / "dem").mkdir()
    mine = {"notes.partial.txt": b"my notes", "sub/thesis.partial.docx": b"thesis", "dem/x.tif.partial": b"keep",
            ".hidden.partial": b"keep too", "sub/.a.tif.gistools-1-0123abcd.partial": b"not a place gistools writes"}
    for name, data in mine.items():
        (out / name).write_bytes(data)
    # what a killed gistools run leaves: its own partial names and a scratch folder
    (out / "dem" / ".35712.tif.gistools-999-deadbeef.partial").write_bytes(b"left by a killed run")
    (out / ".gistools-scratch-abc123").mkdir()
    (out / ".gistools-scratch-abc123" / "35712.ground.i4").write_bytes(b"x")
    before = snapshot(tiles)
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 0, text
    for name, data in mine.items():
        assert (out / name).read_bytes() == data, name
    assert not (out / "dem" / ".35712.tif.gistools-999-deadbeef.partial").exists()
    assert not (out / ".gistools-scratch-abc123").exists()
    assert snapshot(tiles) == before


# ------------------------------------------------------------------ bad options: refused before anything is touched

@pytest.mark.parametrize("args,needle", [
    (["density", "{out}", "--radius", "0"], "--radius '0' must be a finite length, positive"),
    (["density", "{out}", "--radius", "-5ft"], "--radius '-5ft'"),
    (["classify", "{out}", "--breaks", "0.7,0.3"], "--breaks 0.7,0.3: the values must be finite and increasing"),
    (["classify", "{out}", "--breaks", "0.3"], "--breaks 0.3: needs 2 values, got 1"),
    (["classify", "{out}", "--breaks", "0.3,1.5"], "--breaks 0.3,1.5"),
    (["bands", "{out}", "--band-breaks", "2,1,6"], "--band-breaks 2,1,6"),
    (["bands", "{out}", "--noise-floor", "-1m"], "--noise-floor"),
    (["clip", "{out}", "--max-road-width", "0"], "--max-road-width"),
    (["shrub", "{tiles}", "--out", "{out}", "--radius", "nan"], "--radius"),
    (["rasters", "{tiles}", "--out", "{out}", "--buffer", "-100"], "--buffer '-100' must be a finite length, at least 0"),
    (["rasters", "{tiles}", "--out", "{out}", "--dem-max-distance", "0"], "--dem-max-distance '0'"),
    (["rasters", "{tiles}", "--out", "{out}", "--dem-max-distance", "-1m"], "--dem-max-distance '-1m'"),
    (["rasters", "{tiles}", "--out", "{out}", "--cell-size", "1e400"], "--cell-size '1e400' must be a finite length"),
    (["rasters", "{tiles}", "--out", "{out}", "--cell-size", "0"], "--cell-size '0'"),
    (["rasters", "{tiles}", "--out", "{out}", "--cell-size", "0.001ft"], "grid of"),
    (["rasters", "{tiles}", "--out", "{out}", "--scheduler", "my-cluster"], "is not a Dask scheduler address"),
])
def test_a_bad_option_leaves_the_folder_as_it_was(shrub_out, tiles, args, needle):
    before, before_tiles = snapshot(shrub_out), snapshot(tiles)
    code, text = invoke([a.format(out=shrub_out, tiles=tiles) for a in args])
    assert code == 1, text
    one_line(text, needle)
    assert snapshot(shrub_out) == before
    assert snapshot(tiles) == before_tiles


def test_a_huge_grid_is_refused_with_its_size_before_any_allocation(tiles, tmp_path):
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "o", "--cell-size", "0.001ft", "-q"])
    assert code == 1
    line = one_line(text, "cells", "GB", "--cell-size")
    assert "MemoryError" not in line


@pytest.mark.parametrize("step", ["bands", "density"])
def test_a_step_rerun_that_fails_prints_why_and_leaves_the_folder_as_it_was(shrub_out, step):
    (shrub_out / "ndsm" / "35712.tif").write_bytes(b"damaged")  # the bands step reads it; steps never redo rasters
    (shrub_out / "veg" / "35813.tif").write_bytes(b"damaged")  # the density step reads it, and the clip step rewrites it
    before = snapshot(shrub_out)
    code, text = invoke([step, shrub_out, "-q", *{"bands": ["--bands", "text_literal"], "density": ["--radius", "30ft"]}[step]])
    assert code == 1 and "Traceback" not in text
    if step == "bands":
        assert "FAILED" in text and "35712" in text
        one_line(text, "bands failed on 1 tile(s)", "put back as it was")
    else:  # the damaged veg tile is recomputed (the resume check); the damaged nDSM stops the rerun
        one_line(text, "ndsm/35712.tif", "cannot read the raster")
    assert snapshot(shrub_out) == before


def test_a_damaged_report_is_one_line_for_the_steps_and_the_map(shrub_out):
    (shrub_out / "report.json").write_text("{ not json")
    before = snapshot(shrub_out)
    for args in (["density", shrub_out, "-q"], ["map", shrub_out]):
        code, text = invoke(args)
        assert code == 1
        one_line(text, "report.json is not the report of a gistools run")
    assert snapshot(shrub_out) == before


def test_a_step_rerun_interrupted_leaves_the_folder_as_it_was(shrub_out, monkeypatch):
    import gistools.products.shrub as shrub

    before = snapshot(shrub_out)
    real = shrub._classes_tile

    def interrupted(*args):
        real(*args)
        raise KeyboardInterrupt  # after the first tile's classes were rewritten

    monkeypatch.setattr(shrub, "_classes_tile", interrupted)
    code, text = invoke(["classify", shrub_out, "-q", "--breaks", "0.2,0.6"])
    assert code == 130
    one_line(text, "interrupted")
    assert snapshot(shrub_out) == before


# ------------------------------------------------------------------ full disk, damaged outputs

def _disk_full_case(out: Path, env=None, preexec=None):
    proc = run(["rasters", SAMPLE, "--out", out, "-q"], env=env, preexec_fn=preexec)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    return proc


@pytest.mark.parametrize("size", ["2500k", "8M"])  # full while writing the scratch / while writing the rasters
def test_a_full_disk_stops_the_run_with_one_line_and_no_broken_file(tmp_path, size):
    with small_disk(tmp_path, size) as disk:
        if disk is None:  # no mount allowed: a file size limit gives the same write errors (EFBIG)
            limit = 90_000 if size == "8M" else 30_000
            out = tmp_path / "fsize"

            def preexec():
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

            proc = _disk_full_case(out, preexec=preexec)
            one_line(proc.stderr, "no space left")
        else:
            out = disk / "out"
            proc = _disk_full_case(out)
            line = one_line(proc.stderr, "no space left on", str(disk), "choose another --out")
            assert "FAILED" not in proc.stderr and "35712.las" not in line  # it does not blame a tile
        no_partial_under_final_names(out)
        assert not (out / ".gistools.lock").exists()


def test_resume_after_a_full_disk_completes_the_run(tmp_path):
    with small_disk(tmp_path, "8M") as disk:
        if disk is None:
            pytest.skip("mounting a tmpfs is not allowed here (the RLIMIT case runs above)")
        out = disk / "out"
        _disk_full_case(out)
        kept = {p.name: p.read_bytes() for p in (out / "dem").glob("*.tif")}
        # complete tiles: their reports (a tile whose DEM was written as the disk filled on another tile has none,
        # and is made again, to the same bytes)
        reported = [name for name in (p.stem for p in SAMPLE.iterdir() if p.suffix in (".las", ".laz"))
                    if tile_report_file(out, name).exists()]
        moved = tmp_path / "moved"
        shutil.copytree(out, moved)  # "free some space": go on on a bigger disk
        proc = run(["rasters", SAMPLE, "--out", moved, "-q"])
        assert proc.returncode == 0, proc.stderr
        report = json.loads((moved / "report.json").read_text())
        assert [t["status"] for t in report["tiles"]].count("skipped") == len(reported) > 0
        for name, data in kept.items():
            assert (moved / "dem" / name).read_bytes() == data  # complete tiles were kept
        ref = tmp_path / "ref"
        assert run(["rasters", SAMPLE, "--out", ref, "-q"]).returncode == 0
        for product in ("dsm", "dem", "ndsm"):
            a, _, _ = read_raster(ref / f"{product}.vrt")
            b, _, _ = read_raster(moved / f"{product}.vrt")
            assert np.array_equal(a, b, equal_nan=True), product


def test_a_damaged_finished_tile_is_recomputed_not_a_traceback(tiles, tmp_path):
    out = tmp_path / "out"
    assert invoke(["rasters", tiles, "--out", out, "-q"])[0] == 0
    good = (out / "dem" / "35712.tif").read_bytes()
    (out / "dem" / "35712.tif").write_bytes(good[:4096])  # damaged after the run (a bad copy, a disk fault)
    (out / "dsm" / "35713.tif").write_bytes(b"")
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 0, text
    assert (out / "dem" / "35712.tif").read_bytes() == good
    no_partial_under_final_names(out)
    report = json.loads((out / "report.json").read_text())
    status = {t["name"]: t["status"] for t in report["tiles"]}
    assert status["35712"] == "ok" and status["35713"] == "ok" and status["35812"] == "skipped"


# ------------------------------------------------------------------ output folders that cannot be written

def test_out_under_a_file_is_one_line(tiles, tmp_path):
    (tmp_path / "a_file").write_text("x")
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "a_file" / "out", "-q"])
    assert code == 1
    one_line(text, "under a file", "another --out")
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "a_file", "-q"])
    assert code == 2 and "is a file" in text and "Traceback" not in text  # click's own check of --out
    from gistools.products.rasters import rasters_from_tiles
    from gistools.errors import OutputError

    with pytest.raises(OutputError, match="is a file, not a folder"):  # the library call, and QGIS, get it too
        rasters_from_tiles([tiles], tmp_path / "a_file")
    assert (tmp_path / "a_file").read_text() == "x"


def test_out_on_a_read_only_file_system_is_one_line(tiles, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1M", "tmpfs", str(ro)], capture_output=True).returncode:
        pytest.skip("mounting a read-only tmpfs is not allowed here")
    try:
        proc = run(["rasters", tiles, "--out", ro / "out", "-q"])
        assert proc.returncode == 1
        one_line(proc.stderr, "read-only file system", "another --out")
        proc = run(["structure", tmp_path / "none.txt", "--out", ro / "s"])
        assert proc.returncode == 1 and "Traceback" not in proc.stderr
    finally:
        subprocess.run(["umount", "-l", str(ro)], capture_output=True)


# ------------------------------------------------------------------ header lies and silent wrong answers

@pytest.mark.parametrize("lie,needle", [
    ("count_low", "the header counts 1,000 points but the file holds 2,000 point records"),
    ("bounds_small", "points lie outside the header's bounds"),
    ("scale_zero", "scale factors"),
    ("scale_nan", "scale factors"),
    ("offset_nan", "offsets"),
    ("max_x_huge", "beyond any map"),
    ("bounds_nan", "bounds"),
    ("no_ground", "no ground (class 2) points"),
])
def test_a_lying_header_is_refused_never_ok(tmp_path, lie, needle):
    tile = las12(tmp_path / "t.las", cls=1 if lie == "no_ground" else None)
    if lie == "count_low":
        patch(tile, POINT_COUNT, "<I", 1000)
    elif lie == "bounds_small":
        patch(tile, MAX_X, "<d", 500250.0)
    elif lie == "scale_zero":
        patch(tile, X_SCALE, "<d", 0.0)
    elif lie == "scale_nan":
        patch(tile, X_SCALE, "<d", float("nan"))
    elif lie == "offset_nan":
        patch(tile, X_OFFSET, "<d", float("nan"))
    elif lie == "max_x_huge":
        patch(tile, MAX_X, "<d", 1e300)
    elif lie == "bounds_nan":
        patch(tile, MIN_X, "<d", float("nan"))
    before = tile.read_bytes()
    code, text = invoke(["rasters", tile, "--out", tmp_path / "out", "-q"])
    assert code == 1, text
    assert "tiles ok" not in text or "0 tiles ok" in text
    assert "RuntimeWarning" not in text and "Traceback" not in text
    assert needle in text and "t.las" in text
    assert tile.read_bytes() == before
    if (tmp_path / "out" / "report.json").exists():
        report = json.loads((tmp_path / "out" / "report.json").read_text())
        assert report["tiles"][0]["status"] == "failed" and needle in report["tiles"][0]["error"]


def test_bounds_rounded_by_a_writer_are_a_warning(tmp_path):
    """A point a hundredth beyond a header bound that lies on a cell edge: left out with a warning, not a failure."""
    tile = las12(tmp_path / "r.las")
    las = laspy.read(tile)
    x = np.asarray(las.x)
    x[0] = 499999.99
    las.x = x
    las.write(tile)
    patch(tile, MIN_X, "<d", 500000.0)
    code, text = invoke(["rasters", tile, "--out", tmp_path / "out", "-q"])
    assert code == 0, text
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    t = report["tiles"][0]
    assert t["status"] == "ok" and t["points_outside_header_bounds"] == 1
    assert "outside the header's bounds (rounded bounds)" in t["warnings"][0]


def test_a_lake_tile_without_ground_is_a_warning_not_silent(tmp_path):
    lake = las12(tmp_path / "lake.las", cls=9)
    code, text = invoke(["rasters", lake, "--out", tmp_path / "out", "-q"])
    assert "Traceback" not in text
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    tile = report["tiles"][0]
    assert tile["status"] == "ok" and tile["warnings"] and "no ground (class 2) points" in tile["warnings"][0]


def test_a_geographic_crs_names_the_file(tmp_path):
    tile = las12(tmp_path / "geo.las")
    code, text = invoke(["rasters", tile, "--out", tmp_path / "out", "-q", "--crs", "EPSG:4326"])
    assert code == 1 and "Traceback" not in text
    failed = [line for line in text.splitlines() if "FAILED" in line]
    assert len(failed) == 1 and "geo.las" in failed[0] and "geographic" in failed[0] and "Reproject" in failed[0]


# ------------------------------------------------------------------ vector layers of the wrong kind, invalid polygons

def test_a_point_or_polygon_layer_as_roads_is_refused(tmp_path):
    import geopandas as gpd
    import shapely

    pts = gpd.GeoDataFrame({"n": [1, 2]}, geometry=shapely.points([[0, 0], [1, 1]]), crs=2882)
    pts.to_file(tmp_path / "p.gpkg", layer="P")
    code, text = invoke(["shrub", SAMPLE, "--out", tmp_path / "out", "-q", "--roads", f"{tmp_path / 'p.gpkg'}:P"])
    assert code == 1
    one_line(text, "--roads must hold lines", "Point", "p.gpkg")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").rglob("*.tif"))
    code, text = invoke(["shrub", SAMPLE, "--out", tmp_path / "out2", "-q", "--roads", f"{B}:FOOTPRINT"])
    assert code == 1  # the tile index given as roads: every road vanished before
    one_line(text, "--roads must hold lines", "Polygon", "Polygons to Lines")


def test_a_self_intersecting_waterbody_is_repaired_with_a_warning(tmp_path, caplog):
    import geopandas as gpd
    import shapely

    wb = gpd.read_file(B, layer="WATERBODY")
    x0, y0, x1, y1 = wb.total_bounds
    bowtie = shapely.Polygon([(x0, y0), (x1, y1), (x1, y0), (x0, y1)])  # crosses itself
    bad = gpd.GeoDataFrame(geometry=list(wb.geometry) + [bowtie], crs=wb.crs)
    bad.to_file(tmp_path / "wb.gpkg", layer="WB")
    from gistools.io.vector import read_layer

    with caplog.at_level("WARNING"):
        fixed = read_layer(f"{tmp_path / 'wb.gpkg'}:WB", ("polygon",), "--waterbodies")
    assert fixed.geometry.is_valid.all() and "not valid" in caplog.text and "--waterbodies feature" in caplog.text
    args = ["shrub", SAMPLE, "--out", tmp_path / "out", "-q", "--no-map", "--waterbodies", f"{tmp_path / 'wb.gpkg'}:WB"]
    code, text = invoke(args)
    assert code == 0, text


# ------------------------------------------------------------------ tables: BOMs and degenerate content

def test_bom_csvs_keep_their_first_column(tmp_path):
    from gistools.runway.synthetic import synthetic_runway
    from gistools.structure.fixtures import building

    pts, _ = synthetic_runway(8)
    pts.to_csv(tmp_path / "plain.csv", index=False)
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "plain.csv").read_bytes())
    reports = []
    for name in ("plain", "bom"):
        code, text = invoke(["runway", tmp_path / f"{name}.csv", "--code", "4E", "--crs", "EPSG:3003",
                             "--out", tmp_path / f"r_{name}", "-q"])
        assert code == 0, text
        reports.append(json.loads((tmp_path / f"r_{name}" / "report.json").read_text()))
    assert reports[0]["removed"] == reports[1]["removed"] and reports[0]["cut"] == reports[1]["cut"]
    assert reports[1]["removed"]["duplicates"] == 1  # a reused id is found: the ids were read, not row numbers
    b, _ = building("F4")
    text = "\n".join(f"{i} {x} {y} {z}" for i, x, y, z in b.itertuples(index=False))
    (tmp_path / "s.txt").write_text(text)
    (tmp_path / "s_bom.txt").write_bytes(b"\xef\xbb\xbf" + text.encode())
    from gistools.products.structure import read_points

    assert len(read_points(tmp_path / "s_bom.txt")) == len(read_points(tmp_path / "s.txt")) == len(b)


def _runway_frame():
    from gistools.runway.synthetic import synthetic_runway

    return synthetic_runway(8)[0]


def _aquifer_frame():
    from gistools.aquifer.synthetic import synthetic_aquifer

    return synthetic_aquifer(2012)[0]


@pytest.mark.parametrize("case,needle", [
    ("runway_empty", "not a readable CSV table"),
    ("runway_header_only", "0 centre-line light(s)"),
    ("runway_identical", "distinct position"),
    ("runway_ground_on_axis", "the ground points (type 2) lie on one line"),
    ("aquifer_header_only", "the table holds no contacts"),
    ("aquifer_collinear_layer", "the points do not span an area"),
    ("structure_identical", "do not span an area in plan"),
    ("structure_collinear", "do not span an area in plan"),
    ("structure_nan", "is not a finite number"),
    ("structure_inf", "is not a finite number"),
    ("structure_scales_zero", "--scales 0.0,0.0,0.0: three finite, non-zero factors"),
    ("structure_height_interval_zero", "--height-interval 0"),
])
def test_degenerate_tables_are_one_line(tmp_path, case, needle):
    src = tmp_path / "in.csv"
    if case.startswith("runway"):
        df = _runway_frame()
        if case == "runway_empty":
            src.write_text("")
        elif case == "runway_header_only":
            src.write_text(",".join(df.columns) + "\n")
        else:
            if case == "runway_identical":
                df[["x", "y", "z"]] = df[["x", "y", "z"]].iloc[0].to_numpy()
            else:  # every ground point moved onto the line of the lights
                lights = df[df["type"] == 1]
                k = np.flatnonzero(df["type"] == 2)
                t = np.linspace(0, 1, len(k))
                a, b = lights[["x", "y"]].to_numpy()[[0, -1]]
                df.loc[k, "x"], df.loc[k, "y"] = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            df.to_csv(src, index=False)
        args = ["runway", src, "--code", "4E", "--crs", "EPSG:3003", "--out", tmp_path / "o", "-q"]
    elif case.startswith("aquifer"):
        df = _aquifer_frame()
        if case == "aquifer_header_only":
            src.write_text(",".join(df.columns) + "\n")
        else:
            k = df["layer"] == "AQ"  # the layer's contacts on one line across the area
            x0, y0 = df.loc[k, "x"].mean(), df.loc[k, "y"].mean()
            df.loc[k, "y"] = y0 + (df.loc[k, "x"] - x0) * 0.5
            df.to_csv(src, index=False)
        args = ["aquifer", "model", src, "--layers", "LS,AU,AD,AQ", "--crs", "EPSG:3003", "--out", tmp_path / "o", "-q",
                "--no-figures"]
    else:
        from gistools.structure.fixtures import building

        src = tmp_path / "in.txt"
        rows = list(building("F4")[0].itertuples(index=False))
        extra = []
        if case == "structure_identical":
            rows = [(i, 1.0, 1.0, 1.0) for i in range(60)]
        elif case == "structure_collinear":
            rows = [(i, float(i), float(i), float(i % 5)) for i in range(60)]
        elif case in ("structure_nan", "structure_inf"):
            rows = rows + [(99999, float("nan") if case.endswith("nan") else float("inf"), 1.0, 1.0)]
        src.write_text("\n".join(f"{i} {x} {y} {z}" for i, x, y, z in rows))
        extra = {"structure_scales_zero": ["--scales", "0,0,0"],
                 "structure_height_interval_zero": ["--height-interval", "0"]}.get(case, [])
        args = ["structure", src, "--out", tmp_path / "o", "-q", *extra]
    before = src.read_bytes()
    started = time.time()
    code, text = invoke(args)
    assert code == 1, text
    one_line(text, needle)
    assert time.time() - started < 60  # refused, not computed for minutes
    assert src.read_bytes() == before
    assert not (tmp_path / "o" / "report.json").exists()


# ------------------------------------------------------------------ two runs into one --out

def _wait_for(predicate, timeout=60.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return False


def test_a_second_run_into_the_same_out_is_refused_and_the_first_completes(tiles, tmp_path, shrub_done):
    out = tmp_path / "out"
    # the first run is the whole chain, in small chunks, so that it is still going when the second one starts
    first = subprocess.Popen(GISTOOLS + ["shrub", str(tiles), "--out", str(out), "-q", "--chunk-size", "50",
                                         *SHRUB_VECTORS], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert _wait_for(lambda: (out / ".gistools.lock").exists())
    second = run(["rasters", tiles, "--out", out, "-q", "--overwrite"])
    assert first.poll() is None, "the first run ended before the second one asked for the folder"
    assert second.returncode == 1
    one_line(second.stderr, "is in use by another gistools run", f"process {first.pid}", "another --out")
    stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    assert not (out / ".gistools.lock").exists()
    for product in ("dsm", "dem", "ndsm", "classes"):  # the first run's outputs are those of a run on its own
        a, _, _ = read_raster(shrub_done / f"{product}.vrt")
        b, _, _ = read_raster(out / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product


def test_a_stale_lock_is_taken_over(tiles, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / ".gistools.lock").write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname(), "start": "1"}))
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 0, text
    assert not (out / ".gistools.lock").exists()


def test_the_lock_check_without_proc_tells_a_live_process_from_a_dead_one(monkeypatch):
    """Where there is no /proc (macOS, the BSDs) the pid alone decides: a running process holds its lock, an exited
    one's lock is stale; and the check never signals the process (Windows has its own branch: os.kill(pid, 0)
    would end the process there)."""
    from gistools.io import outdir

    monkeypatch.setattr(outdir, "_process_start", lambda pid: None)
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    try:
        assert outdir._alive(live.pid, "12345") and not outdir._alive(dead.pid, "12345")
        assert live.poll() is None  # asked, not signalled
    finally:
        live.kill()
        live.wait()


# ------------------------------------------------------------------ Ctrl-C at several moments, kill -9 of the parent

def _interrupt_when(args, ready, out: Path, signum=signal.SIGINT):
    proc = subprocess.Popen(GISTOOLS + [str(a) for a in args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    reached = _wait_for(lambda: ready(out) or proc.poll() is not None, 120)
    assert reached and proc.poll() is None, "the run ended before the moment of the interrupt"
    proc.send_signal(signum)
    stdout, stderr = proc.communicate(timeout=120)
    return proc.returncode, stdout + stderr


MOMENTS = {
    "reading": lambda out: bool(list(out.glob(".gistools-scratch-*/*.i4"))),
    "gridding": lambda out: (out / "dem").is_dir() and bool(list((out / "dem").glob("*.tif"))),
    "steps": lambda out: (out / "bands").is_dir() and bool(list((out / "bands").glob("*.tif"))),
    "map": lambda out: (out / "classes.vrt").exists(),
}


@pytest.mark.parametrize("moment,jobs,signum", [("reading", 1, signal.SIGINT), ("gridding", 2, signal.SIGINT),
                                                ("gridding", "auto", signal.SIGINT),
                                                ("steps", 1, signal.SIGINT), ("map", 1, signal.SIGINT),
                                                ("gridding", 2, signal.SIGTERM), ("steps", 1, signal.SIGTERM),
                                                ("reading", 2, signal.SIGHUP)])
def test_ctrl_c_ends_with_130_and_one_line_and_the_rerun_resumes(tiles, tmp_path, moment, jobs, signum, shrub_done):
    """Ctrl-C, and what a scheduler, `timeout` or a closed terminal sends (SIGTERM, SIGHUP), clean up alike:
    exit 128 + the signal, one line, no lock, scratch or partial file, and the rerun completes the run."""
    out = tmp_path / "out"
    args = ["shrub", tiles, "--out", out, "-q", "--jobs", jobs, "--chunk-size", "2000", *SHRUB_VECTORS]
    before = snapshot(tiles)
    code, text = _interrupt_when(args, MOMENTS[moment], out, signum)
    assert code == 128 + signum, text
    one_line(text, "interrupted")
    assert "Exception ignored" not in text
    no_partial_under_final_names(out)
    assert not (out / ".gistools.lock").exists()
    again = run(args)
    assert again.returncode == 0, again.stderr
    for product in ("dem", "classes"):
        a, _, _ = read_raster(shrub_done / f"{product}.vrt")
        b, _, _ = read_raster(out / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product
    assert snapshot(tiles) == before


def _children(pid: int) -> list[int]:
    kids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[1]) == pid:
                kids.append(int(stat.parent.name))
    return kids


def test_workers_die_with_a_killed_parent(tiles, tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen(GISTOOLS + ["rasters", str(tiles), "--out", str(out), "-q", "--jobs", "2",
                                        "--chunk-size", "2000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert _wait_for(lambda: len([k for k in _children(proc.pid)]) >= 2 and MOMENTS["reading"](out), 120)
    workers = _children(proc.pid)
    proc.kill()
    proc.wait()

    def gone():
        return all(not Path(f"/proc/{w}").exists() or "Z" in Path(f"/proc/{w}/stat").read_text().rsplit(")", 1)[1][:3]
                   for w in workers)

    assert _wait_for(gone, 10), f"workers {workers} outlived their parent"
    again = run(["rasters", tiles, "--out", out, "-q"])  # the stale lock and the leftovers are handled
    assert again.returncode == 0, again.stderr
    no_partial_under_final_names(out)


@pytest.mark.parametrize("command", ["rasters", "ground", "normalize"])
def test_a_neighbour_warning_reaches_the_console_and_the_record_in_every_command(command, tiles, tmp_path):
    """The same path for every tile command: a neighbour that does not read is a warning on the console (stderr,
    as it happens) and in report.json (the tile's line and the record's warnings, named by tile)."""
    good = (tiles / "35813.laz").read_bytes()
    (tiles / "35813.laz").write_bytes(good[: int(len(good) * 0.6)])  # the header reads, the points do not
    proc = run([command, tiles, "--out", tmp_path / "out", "-q"])
    assert proc.returncode == 1 and "Traceback" not in proc.stderr  # the broken tile failed; the others were made
    record = json.loads((tmp_path / "out" / "report.json").read_text())
    for name in ("35712", "35713", "35812"):
        line = next(t for t in record["tiles"] if t["name"] == name)
        assert any("35813" in w and "could not be read" in w for w in line["warnings"]), (name, line["warnings"])
        assert any(w.startswith(f"{name}: ") and "35813" in w for w in record["warnings"]), record["warnings"]
        assert re.search(rf"{name}\.la[sz]: .*35813.* could not be read", proc.stderr), proc.stderr[-2000:]
    assert "laspy" not in proc.stderr  # the reader's own log lines of the broken file: gistools says it once


def test_a_tile_made_without_a_neighbour_is_recomputed_once_the_neighbour_reads(tiles, tmp_path):
    """A neighbour whose points fail to decode leaves the tiles beside it without its points near the edge: they are
    reported with a warning, and a rerun after the neighbour is repaired recomputes them (they were kept before)."""
    out = tmp_path / "out"
    good = (tiles / "35813.laz").read_bytes()
    (tiles / "35813.laz").write_bytes(good[: int(len(good) * 0.6)])  # the header reads, the points do not
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 1
    report = json.loads((out / "report.json").read_text())
    warned = {t["name"] for t in report["tiles"] if any("35813 could not be read" in w for w in t["warnings"])}
    assert warned == {"35712", "35713", "35812"}
    (tiles / "35813.laz").write_bytes(good)  # repaired
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 0, text
    report = json.loads((out / "report.json").read_text())
    assert all(t["status"] == "ok" for t in report["tiles"])  # recomputed, none kept with a stale edge
    ref = tmp_path / "ref"
    assert invoke(["rasters", tiles, "--out", ref, "-q"])[0] == 0
    for product in ("dsm", "dem", "ndsm"):
        a, _, _ = read_raster(ref / f"{product}.vrt")
        b, _, _ = read_raster(out / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product


def test_an_interrupt_that_a_library_turned_into_another_error_stops_the_run(tiles, tmp_path, monkeypatch):
    """numpy was seen turning a Ctrl-C inside tofile() into a TypeError; the run must stop, not go on with the
    tile marked failed (its neighbours were then kept without its points)."""
    import gistools.products.rasters as rasters
    from gistools.progress import _INTERRUPT

    real = rasters._scan_tile

    def scan(info, run, *rest):
        if info.name == "35712":
            _INTERRUPT.set()  # what the CLI's SIGINT handler records
            raise TypeError("expected str, bytes or os.PathLike object, not BufferedWriter")
        return real(info, run, *rest)

    monkeypatch.setattr(rasters, "_scan_tile", scan)
    try:
        with pytest.raises(KeyboardInterrupt):
            rasters.rasters_from_tiles([tiles], tmp_path / "out")
    finally:
        _INTERRUPT.clear()
    assert not list((tmp_path / "out").glob("tile_reports/*.json"))


def _blas_threads() -> int:
    from threadpoolctl import threadpool_info

    return max([p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"] or [0])


def test_workers_run_one_blas_thread_and_the_parent_environment_is_untouched(monkeypatch):
    """The pool's initializer limits BLAS in each worker (threadpoolctl); the parent's os.environ is not edited."""
    from gistools.engine.batch import WORKER_THREAD_ENV, ProcessPool

    for k in WORKER_THREAD_ENV:
        monkeypatch.delenv(k, raising=False)
    before = dict(os.environ)
    pool = ProcessPool(1)
    try:
        assert pool.submit(_blas_threads).result(timeout=120) in (0, 1)  # 0: numpy without a threaded BLAS
    finally:
        pool.close()
    assert dict(os.environ) == before
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")  # the user's choice is theirs
    pool = ProcessPool(1)
    try:
        assert pool.submit(_blas_threads).result(timeout=120) in (0, 2)
    finally:
        pool.close()


def test_the_command_line_gives_its_workers_one_blas_thread_unless_the_user_chose(monkeypatch):
    """The command line (not the library: QGIS's threads read the environment) sets WORKER_THREAD_ENV to 1 for the
    workers it spawns; a variable the user set keeps every one of them as it is."""
    from gistools.engine.batch import WORKER_THREAD_ENV, worker_thread_environment

    for k in WORKER_THREAD_ENV:
        monkeypatch.delenv(k, raising=False)
    worker_thread_environment()
    assert all(os.environ[k] == "1" for k in WORKER_THREAD_ENV)
    for k in WORKER_THREAD_ENV:
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "4")
    worker_thread_environment()
    assert os.environ["MKL_NUM_THREADS"] == "4" and not any(k in os.environ for k in WORKER_THREAD_ENV if k != "MKL_NUM_THREADS")


def _rayon_threads():
    from gistools.io.raster import compression_threads

    return os.environ.get("RAYON_NUM_THREADS"), compression_threads()


def test_workers_decode_laz_and_compress_geotiffs_on_one_thread_unless_the_user_chose(monkeypatch):
    """lazrs's rayon pool (RAYON_NUM_THREADS, read when the pool starts) and GDAL's GeoTIFF compression
    (GDAL_NUM_THREADS): one thread in each worker, every core in a run without workers, the parent's environment
    untouched, and a value the user set is kept."""
    from gistools.engine.batch import ProcessPool, worker_timed

    monkeypatch.delenv("RAYON_NUM_THREADS", raising=False)
    monkeypatch.delenv("GDAL_NUM_THREADS", raising=False)
    assert _rayon_threads() == (None, "ALL_CPUS")
    before = dict(os.environ)
    pool = ProcessPool(1)
    try:
        assert pool.submit(worker_timed, _rayon_threads, ()).result(timeout=120)[0] == ("1", None)
    finally:
        pool.close()
    assert dict(os.environ) == before
    monkeypatch.setenv("RAYON_NUM_THREADS", "2")
    monkeypatch.setenv("GDAL_NUM_THREADS", "2")
    pool = ProcessPool(1)
    try:
        assert pool.submit(worker_timed, _rayon_threads, ()).result(timeout=120)[0] == ("2", "2")
    finally:
        pool.close()


def test_a_geotiff_compressed_on_every_core_has_the_bytes_of_one_thread(tmp_path, monkeypatch):
    """write_raster on GDAL's compression threads writes the file one thread writes, byte for byte (GDAL keeps
    the blocks' order), and GDAL reads the values back."""
    from gistools.grid import Grid
    from gistools.io.raster import write_raster
    from rasterio.transform import from_origin

    rng = np.random.default_rng(5)
    z = np.cumsum(rng.normal(0, 1, (700, 900)), axis=1)
    z[100:140, 200:260] = np.nan
    grid = Grid(from_origin(500000.0, 4000000.0, 1.0, 1.0), 900, 700, None)
    monkeypatch.delenv("GDAL_NUM_THREADS", raising=False)
    write_raster(tmp_path / "threads.tif", z, grid)
    monkeypatch.setenv("GDAL_NUM_THREADS", "1")
    write_raster(tmp_path / "one.tif", z, grid)
    assert (tmp_path / "threads.tif").read_bytes() == (tmp_path / "one.tif").read_bytes()
    with rasterio.open(tmp_path / "threads.tif") as src:
        back = src.read(1, masked=True)
    assert np.array_equal(back.mask, np.isnan(z)) and np.array_equal(back.filled(np.nan), z.astype(np.float32), equal_nan=True)


@pytest.mark.parametrize("how", ["script without a main guard", "standard input"])
def test_jobs_2_works_from_a_plain_script_and_from_stdin(tmp_path, how):
    """spawn would re-run such a script in every worker (or cannot re-read stdin): the workers are forked instead,
    with a warning, and every tile is made."""
    script = tmp_path / "plain.py"
    script.write_text("from gistools.products.rasters import rasters_from_tiles\n"
                      f"r = rasters_from_tiles({str(SAMPLE)!r}, {str(tmp_path / 'out')!r}, jobs=2)\n"
                      "print('COUNTS', r['counts'])\n")
    if how == "standard input":
        proc = subprocess.run([sys.executable, "-"], stdin=script.open(), capture_output=True, text=True, cwd=tmp_path,
                              timeout=300)
    else:
        proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "COUNTS {'ok': 4, 'failed': 0, 'skipped': 0}" in proc.stdout
    assert "forked" in proc.stderr and "Traceback" not in proc.stderr


def test_a_library_call_whose_every_tile_failed_raises_with_the_report(tmp_path):
    from gistools.errors import TilesFailed
    from gistools.products.rasters import rasters_from_tiles

    bad = tmp_path / "tiles"
    bad.mkdir()
    (bad / "a.las").write_bytes(b"not a LAS file at all" * 10)
    with pytest.raises(TilesFailed, match="every tile failed") as info:
        rasters_from_tiles(bad, tmp_path / "out")
    assert info.value.report["counts"]["failed"] == 1 and "a.las" in info.value.report["tiles"][0]["error"]
    assert json.loads((tmp_path / "out" / "report.json").read_text())["counts"]["failed"] == 1
    code, text = invoke(["rasters", bad, "--out", tmp_path / "out2", "-q"])  # the CLI prints it and exits 1
    assert code == 1 and "FAILED" in text and "Traceback" not in text


# ------------------------------------------------------------------ the record never replaces a user's file

@pytest.mark.parametrize("command", [["rasters", "-q"], ["ground", "-q"], ["metrics", "-q"], ["chm", "-q"],
                                     ["fuels", "-q"], ["normalize", "-q"], ["points"], ["shrub", "-q", *SHRUB_VECTORS]])
def test_a_report_json_gistools_did_not_write_is_kept_and_the_run_refused(tiles, tmp_path, command):
    out = tmp_path / "out"
    out.mkdir()
    mine = out / "report.json"
    mine.write_text('{"project": "my own notes", "budget": 1200}\n')
    (out / "notes.txt").write_text("field notes\n")
    before, inputs = snapshot(out), snapshot(tiles)
    code, text = invoke([command[0], tiles, "--out", out, *command[1:]])
    assert code == 1, text
    one_line(text, "report.json gistools did not write is in the way", "another output folder")
    assert snapshot(out) == before and snapshot(tiles) == inputs


# ------------------------------------------------------------------ text tables parsers would misread silently

@pytest.mark.parametrize("case,needle", [
    ("nul", "holds a NUL byte"),
    ("latin1", "is not UTF-8 text (byte 0xe9"),
    ("huge_field", "is longer than 1 MB"),
])
@pytest.mark.parametrize("tool", ["runway", "aquifer"])
def test_a_text_table_a_parser_would_misread_is_one_line(tmp_path, case, needle, tool):
    """A NUL byte (the C parser cut the value at it: one light became an outlier), an ANSI / Latin-1 export, a
    1 GB field (96 s, 7 GB, then a message of a billion characters): refused before parsing, in one short line."""
    src = tmp_path / "in.csv"
    df = _runway_frame() if tool == "runway" else _aquifer_frame()
    text = df.to_csv(index=False)
    lines = text.splitlines(keepends=True)
    if case == "nul":
        row = lines[5].split(",")
        row[2] = row[2][:3] + "\0" + row[2][3:]
        lines[5] = ",".join(row)
        data = "".join(lines).encode()
    elif case == "latin1":
        data = "".join(lines).encode("latin-1")[:-1] + " caf\u00e9\n".encode("latin-1")  # a remark in Latin-1
    else:
        data = "".join(lines).encode() + b"1," + b"9" * 2_000_000 + b"\n"
    src.write_bytes(data)
    args = (["runway", src, "--code", "4E", "--crs", "EPSG:3003", "--out", tmp_path / "o", "-q"] if tool == "runway"
            else ["aquifer", "model", src, "--layers", "LS,AU,AD,AQ", "--crs", "EPSG:3003", "--out", tmp_path / "o",
                  "-q", "--no-figures"])
    code, text = invoke(args)
    assert code == 1, text
    line = one_line(text, needle, str(src))
    assert len(line) < 400
    assert src.read_bytes() == data
    assert not (tmp_path / "o" / "report.json").exists()


def test_a_breakline_layer_without_features_is_a_warning_not_a_traceback(tiles, tmp_path, caplog):
    import geopandas as gpd

    empty = tmp_path / "empty.gpkg"
    roads = gpd.read_file(B, layer="ROADBREAKLINE").iloc[:0]
    roads.to_file(empty, layer="ROADS", driver="GPKG")
    out = tmp_path / "out"
    code, text = invoke(["shrub", tiles, "--out", out, "-q", "--roads", f"{empty}:ROADS", "--no-map"])
    assert code == 0, text
    assert "has no features" in caplog.text


def test_layers_are_addressed_as_in_qgis_and_with_colons_in_their_names(tmp_path):
    import geopandas as gpd

    from gistools.io.vector import read_layer, split_layer_spec

    assert split_layer_spec(r"C:\data\b.gpkg") == (Path(r"C:\data\b.gpkg"), None)
    assert split_layer_spec(r"C:\data\b.gpkg:ROADS") == (Path(r"C:\data\b.gpkg"), "ROADS")
    assert split_layer_spec("b.gpkg:ROADS:2020") == (Path("b.gpkg"), "ROADS:2020")
    assert split_layer_spec("b.gpkg|layername=ROADS:2020") == (Path("b.gpkg"), "ROADS:2020")
    gpkg = tmp_path / "b.gpkg"
    roads = gpd.read_file(B, layer="ROADBREAKLINE")
    roads.to_file(gpkg, layer="ROADS:2020", driver="GPKG")
    for spec in (f"{gpkg}:ROADS:2020", f"{gpkg}|layername=ROADS:2020"):
        assert len(read_layer(spec, ("line",), "--roads")) == len(roads)


# ------------------------------------------------------------------ odd but legal values, broken links, hostile VPCs

def test_a_dangling_tile_link_is_named_not_dropped(tiles, tmp_path):
    (tiles / "gone.las").symlink_to(tmp_path / "unmounted" / "gone.las")  # a tile on a disk that is not mounted
    before = snapshot(tiles)
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "out", "-q"])
    assert code == 1, text
    one_line(text, "gone.las: a link to a tile that is not there", "Mount the disk")
    assert snapshot(tiles) == before and not (tmp_path / "out").exists()
    (tiles / "gone.las").unlink()
    (tiles / "loop.las").symlink_to(tiles / "loop.las")  # a link to itself
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "out", "-q"])
    assert code == 1, text
    one_line(text, "loop.las: a link to a tile that is not there")


@pytest.mark.parametrize("doc,needle", [
    ({"type": "FeatureCollection", "features": ["a.las", "b.las"]}, "an item is a str, not an object"),
    ({"type": "FeatureCollection", "features": {"a": 1}}, "its features are a dict, not a list"),
    ({"type": "FeatureCollection", "features": [{"properties": {"proj:epsg": 999999},
                                                 "assets": {"data": {"href": "./a.las"}}}]}, "not a known EPSG code"),
    ({"type": "FeatureCollection", "features": [{"properties": {},
                                                 "assets": {"data": {"href": "https://example.com/a.laz"}}}]},
     "read by area"),
    ("[" * 200_000 + "]" * 200_000, "nested too deep"),
])
def test_a_vpc_that_is_not_one_is_one_line(tmp_path, doc, needle):
    vpc = tmp_path / "tiles.vpc"
    vpc.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    code, text = invoke(["rasters", vpc, "--out", tmp_path / "out", "-q"])
    assert code == 1, text
    one_line(text, needle, str(vpc))
    assert not (tmp_path / "out").exists()


def test_odd_output_folders_are_one_line_or_work(tiles, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code, text = invoke(["rasters", tiles, "--out", "", "-q"])  # an unset variable: never the current folder
    assert code in (1, 2), text
    assert "Traceback" not in text and snapshot(tmp_path) == before
    out = tmp_path / "locked"
    (out / ".gistools.lock").mkdir(parents=True)  # someone's folder of the lock's name
    code, text = invoke(["rasters", tiles, "--out", out, "-q"])
    assert code == 1, text
    one_line(text, ".gistools.lock is a folder")
    dollars = tmp_path / "cost_$5_$10"  # matplotlib would read $5_$ as math in the map's title
    code, text = invoke(["shrub", tiles, "--out", dollars, "-q", *SHRUB_VECTORS])
    assert code == 0, text
    assert (dollars / "shrub_map.png").exists()


@pytest.mark.parametrize("address,needle", [("inproc://x", "an in-process address cannot reach workers"),
                                            ("ucx://127.0.0.1:9", "cannot connect to a Dask scheduler there")])
def test_scheduler_addresses_dask_cannot_use_are_one_line(tiles, tmp_path, address, needle):
    code, text = invoke(["rasters", tiles, "--out", tmp_path / "out", "-q", "--scheduler", address])
    assert code == 1, text
    one_line(text, needle)


def test_a_legal_long_tile_name_is_made(tmp_path):
    name = "t" * 240  # 244 characters with .las: legal; the hidden partial name must still fit in 255 bytes
    (tmp_path / "tiles").mkdir()
    las12(tmp_path / "tiles" / f"{name}.las")
    code, text = invoke(["rasters", tmp_path / "tiles", "--out", tmp_path / "out", "-q", "--cell-size", "10ft"])
    assert code == 0, text
    assert (tmp_path / "out" / "dem" / f"{name}.tif").exists()


def test_ground_whose_every_tile_fails_is_one_line_per_tile_not_a_traceback(tmp_path, sample_tiles):
    """--out the folder of the LAZ tiles themselves: every output would overwrite its input, so every tile fails,
    each with its line, and the run exits 1 (it was AttributeError: 'NoneType' object has no attribute 'buffer')."""
    folder = tmp_path / "tiles"
    folder.mkdir()
    laz = [p for p in sample_tiles if p.suffix == ".laz"]
    for p in laz:
        shutil.copy(p, folder / p.name)
    before = snapshot(folder)
    code, text = invoke(["ground", folder, "--out", folder, "-q"])
    assert code == 1, text
    assert "Traceback" not in text and "the output would overwrite this input" in text
    assert {k: v for k, v in snapshot(folder).items() if k.endswith(".laz")} == before


def test_degenerate_tiles_are_refused_not_gridded_empty(tmp_path):
    """A tile whose ground points are one point (or many at one spot) gave an empty DEM with "ok"; a tile without
    first returns an empty DSM; coordinates in degrees read with a CRS in feet a 1 x 1 grid without a word."""
    one = las12(tmp_path / "one" / "t.las", n=2000, cls=1) if (tmp_path / "one").mkdir() is None else None
    las = laspy.read(one)
    las.classification[:] = 1
    las.classification[0] = 2  # one ground point
    las.write(one)
    code, text = invoke(["rasters", one, "--out", tmp_path / "o1", "-q"])
    assert code == 1, text
    assert "ground (class 2) points span no area" in text and "--dem-method max" in text
    las.return_number[:] = 2  # no first return
    las.number_of_returns[:] = 2
    las.classification[:] = 2
    las.write(one)
    code, text = invoke(["rasters", one, "--out", tmp_path / "o2", "-q"])
    assert code == 1, text
    assert "no first return of the DSM's classes" in text and "--dsm-classes" in text


def test_coordinates_outside_the_crs_area_of_use_are_a_warning(tmp_path, caplog):
    h = laspy.LasHeader(point_format=1, version="1.2")
    h.scales, h.offsets = np.array([1e-7, 1e-7, 0.01]), np.array([-82.0, 28.0, 0.0])
    las = laspy.LasData(h)
    rng = np.random.default_rng(1)
    las.x, las.y = -82.5 + rng.uniform(0, 0.01, 500), 28.1 + rng.uniform(0, 0.01, 500)  # degrees
    las.z = rng.uniform(0, 10, 500)
    las.classification = np.full(500, 2, np.uint8)
    (tmp_path / "in").mkdir()
    las.write(tmp_path / "in" / "deg.las")
    las.x = las.x + 0.01
    las.write(tmp_path / "in" / "deg2.las")
    code, text = invoke(["rasters", tmp_path / "in", "--crs", "EPSG:2882", "--out", tmp_path / "o", "-q",
                         "--dem-method", "max"])
    assert caplog.text.count("lies far outside the area of use of its CRS EPSG:2882") == 1  # once, not per tile
    assert "and 1 more tiles alike, each named in report.json" in caplog.text
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert all(any("area of use" in w for w in t["warnings"]) for t in report["tiles"]) and len(report["tiles"]) == 2
    text = (tmp_path / "o" / "report.json").read_text()
    assert "\ue000" not in text and "\\ue000" not in text  # no parameter mark left unrendered in the record


# ------------------------------------------------------------------ commands sharing a folder

@pytest.mark.parametrize("command", [["metrics", "-q"], ["ground", "-q"], ["chm", "-q"], ["fuels", "-q"],
                                     ["normalize", "-q"], ["points"]])
def test_another_command_into_a_chains_folder_changes_no_byte(shrub_out, tiles, command):
    """gistools metrics into a chain's folder rewrote its density/ and report.json, after which the chain's steps
    refused the folder as damaged: now every other command is refused in one line naming the folder's owner."""
    before = snapshot(shrub_out)
    code, text = invoke([command[0], tiles, "--out", shrub_out, *command[1:]])
    assert code == 1, text
    one_line(text, "this folder holds the outputs of gistools", f"gistools {command[0]} would rewrite them")
    assert snapshot(shrub_out) == before


def test_the_chains_own_rasters_rerun_into_its_folder_change_no_product(shrub_out, tiles):
    before = {k: v for k, v in snapshot(shrub_out).items() if k != "report.json" and not k.startswith("tile_reports")}
    code, text = invoke(["rasters", SAMPLE, "--out", shrub_out, "-q"])
    assert code == 0, text
    after = {k: v for k, v in snapshot(shrub_out).items() if k != "report.json" and not k.startswith("tile_reports")}
    assert after == before
    runs = json.loads((shrub_out / "report.json").read_text())["runs"]
    assert [r["tool"] for r in runs][-2:] == ["gistools shrub", "gistools rasters"]


def test_a_rerun_of_a_batch_command_keeps_the_folders_runs(tiles, tmp_path):
    out = tmp_path / "out"
    for _ in range(2):
        code, text = invoke(["metrics", tiles, "--out", out, "-q"])
        assert code == 0, text
    runs = json.loads((out / "report.json").read_text())["runs"]
    assert [r["tool"] for r in runs] == ["gistools metrics", "gistools metrics"]


def test_the_deliverables_lock_the_folder_add_their_run_and_clear_a_killed_runs_partial(shrub_out):
    """webmap, scene and mapbook take the folder's lock (a kill -9 of mapbook left a partial file its rerun never
    removed: now the claim removes this program's leftovers first) and add their line to the record's runs."""
    from gistools.io.atomic import partial_name

    leftover = partial_name(shrub_out / "map_book.pdf", keep_suffix=True)
    leftover.write_bytes(b"%PDF-1.4 cut short")
    for command in (["webmap"], ["scene"], ["mapbook"]):
        code, text = invoke([*command, shrub_out])
        assert code == 0, text
    assert not leftover.exists() and (shrub_out / "map_book.pdf").exists()
    assert not (shrub_out / ".gistools.lock").exists()
    runs = [r["tool"] for r in json.loads((shrub_out / "report.json").read_text())["runs"]]
    assert runs[-3:] == ["gistools webmap", "gistools scene", "gistools mapbook"]
    from gistools.errors import InputError
    from gistools.deliver.webmap import web_map

    with pytest.raises(InputError, match="no such folder"):  # from Python: refused, no folder made
        web_map(shrub_out.parent / "nowhere")
    assert not (shrub_out.parent / "nowhere").exists()


def test_a_tile_whose_every_point_is_withheld_says_so(tmp_path):
    (tmp_path / "t").mkdir()
    tile = las12(tmp_path / "t" / "w.las")
    las = laspy.read(tile)
    las.withheld = np.ones(len(las.points), bool)
    las.write(tile)
    code, text = invoke(["rasters", tile, "--out", tmp_path / "o", "-q"])
    assert code == 1, text
    assert "all 2,000 points carry the withheld flag" in text and "no ground" not in text


def test_a_laz_file_named_las_is_read_as_laz(tmp_path, sample_tiles):
    """It was refused as "truncated ... re-copy the tile", a harmful hint: laspy and PDAL read it by its header."""
    laz = next(p for p in sample_tiles if p.suffix == ".laz")
    (tmp_path / "t").mkdir()
    named = tmp_path / "t" / f"{laz.stem}.las"
    shutil.copy(laz, named)
    code, text = invoke(["rasters", named, "--out", tmp_path / "o", "-q"])
    assert code == 0, text
    a, _, _ = read_raster(tmp_path / "o" / "dem" / f"{laz.stem}.tif")
    code, text = invoke(["rasters", laz, "--out", tmp_path / "o2", "-q"])
    b, _, _ = read_raster(tmp_path / "o2" / "dem" / f"{laz.stem}.tif")
    assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("case", ["zero_padding", "internal_waveform"])
def test_valid_files_are_not_refused_as_header_lies(tmp_path, case):
    """4 KB of zeros after the points, and a LAS 1.3 file whose waveform packets follow its points (global encoding
    bit 1), were refused as headers that count too few points, with the hint lasinfo -repair, which would corrupt
    them; PDAL and laspy read both."""
    (tmp_path / "t").mkdir()
    tile = tmp_path / "t" / "t.las"
    if case == "zero_padding":
        las12(tile)
        with open(tile, "ab") as f:
            f.write(b"\0" * 4096)
    else:
        rng = np.random.default_rng(3)
        header = laspy.LasHeader(point_format=4, version="1.3")
        header.scales, header.offsets = np.array([0.01, 0.01, 0.01]), np.array([500000.0, 1700000.0, 0.0])
        import pyproj

        header.add_crs(pyproj.CRS(2882))
        las = laspy.LasData(header)
        las.x, las.y = 500000 + rng.uniform(0, 500, 2000), 1700000 + rng.uniform(0, 500, 2000)
        las.z = rng.uniform(10, 20, 2000)
        las.classification = np.where(np.arange(2000) % 2 == 0, 2, 1).astype(np.uint8)
        las.return_number, las.number_of_returns = np.ones(2000, np.uint8), np.ones(2000, np.uint8)
        las.write(tile)
        size = tile.stat().st_size
        with open(tile, "ab") as f:
            f.write(bytes(rng.integers(1, 255, 3000, dtype=np.uint8)))  # the waveform packets
        patch(tile, 6, "<H", 2)  # global encoding: waveform data packets internal
        patch(tile, 227, "<Q", size)  # start of the waveform data packet record
    code, text = invoke(["rasters", tile, "--out", tmp_path / "o", "-q", "--cell-size", "10ft"])
    assert code == 0, text
    assert "lasinfo -repair" not in text


@pytest.mark.parametrize("command", ["ground", "normalize"])
def test_copc_inputs_are_written_as_laz(tmp_path, command):
    """ground / normalize on *.copc.laz failed every tile with NotImplementedError: Writing COPC is not supported
    (laspy keeps the COPC records of what it reads, and cannot write them): now a plain LAZ of every point."""
    from conftest import SHARED_DATA, need_shared

    copc = SHARED_DATA / "lidar" / "lasr" / "example.copc.laz"
    need_shared(copc)
    code, text = invoke([command, copc, "--out", tmp_path / "o", "-q"])
    assert code == 0, text
    written = tmp_path / "o" / "example.laz"
    with laspy.open(written) as got, laspy.open(copc) as src:
        assert got.header.point_count == src.header.point_count
        assert not any(v.user_id == "copc" for v in got.header.vlrs)


@pytest.mark.parametrize("edit", ["missing_key", "text_for_a_number", "bad_setting"])
def test_a_damaged_record_is_one_line_for_a_step_rerun(shrub_out, edit):
    """A report.json missing a key or holding "abc" as a number gave KeyError / ValueError; a bad recorded value
    was reported as an option the user never gave (--radius {'a': 1})."""
    record = json.loads((shrub_out / "report.json").read_text())
    if edit == "missing_key":
        del record["horizontal_unit_m"]
    elif edit == "text_for_a_number":
        record["cell_size"] = "abc"
    else:
        record["settings"]["radius"] = {"a": 1}
    (shrub_out / "report.json").write_text(json.dumps(record))
    before = snapshot(shrub_out)
    code, text = invoke(["density", shrub_out, "--density-bands", "1,2"])
    assert code == 1, text
    line = one_line(text, "report.json")
    assert "damaged or edited" in line and "--radius" not in line
    assert snapshot(shrub_out) == before


def test_a_pool_closed_with_tasks_pending_ends_without_a_traceback_from_its_thread():
    """Closing a process pool on an interrupt with tasks still queued (not yet sent to a worker): the workers are
    killed and the pool's own thread marks the pending futures failed; no future is cancelled from this thread
    meanwhile, which stops that thread with InvalidStateError on Python 3.11 (a traceback under the run's line)."""
    import threading
    import time

    from gistools.engine.batch import ProcessPool

    raised = []
    before = threading.excepthook
    threading.excepthook = lambda args: raised.append(args.exc_value)
    try:
        pool = ProcessPool(1)
        futures = [pool.submit(time.sleep, 30) for _ in range(8)]  # one running, one queued, six pending
        deadline = time.monotonic() + 60
        while not futures[0].running() and time.monotonic() < deadline:
            time.sleep(0.05)
        pool.close(futures)
        pool.join()
    finally:
        threading.excepthook = before
    assert raised == []
    assert all(f.done() for f in futures)
