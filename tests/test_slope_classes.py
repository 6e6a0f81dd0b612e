"""gistools slope-classes, a command declared whole: the classes equal GDAL's own `gdaldem slope` cut at the same
limits, on a DEM whose slopes run from flat to 58 degrees with holes; reruns keep or refuse as the other DEM
commands; bad limits are refused in one line; the command line and Python give the same raster."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import from_origin

from gistools import slope_classes_from_dem
from gistools.cli.main import cli
from gistools.errors import InputError

BREAKS = (5.0, 15.0, 30.0, 45.0)


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    """400 x 300 cells of 1 m (EPSG:32611, z in metres): z = 0.002 x^2 plus a ripple, slopes 0-58 degrees; a hole."""
    y, x = np.mgrid[0:300, 0:400].astype(np.float64)
    z = (0.002 * x ** 2 + 3 * np.sin(y / 17.0)).astype(np.float32)
    z[100:120, 200:230] = -9999
    path = tmp_path_factory.mktemp("dem") / "dem.tif"
    with rasterio.open(path, "w", driver="GTiff", width=400, height=300, count=1, dtype="float32", crs="EPSG:32611",
                       transform=from_origin(500000, 4100000, 1.0, 1.0), nodata=-9999) as dst:
        dst.write(z, 1)
        dst.update_tags(1, units="m")
    return path


def _gdaldem_classes(dem, tmp_path):
    """GDAL's slope (gdaldem slope, degrees) and its classes at BREAKS (0 where gdaldem gives nodata)."""
    gdaldem = shutil.which("gdaldem")
    if gdaldem is None:
        pytest.skip("gdaldem (GDAL's tools) is not installed here")
    out = tmp_path / "gdal_slope.tif"
    subprocess.run([gdaldem, "slope", str(dem), str(out), "-q"], check=True)
    with rasterio.open(out) as src:
        slope = src.read(1, masked=True)
    classes = np.where(slope.mask, 0, np.digitize(slope.filled(0), BREAKS) + 1)
    return slope, classes


def test_the_classes_are_gdaldems_slope_cut_at_the_limits(dem, tmp_path):
    report = slope_classes_from_dem(dem, tmp_path / "out", breaks=BREAKS)
    with rasterio.open(report["outputs"]["slope_classes"]) as src:
        got = src.read(1)
        assert src.nodata == 0 and src.dtypes[0] == "uint8"
        assert src.colormap(1)[1][:3] != src.colormap(1)[5][:3]  # a colour table: flat and steep differ
    slope, expected = _gdaldem_classes(dem, tmp_path)
    near = np.zeros(got.shape, bool)  # within 1e-4 degrees of a limit: single-precision rounding may tip either way
    for b in BREAKS:
        near |= ~slope.mask & (np.abs(slope.filled(-1) - b) < 1e-4)
    assert near.sum() < 20
    np.testing.assert_array_equal(got[~near], expected[~near])
    counts = np.bincount(got.ravel(), minlength=6)
    assert all(counts[k] > 1000 for k in range(1, 6)), counts  # every class is there
    assert report["classes"] == {"1": "0-5 deg", "2": "5-15 deg", "3": "15-30 deg", "4": "30-45 deg",
                                 "5": ">= 45 deg"}


def test_a_rerun_keeps_the_same_limits_and_refuses_others(dem, tmp_path):
    out = tmp_path / "out"
    slope_classes_from_dem(dem, out, breaks=BREAKS)
    again = slope_classes_from_dem(dem, out, breaks=BREAKS)
    assert again["kept"] == ["slope_classes"]
    with pytest.raises(InputError, match="was made with breaks 5,15,30,45, this run asks 10,20"):
        slope_classes_from_dem(dem, out, breaks=(10, 20))
    assert slope_classes_from_dem(dem, out, breaks=(10, 20), overwrite=True)["kept"] == []


@pytest.mark.parametrize("breaks,words", [((15, 5), "increasing"), ((5, 95), "0 - 90"), ((), "needs 1 to 254"),
                                          (tuple(range(1, 256)), "needs 1 to 254")])
def test_limits_that_cannot_be_classes_are_refused_before_anything_is_written(dem, tmp_path, breaks, words):
    with pytest.raises(InputError, match=words) as err:
        slope_classes_from_dem(dem, tmp_path / "out", breaks=breaks)
    assert "breaks" in str(err.value) and not (tmp_path / "out").exists()


def test_the_command_line_writes_what_python_writes(dem, tmp_path):
    done = CliRunner().invoke(cli, ["slope-classes", str(dem), "--out", str(tmp_path / "cli"), "--breaks",
                                    "5,15,30,45", "-q"])
    assert done.exit_code == 0, done.output
    assert "slope_classes written" in done.output
    bad = CliRunner().invoke(cli, ["slope-classes", str(dem), "--out", str(tmp_path / "bad"), "--breaks", "30,5"])
    assert bad.exit_code == 1 and "--breaks" in bad.output and "Traceback" not in bad.output
    slope_classes_from_dem(dem, tmp_path / "py", breaks=BREAKS)
    with rasterio.open(tmp_path / "cli" / "slope_classes.tif") as a, rasterio.open(
            tmp_path / "py" / "slope_classes.tif") as b:
        np.testing.assert_array_equal(a.read(), b.read())
