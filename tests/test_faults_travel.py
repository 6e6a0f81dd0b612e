"""Faults and bad input of gistools travel and of the travel layers of gistools webmap and mapbook, through the
command line: each case ends right, or refused in one line naming the file or option, the problem and the fix.

Every case asserts the exit code, that no traceback is printed and the one line; where a value is computed it is
checked against an independent computation. The DEMs are small synthetic rasters written with rasterio.
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import Affine
from shapely.geometry import box

from gistools.cli.main import cli

CRS = "EPSG:32610"
N = 40  # cells a side of the synthetic DEMs, 1 m cells
WEST, SOUTH = 500000.0, 4000000.0
START = f"{WEST + 10.5},{SOUTH + 10.5}"  # a cell centre
FLAT_KMH = 6.0 * math.exp(-3.5 * 0.05)  # Tobler (1993) on flat ground, typed here


def _tobler(s: float) -> float:
    return 6.0 * math.exp(-3.5 * abs(s + 0.05))


def invoke(*args) -> tuple[int, str]:
    """The CLI in this process: (exit code, all it printed); an uncaught exception fails the test."""
    result = CliRunner().invoke(cli, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"traceback: {type(result.exception).__name__}: {result.exception}\n{result.output}")
    return result.exit_code, result.output


def refused(args, *needles) -> str:
    """Run ``args``: exit 1, no traceback, one ``gistools: error:`` line holding every needle; returns the line."""
    code, text = invoke(*args)
    assert code == 1, text
    assert "Traceback" not in text, text
    lines = [line for line in text.splitlines() if line.startswith("gistools:")]
    assert len(lines) == 1 and lines[0].startswith("gistools: error: "), text
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def ran(args) -> str:
    code, text = invoke(*args)
    assert code == 0 and "Traceback" not in text and "error" not in text, text
    return text


def write_dem(path: Path, data=None, transform=None, crs=CRS, dtype="float32") -> Path:
    data = np.zeros((N, N)) if data is None else data
    transform = transform or Affine(1.0, 0.0, WEST, 0.0, -1.0, SOUTH + data.shape[0])
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[1], height=data.shape[0], count=1, dtype=dtype,
                       crs=crs, transform=transform, nodata=-9999) as dst:
        dst.write(data.astype(dtype), 1)
        dst.units = ("m",)
    return path


def read(path: Path) -> np.ndarray:
    with rasterio.open(path) as src:
        return src.read(1)


def snapshot(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def same_outputs(a: Path, b: Path) -> None:
    """The two folders hold the same travel outputs: rasters cell for cell, the layers' points and areas."""
    for name in ("travel_minutes.tif", "isochrone_bands.tif"):
        np.testing.assert_array_equal(read(a / name), read(b / name))
    for layer in ("isochrones", "last_seen"):
        x, y = (gpd.read_file(f / "travel.gpkg", layer=layer) for f in (a, b))
        assert len(x) == len(y) and all(g.equals(h) for g, h in zip(x.geometry, y.geometry))


# ------------------------------------------------------------------ 1. rotated and south-up DEMs

def test_a_rotated_dem_is_refused(tmp_path):
    dem = write_dem(tmp_path / "rotated.tif", transform=Affine(1.0, 0.1, WEST, 0.1, -1.0, SOUTH + N))
    refused(["travel", tmp_path / "out", "--dem", dem, "--from", START, "-q"],
            "rotated.tif", "the DEM is rotated", "Warp it north-up first (gdalwarp)")
    assert not (tmp_path / "out").exists()


