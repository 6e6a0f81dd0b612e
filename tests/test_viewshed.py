"""gistools viewshed equals GDAL's own gdal_viewshed (run here) on the sample's DSM, on a real survey's DSM and, with
Earth curvature, on a 30 km metre surface; several observers are counted."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from conftest import AUTZEN, need_shared
from gistools.errors import InputError
from gistools.grid import affine_apply
from gistools.products.viewshed import viewshed_from_surface

GDAL_VIEWSHED = shutil.which("gdal_viewshed")
pytestmark = pytest.mark.skipif(GDAL_VIEWSHED is None, reason="GDAL's gdal_viewshed is not installed")


def _observers(surface, n, seed=1):
    """``n`` positions on cells with data, drawn at random inside ``surface``."""
    rng = np.random.default_rng(seed)
    with rasterio.open(surface) as src:
        z, b = src.read(1, masked=True), src.bounds
        found = []
        while len(found) < n:
            x, y = b.left + rng.random() * (b.right - b.left), b.bottom + rng.random() * (b.top - b.bottom)
            r, c = src.index(x, y)
            if not z.mask[r, c]:
                found.append((x, y))
    return found, ~z.mask


def assert_equals_gdal_viewshed(surface, tmp_path, *, height, height_units, cc=None, n=3):
    """Each observer's visibility against gdal_viewshed's (-vv 1 -iv 0) on the cells with data: the cells that
    differ (sightline-boundary cells where the sampling could differ) are counted and must be < 1 %."""
    points, valid = _observers(surface, n)
    differ = total = 0
    for i, (x, y) in enumerate(points):
        ref = tmp_path / f"gdal_{i}.tif"
        subprocess.run([GDAL_VIEWSHED, "-q", "-ox", repr(x), "-oy", repr(y), "-oz", repr(height), "-tz", "0", "-vv", "1",
                        "-iv", "0", "-cc", repr(cc or 0.0), str(surface), str(ref)], check=True)
        rep = viewshed_from_surface(surface, tmp_path / f"ours_{i}", observers=[(x, y)], observer_height=height_units,
                                    curvature=cc is not None, curvature_coefficient=cc or 0.85714)
        with rasterio.open(ref) as a, rasterio.open(tmp_path / f"ours_{i}" / "viewshed.tif") as b:
            theirs, ours = a.read(1), b.read(1)
        assert set(np.unique(ours[valid])) <= {0, 1} and (ours[~valid] == 255).all()
        assert 0 < (ours[valid] == 1).sum() < valid.sum()
        differ += int(((theirs != ours) & valid).sum())
        total += int(valid.sum())
        assert rep["observers"][0]["cells_seen"] == int((ours == 1).sum())
    assert differ / total < 0.01, (differ, total)
    return differ


def test_viewshed_equals_gdal_viewshed_on_the_sample_dsm(sample_run, tmp_path):
    out, _ = sample_run
    differ = assert_equals_gdal_viewshed(out / "dsm.vrt", tmp_path, height=6.0, height_units="6ft")
    assert differ == 0  # the same sweep, the same order of operations: every cell agrees


def test_viewshed_equals_gdal_viewshed_on_a_real_dsm(tmp_path):
    need_shared(AUTZEN)
    from gistools import rasters_from_tiles

    rasters_from_tiles([AUTZEN], tmp_path / "autzen")
    differ = assert_equals_gdal_viewshed(tmp_path / "autzen" / "dsm.vrt", tmp_path, height=2 / 0.3048,
                                         height_units="2m")
    assert differ == 0


def test_curvature_equals_gdal_viewshed_cc_on_metres(tmp_path):
    """1500 x 1500 cells of 20 m: curvature hides a third of what is seen without it; both as gdal_viewshed."""
    n = 1500
    yy, xx = np.mgrid[0:n, 0:n] / n
    z = (50 + 20 * np.sin(7 * xx) * np.cos(5 * yy) + 5 * np.sin(31 * xx + 17 * yy)).astype(np.float32)
    surface = tmp_path / "hills.tif"
    with rasterio.open(surface, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32", crs="EPSG:32617",
                       transform=from_origin(500000, 4000000, 20, 20), nodata=-9999) as dst:
        dst.write(z, 1)
        dst.units = ("m",)
    assert assert_equals_gdal_viewshed(surface, tmp_path, height=2.0, height_units="2m", cc=0.85714, n=1) == 0
    flat = viewshed_from_surface(surface, tmp_path / "flat", observers=[(514006, 3986988)], observer_height="2m")
    bent = viewshed_from_surface(surface, tmp_path / "bent", observers=[(514006, 3986988)], observer_height="2m",
                                 curvature=True)
    assert bent["cells_seen"] < 0.8 * flat["cells_seen"]


def test_several_observers_are_counted(sample_run, tmp_path):
    out, _ = sample_run
    a, b = (430500.0, 1811500.0), (431500.0, 1810500.0)
    both = viewshed_from_surface(out, tmp_path / "both", observers=f"{a[0]},{a[1]};{b[0]},{b[1]}")
    one = [viewshed_from_surface(out, tmp_path / f"one{i}", observers=[p]) for i, p in enumerate((a, b))]

    def read(path):
        with rasterio.open(path) as src:
            return src.read(1)

    va, vb = (read(tmp_path / f"one{i}" / "viewshed.tif") for i in range(2))
    count, seen = read(tmp_path / "both" / "viewshed_count.tif"), read(tmp_path / "both" / "viewshed.tif")
    data = va != 255
    assert np.array_equal(count[data], (va[data] == 1).astype(int) + (vb[data] == 1))
    assert np.array_equal(seen[data] == 1, count[data] > 0)
    assert both["cells_seen"] == int((count[data] > 0).sum()) and len(both["observers"]) == 2
    assert one[0]["units"]["observer_height"] == 6.0  # the default eye on data in feet: 6 ft


def test_bad_observers_write_nothing(sample_run, tmp_path):
    out, _ = sample_run
    for bad in ({"observers": "1,2"}, {"observers": "x"}, {"observers": None}, {"surface_kind": "chm",
                                                                              "observers": "431000,1811000"}):
        with pytest.raises(InputError):
            viewshed_from_surface(out, tmp_path / "bad", **bad)
    assert not (tmp_path / "bad").exists()


def test_a_point_layer_of_observers_and_the_command_line(sample_run, tmp_path):
    """Observers from a GeoPackage layer equal the same positions given with --from."""
    import geopandas as gpd
    import shapely
    from click.testing import CliRunner

    from gistools.cli.main import cli

    out, _ = sample_run
    points = [(430500.0, 1811500.0), (431500.0, 1810500.0)]
    gpd.GeoDataFrame(geometry=[shapely.Point(p) for p in points], crs="EPSG:2882").to_file(tmp_path / "obs.gpkg",
                                                                                          layer="observers")
    a = CliRunner().invoke(cli, ["viewshed", str(out), "--out", str(tmp_path / "a"), "--observers",
                                 f"{tmp_path / 'obs.gpkg'}:observers", "-q"])
    b = CliRunner().invoke(cli, ["viewshed", str(out), "--out", str(tmp_path / "b"), "--from", "430500,1811500",
                                 "--from", "431500,1810500", "-q"])
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    for name in ("viewshed.tif", "viewshed_count.tif"):
        with rasterio.open(tmp_path / "a" / name) as x, rasterio.open(tmp_path / "b" / name) as y:
            assert np.array_equal(x.read(1), y.read(1))
    bad = CliRunner().invoke(cli, ["viewshed", str(out), "--out", str(tmp_path / "c"), "--from", "0,0"])
    assert bad.exit_code != 0 and "outside" in bad.output and not (tmp_path / "c").exists()


def test_max_distance_equals_gdal_viewshed_md(sample_run, tmp_path):
    """--max-distance 400ft: gdal_viewshed -md 400 writes the observer's window; the output covers the same cells
    (two observers: the union of their windows) and each observer's cells equal gdal_viewshed's."""
    out, _ = sample_run
    points = [(430500.0, 1811500.0), (430800.0, 1811300.0)]
    rep = viewshed_from_surface(out, tmp_path / "ours", observers=points, max_distance="400ft")
    with rasterio.open(tmp_path / "ours" / "viewshed_count.tif") as src:
        count, transform = src.read(1), src.transform
    ours_total = np.zeros(count.shape, int)
    for i, (x, y) in enumerate(points):
        ref = tmp_path / f"gdal_{i}.tif"
        subprocess.run([GDAL_VIEWSHED, "-q", "-ox", repr(x), "-oy", repr(y), "-oz", "6", "-md", "400", "-vv", "1",
                        "-iv", "0", "-ov", "0", "-cc", "0", str(out / "dsm.vrt"), str(ref)], check=True)
        one = viewshed_from_surface(out, tmp_path / f"one_{i}", observers=[(x, y)], max_distance="400ft")
        with rasterio.open(ref) as a, rasterio.open(tmp_path / f"one_{i}" / "viewshed.tif") as b:
            assert a.transform == b.transform and a.shape == b.shape  # the same window of the surface
            theirs, ours = a.read(1), b.read(1)
            valid = ours != 255
            assert np.array_equal(theirs[valid], ours[valid]) and (theirs[valid] == 1).sum() > 100
            c0, r0 = affine_apply(~transform, (b.transform.c, b.transform.f))
            ours_total[round(r0):round(r0) + ours.shape[0], round(c0):round(c0) + ours.shape[1]] += ours == 1
    data = count != 65535
    assert np.array_equal(count[data], ours_total[data]) and rep["extent"]["width"] < 400


def test_cancel_writes_nothing(sample_run, tmp_path):
    from gistools.errors import Cancelled

    out, _ = sample_run
    calls = []

    def progress(fraction, message=""):
        calls.append(message)
        return len(calls) < 3  # cancel during the first observer's sweep

    with pytest.raises(Cancelled):
        viewshed_from_surface(out, tmp_path / "v", observers="431000,1811000;430500,1811500", progress=progress)
    assert calls[0] == "viewshed: observer 1 of 2"
    assert not list((tmp_path / "v").glob("*.tif")) and not (tmp_path / "v" / "report.json").exists()