def test_a_south_up_dem_gives_the_north_up_minutes(tmp_path):
    """A plane rising 10 % northwards, written north-up and south-up (rows south to north, transform.e > 0), with
    a waterbody across its east: the same minutes, north-up, and Tobler's times up and down the plane."""
    rows = np.arange(N)[:, None] * np.ones((1, N))
    north_up = (N - 1 - rows) * 0.1  # row 0 is the north edge: the highest
    north = write_dem(tmp_path / "north.tif", north_up)
    south = write_dem(tmp_path / "south.tif", north_up[::-1], transform=Affine(1.0, 0.0, WEST, 0.0, 1.0, SOUTH))
    gpd.GeoDataFrame(geometry=[box(WEST + 30, SOUTH - 5, WEST + 33, SOUTH + N + 5)], crs=CRS).to_file(
        tmp_path / "water.gpkg", layer="WATER", driver="GPKG")
    start = f"{WEST + 10.5},{SOUTH + 20.5}"  # row 19, column 10
    for name, dem in (("n", north), ("s", south)):
        ran(["travel", tmp_path / name, "--dem", dem, "--from", start, "--waterbodies",
             f"{tmp_path / 'water.gpkg'}:WATER", "-q"])
    np.testing.assert_array_equal(read(tmp_path / "s" / "travel_minutes.tif"),
                                  read(tmp_path / "n" / "travel_minutes.tif"))
    with rasterio.open(tmp_path / "s" / "travel_minutes.tif") as src:
        assert src.transform == Affine(1.0, 0.0, WEST, 0.0, -1.0, SOUTH + N)
        t = src.read(1).astype(float)
    assert t[19 - 15, 10] == pytest.approx(15 / 1000 / _tobler(0.1) * 60, rel=1e-6)  # 15 m north: uphill
    assert t[19 + 15, 10] == pytest.approx(15 / 1000 / _tobler(-0.1) * 60, rel=1e-6)  # 15 m south: downhill
    assert (t[:, 30:33] == -9999).all()  # the water (from the breaklines, on the flipped grid) is not reached
    rep = json.loads((tmp_path / "s" / "report.json").read_text())
    assert rep["speed_model"]["water_cells"] == 3 * N


# ------------------------------------------------------------------ 2. isochrones

@pytest.mark.parametrize("value", ["nan", "inf", "30,inf"])
def test_isochrones_not_finite_are_refused(tmp_path, value):
    dem = write_dem(tmp_path / "dem.tif")
    refused(["travel", tmp_path / "out", "--dem", dem, "--from", START, "--isochrones", value, "-q"],
            "--isochrones", "finite number of minutes", "e.g. --isochrones 30,60,120,240")
    assert not (tmp_path / "out").exists()  # no report.json with Infinity or NaN in it


def test_more_isochrones_than_band_codes_are_refused_and_the_most_fit(tmp_path):
    dem = write_dem(tmp_path / "dem.tif", np.zeros((12, 12)))
    start = f"{WEST + 0.5},{SOUTH + 0.5}"
    # codes 1 ... n within the isochrones and n + 1 beyond the last must stay below the nodata code 255
    most = 255 - 2
    too_many = ",".join(f"{i / 2000:g}" for i in range(1, most + 2))
    refused(["travel", tmp_path / "over", "--dem", dem, "--from", start, "--isochrones", too_many, "-q"],
            "--isochrones", f"{most + 1} isochrones need {most + 2} band codes", "at most 253 isochrones")
    edges = [i / 2000 for i in range(1, most + 1)]  # to 0.1265 min; the far corner is 0.18 min away
    ran(["travel", tmp_path / "ok", "--dem", dem, "--from", start, "--isochrones", ",".join(f"{e:g}" for e in edges),
         "-q"])
    minutes = read(tmp_path / "ok" / "travel_minutes.tif").astype(np.float64)
    bands = read(tmp_path / "ok" / "isochrone_bands.tif")
    expected = np.searchsorted(np.asarray(edges), minutes.astype(np.float32), side="left") + 1
    assert bands.max() == most + 1 and (bands != 255).all()  # some cells beyond the last isochrone, none lost
    np.testing.assert_array_equal(bands[np.abs(minutes[..., None] - edges).min(-1) > 1e-4],
                                  expected[np.abs(minutes[..., None] - edges).min(-1) > 1e-4])


# ------------------------------------------------------------------ 3. --from

@pytest.mark.parametrize("value", ["nan,nan", f"inf,{SOUTH + 10}", f"{WEST + 10},-inf"])
def test_points_last_seen_not_finite_are_refused(tmp_path, value):
    dem = write_dem(tmp_path / "dem.tif")
    refused(["travel", tmp_path / "out", "--dem", dem, "--from", value, "-q"],
            f"--from {value}", "finite numbers", "X,Y in the DEM's CRS")


@pytest.mark.parametrize("value", ["", "1,2,3", " , "])
def test_a_from_that_is_neither_a_point_nor_a_layer_says_what_it_takes(tmp_path, value):
    dem = write_dem(tmp_path / "dem.tif")
    refused(["travel", tmp_path / "out", "--dem", dem, "--from", value, "-q"],
            "--from", "is neither X,Y nor a point layer", "X,Y in the DEM's CRS", "file.gpkg:LAYER")


# ------------------------------------------------------------------ 4. a geographic DEM

def test_a_geographic_dem_is_refused_with_its_utm_zone(tmp_path):
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    dem = write_dem(tmp_path / "lonlat.tif", transform=Affine(1e-4, 0, -122.5, 0, -1e-4, 45.5), crs="EPSG:4326")
    lon, lat = -122.5 + N * 1e-4 / 2, 45.5 - N * 1e-4 / 2
    utm = [c for c in query_utm_crs_info(datum_name="WGS 84", area_of_interest=AreaOfInterest(lon, lat, lon, lat))
           if c.code.startswith("326")][0].code
    line = refused(["travel", tmp_path / "out", "--dem", dem, "--from", f"{lon},{lat}", "-q"],
                   "lonlat.tif", "geographic", f"gdalwarp -t_srs EPSG:{utm}")
    assert "PDAL" not in line and "las2las" not in line and "tiles" not in line


# ------------------------------------------------------------------ 5. memory, before any read

def test_a_dem_too_big_for_any_method_is_refused_before_it_is_read(tmp_path):
    """A 100,000 x 100,000 VRT (no sources: reading it would take long): refused from its size at once."""
    from rasterio.crs import CRS as RCRS

    vrt = tmp_path / "huge.vrt"
    vrt.write_text(f'<VRTDataset rasterXSize="100000" rasterYSize="100000"><SRS>{RCRS.from_string(CRS).to_wkt()}'
                   f'</SRS><GeoTransform>{WEST}, 1, 0, {SOUTH + 100000}, 0, -1</GeoTransform>'
                   '<VRTRasterBand dataType="Float32" band="1"><NoDataValue>-9999</NoDataValue></VRTRasterBand>'
                   '</VRTDataset>')
    gb = 100_000 * 100_000 * 80 / 1e9  # 80 bytes a cell for the cell arrays of the block-wise method
    started = time.time()
    refused(["travel", tmp_path / "out", "--dem", vrt, "--from", START, "-q"],
            "100,000 x 100,000 cells", f"needs about {gb:.2f} GB", "more than the 4.00 GB allowed", "--max-memory")
    assert time.time() - started < 5
    assert not (tmp_path / "out").exists()


def test_a_dem_whose_graph_does_not_fit_goes_block_by_block(tmp_path):
    """Whole graph 200 x 200 x 600 bytes = 24 MB > 10 MB allowed, cell arrays 3.2 MB: solved by blocks, the same
    minutes as the whole grid's."""
    dem = write_dem(tmp_path / "dem.tif", np.random.default_rng(1).uniform(0, 3, (200, 200)))
    start = f"{WEST + 40.5},{SOUTH + 160.5}"
    ran(["travel", tmp_path / "blocks", "--dem", dem, "--from", start, "--max-memory", "0.01", "-q"])
    ran(["travel", tmp_path / "whole", "--dem", dem, "--from", start, "-q"])
    assert json.loads((tmp_path / "blocks" / "report.json").read_text())["solver"]["method"] == "blocks"
    np.testing.assert_allclose(read(tmp_path / "blocks" / "travel_minutes.tif"),
                               read(tmp_path / "whole" / "travel_minutes.tif"), rtol=1e-6)


# ------------------------------------------------------------------ 6. a run killed while it puts its outputs in place

KILLER = """
import os, sys
from pathlib import Path
real = os.replace
def replace(src, dst, *args, **kw):
    real(src, dst, *args, **kw)
    if Path(dst).name == "travel_minutes.tif" and ".gistools-scratch" in str(src) \\
            and ".gistools-scratch" not in str(dst):
        os._exit(9)  # killed just after the new minutes replaced the old ones
os.replace = replace
from gistools.cli.main import main
sys.argv = ["gistools", *sys.argv[1:]]
main()
"""


def test_a_run_killed_after_the_minutes_are_replaced_is_marked_and_redone(tmp_path):
    dem = write_dem(tmp_path / "dem.tif")
    new = f"{WEST + 30.5},{SOUTH + 30.5}"
    ran(["travel", tmp_path / "out", "--dem", dem, "--from", START, "-q"])
    before = snapshot(tmp_path / "out")
    proc = subprocess.run([sys.executable, "-c", KILLER, "travel", str(tmp_path / "out"), "--dem", str(dem),
                           "--from", new, "--overwrite", "-q"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 9, proc.stderr
    after = snapshot(tmp_path / "out")
    assert after["travel_minutes.tif"] != before["travel_minutes.tif"]  # new minutes beside the old bands
    assert after["isochrone_bands.tif"] == before["isochrone_bands.tif"]
    record = json.loads((tmp_path / "out" / "report.json").read_text())
    assert record["made"] == {} and "a rerun makes them again" in record["incomplete"]  # recognisable
    text = ran(["travel", tmp_path / "out", "--dem", dem, "--from", new, "-q"])  # no --overwrite needed
    assert "kept" not in text
    ran(["travel", tmp_path / "clean", "--dem", dem, "--from", new, "-q"])
    same_outputs(tmp_path / "out", tmp_path / "clean")
    record = json.loads((tmp_path / "out" / "report.json").read_text())
    assert "incomplete" not in record and set(record["made"]) == {"minutes", "bands", "polygons"}
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".gistools")]  # scratch, lock: gone


# ------------------------------------------------------------------ 7. reruns: full disk, --resume, other settings

def test_a_rerun_after_a_full_disk_completes_keeps_and_refuses_other_settings(tmp_path, monkeypatch):
    import pyogrio

    dem = write_dem(tmp_path / "dem.tif")
    out = tmp_path / "out"
    real = pyogrio.write_dataframe

    def full(*args, **kw):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pyogrio, "write_dataframe", full)
    refused(["travel", out, "--dem", dem, "--from", START, "-q"],
            "no space left", "complete outputs are kept and a rerun resumes")
    assert not list(out.glob("*.tif"))  # nothing of the set put in place
    monkeypatch.setattr(pyogrio, "write_dataframe", real)
    ran(["travel", out, "--dem", dem, "--from", START, "-q"])  # the rerun resumes: it completes
    ran(["travel", tmp_path / "clean", "--dem", dem, "--from", START, "-q"])
    same_outputs(out, tmp_path / "clean")
    before = {k: v for k, v in snapshot(out).items() if k != "report.json"}
    for extra in ([], ["--resume"]):  # the same settings: kept, exit 0
        text = ran(["travel", out, "--dem", dem, "--from", START, "-q", *extra])
        assert "kept the complete outputs of an earlier run" in text
        assert {k: v for k, v in snapshot(out).items() if k != "report.json"} == before
    record = json.loads((out / "report.json").read_text())
    assert record["kept"] == ["minutes", "bands", "polygons"] and len(record["runs"]) == 3
    # a full disk while an earlier complete set is there: the earlier set is left whole, and kept by a rerun
    monkeypatch.setattr(pyogrio, "write_dataframe", full)
    refused(["travel", out, "--dem", dem, "--from", START, "-q", "--overwrite"], "no space left")
    monkeypatch.setattr(pyogrio, "write_dataframe", real)
    assert {k: v for k, v in snapshot(out).items() if k != "report.json"} == before
    assert "kept the complete outputs" in ran(["travel", out, "--dem", dem, "--from", START, "-q"])
    # other settings: refused naming both values
    other = f"{WEST + 20.5},{SOUTH + 20.5}"
    refused(["travel", out, "--dem", dem, "--from", other, "-q"],
            "travel_minutes.tif was made with --from", f"{START}, this run asks {other}", "--overwrite")
    refused(["travel", out, "--dem", dem, "--from", START, "--isochrones", "1,2", "-q"],
            "made with --isochrones 30,60,120,240, this run asks 1,2")
    ran(["travel", out, "--dem", dem, "--from", other, "-q", "--overwrite"])
    ran(["travel", tmp_path / "clean2", "--dem", dem, "--from", other, "-q"])
    same_outputs(out, tmp_path / "clean2")


def test_a_changed_dem_is_made_again_and_a_foreign_file_is_refused(tmp_path):
    dem = write_dem(tmp_path / "dem.tif")
    out = tmp_path / "out"
    ran(["travel", out, "--dem", dem, "--from", START, "-q"])
    write_dem(dem, np.tile(np.arange(N) * 0.1, (N, 1)))  # the DEM rewritten: a plane
    assert "kept" not in ran(["travel", out, "--dem", dem, "--from", START, "-q"])
    ran(["travel", tmp_path / "clean", "--dem", dem, "--from", START, "-q"])
    same_outputs(out, tmp_path / "clean")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "travel.gpkg").write_bytes(b"a user's own file")
    for extra in ([], ["--overwrite"]):  # never replaced
        refused(["travel", mine, "--dem", dem, "--from", START, "-q", *extra],
                f"{mine / 'travel.gpkg'}: a file gistools did not write is in the way")
    assert (mine / "travel.gpkg").read_bytes() == b"a user's own file"


# ------------------------------------------------------------------ 8. travel layers of webmap and mapbook

@pytest.fixture(scope="module")
def shrub_and_travel(tmp_path_factory):
    """A minimal shrub folder over the synthetic DEM's area (classes, their polygons, the record) and a travel
    folder of that DEM."""
    from gistools.io.raster import write_vrt

    root = tmp_path_factory.mktemp("deliver")
    shrub = root / "shrub"
    shrub.mkdir()
    with rasterio.open(shrub / "classes.tif", "w", driver="GTiff", width=N, height=N, count=1, dtype="uint8",
                       crs=CRS, transform=Affine(1.0, 0.0, WEST, 0.0, -1.0, SOUTH + N), nodata=255) as dst:
        dst.write(np.ones((N, N), np.uint8), 1)
    write_vrt(shrub / "classes.vrt", [shrub / "classes.tif"])
    gpd.GeoDataFrame({"tile": ["t1"], "class_code": [1], "class": ["light"], "area": [1600.0],
                      "area_acres": [1600 / 4046.8564224], "area_ha": [0.16]},
                     geometry=[box(WEST, SOUTH, WEST + N, SOUTH + N)], crs=CRS).to_file(
        shrub / "shrub_classes.gpkg", layer="shrub_classes", driver="GPKG")
    (shrub / "report.json").write_text(json.dumps({"tool": "gistools shrub", "cell_size": 1.0, "horizontal_unit": "m",
                                                   "horizontal_unit_m": 1.0}))
    dem = write_dem(root / "dem.tif")
    ran(["travel", root / "travel", "--dem", dem, "--from", START, "--isochrones", "0.1,0.2", "-q"])
    return shrub, root / "travel"


def _broken(travel: Path, dest: Path, change) -> Path:
    import shutil

    shutil.copytree(travel, dest)
    iso = gpd.read_file(dest / "travel.gpkg", layer="isochrones")
    seen = gpd.read_file(dest / "travel.gpkg", layer="last_seen")
    iso, seen = change(iso, seen)
    (dest / "travel.gpkg").unlink()
    for name, gdf in (("isochrones", iso), ("last_seen", seen)):
        if gdf is not None:
            gdf.to_file(dest / "travel.gpkg", layer=name, driver="GPKG")
    return dest


BROKEN = {
    "no_minutes": (lambda i, s: (i.drop(columns="minutes"), s), "layer isochrones has no minutes column"),
    "text_minutes": (lambda i, s: (i.assign(minutes=["six", "twelve"]), s),
                     "layer isochrones, column minutes: 'six' is not a finite number"),
    "no_last_seen": (lambda i, s: (i, None), "no layer last_seen (its layers: isochrones)"),
    "empty": (lambda i, s: (i.iloc[:0], s), "layer isochrones has no features"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_travel_gpkg_not_as_travel_wrote_it_is_one_line(shrub_and_travel, tmp_path, case):
    shrub, travel = shrub_and_travel
    change, words = BROKEN[case]
    bad = _broken(travel, tmp_path / case, change)
    before = snapshot(shrub)
    for command in ("webmap", "mapbook"):
        refused([command, shrub, "--travel", bad], f"{bad / 'travel.gpkg'}: {words}", "gistools travel")
    assert snapshot(shrub) == before  # refused before anything is written


def test_a_web_map_layer_of_another_area_is_a_warning(shrub_and_travel, tmp_path, caplog):
    shrub, travel = shrub_and_travel
    far = write_dem(tmp_path / "far.tif", transform=Affine(1.0, 0.0, WEST + 90000, 0.0, -1.0, SOUTH + 90000 + N))
    ran(["travel", tmp_path / "far", "--dem", far, "--from", f"{WEST + 90010.5},{SOUTH + 90010.5}", "-q"])
    with caplog.at_level("WARNING"):
        ran(["webmap", shrub, "--travel", travel])
    assert "does not overlap" not in caplog.text  # the same area: no warning
    caplog.clear()
    with caplog.at_level("WARNING"):
        ran(["webmap", shrub, "--travel", tmp_path / "far"])
    lines = [r.getMessage() for r in caplog.records if "does not overlap" in r.getMessage()]
    assert len(lines) == 1 and "\n" not in lines[0]
    assert lines[0].startswith(f"--travel {tmp_path / 'far'}: ") and "drawn off the map" in lines[0]
    runs = json.loads((shrub / "report.json").read_text())["runs"]
    assert runs[-1]["tool"] == "gistools webmap" and runs[-1]["warnings"] == 1
