"""gistools terrain: slope, aspect, hillshade and TRI equal GDAL's own gdaldem (run here) cell for cell on the
sample's DEM, on a real survey's DEM, and with elevations in another unit than x and y (gdaldem -s); a mosaic read
block by block equals one merged raster."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio

from conftest import AUTZEN, need_shared
from gistools.products.terrain import terrain_from_dem

GDALDEM = shutil.which("gdaldem")
pytestmark = pytest.mark.skipif(GDALDEM is None, reason="GDAL's gdaldem is not installed")

RUNS = {"slope": ["slope"], "slope_percent": ["slope", "-p"], "aspect": ["aspect"], "hillshade": ["hillshade"],
        "tri": ["TRI", "-alg", "Riley"]}


def _read(path):
    with rasterio.open(path) as src:
        return src.read(1).astype(np.float64), src.nodata


def _gdaldem(dem, out, product, scale=None):
    mode, *extra = RUNS[product]
    ref = out / f"gdaldem_{product}.tif"
    scaled = ["-s", repr(scale)] if scale is not None and mode in ("slope", "hillshade") else []
    subprocess.run([GDALDEM, mode, str(dem), str(ref), "-q", *extra, *scaled], check=True)
    return _read(ref)


def assert_equals_gdaldem(dem, out, scale=None):
    """Every product of terrain_from_dem against gdaldem's: the same nodata cells, values within 1e-4 (degrees,
    percent, z units); hillshade, which gdaldem rounds to bytes, within half a grey level."""
    terrain_from_dem(dem, out, overwrite=True)
    for product in RUNS:
        ref, ref_nodata = _gdaldem(dem, out, product, scale)
        ours, nodata = _read(out / f"{product}.tif")
        assert nodata == -9999
        theirs_valid, ours_valid = ref != ref_nodata, ours != nodata
        assert (theirs_valid == ours_valid).all(), product  # the outer ring and cells beside nodata: nodata in both
        assert ours_valid.sum() > 0.3 * ours.size, product
        diff = np.abs(ours - ref)[ours_valid]
        if product == "aspect":
            diff = np.minimum(diff, 360 - diff)
        if product == "hillshade":
            assert diff.max() <= 0.5 + 1e-3, product
            rounded = np.floor(ours[ours_valid] + 0.5) != ref[ours_valid]
            assert rounded.mean() < 1e-3, product  # ties only: gdaldem's approximate square root
        else:
            assert diff.max() <= 1e-4, (product, diff.max())


def test_terrain_equals_gdaldem_on_the_sample_dem(sample_run, tmp_path):
    out, _ = sample_run
    assert_equals_gdaldem(out / "dem.vrt", tmp_path)


def test_terrain_equals_gdaldem_on_a_real_dem(tmp_path):
    need_shared(AUTZEN)
    from gistools import rasters_from_tiles

    rasters_from_tiles([AUTZEN], tmp_path / "autzen")
    assert_equals_gdaldem(tmp_path / "autzen" / "dem.vrt", tmp_path)


def test_elevations_in_metres_on_feet_are_scaled_as_gdaldem_s(sample_run, tmp_path):
    """The sample's DEM (US survey feet) with its elevations in metres, band unit "m": gdaldem -s 0.3048006."""
    out, _ = sample_run
    with rasterio.open(out / "dem.vrt") as src:
        z, profile = src.read(1), src.profile
    metres = np.where(z == src.nodata, src.nodata, z * (1200 / 3937)).astype(np.float32)
    profile.update(driver="GTiff")
    with rasterio.open(tmp_path / "dem_m.tif", "w", **profile) as dst:
        dst.write(metres, 1)
        dst.units = ("m",)
    assert_equals_gdaldem(tmp_path / "dem_m.tif", tmp_path / "t", scale=1200 / 3937)
    rep = terrain_from_dem(tmp_path / "dem_m.tif", tmp_path / "t", products=("slope",), overwrite=True)
    assert rep["units"]["vertical"] == "m" and rep["units"]["horizontal"] == "ftUS"


def test_tiled_equals_untiled(sample_run, tmp_path):
    """The VRT of 4 tiles in 37-cell blocks == one merged GeoTIFF in one block."""
    out, _ = sample_run
    merged = tmp_path / "merged.tif"
    subprocess.run(["gdal_translate", "-q", str(out / "dem.vrt"), str(merged)], check=True)
    terrain_from_dem(out / "dem.vrt", tmp_path / "tiled", block=37)
    terrain_from_dem(merged, tmp_path / "whole", block=0)
    for product in RUNS:
        a, _ = _read(tmp_path / "tiled" / f"{product}.tif")
        b, _ = _read(tmp_path / "whole" / f"{product}.tif")
        assert np.array_equal(a, b), product


def test_a_folder_of_rasters_is_its_dem_and_bad_options_write_nothing(sample_run, tmp_path):
    from gistools.errors import InputError

    out, _ = sample_run
    rep = terrain_from_dem(out, tmp_path / "t", products=("aspect",))
    assert rep["input"].endswith("dem.vrt") and (tmp_path / "t" / "aspect.tif").exists()
    for bad in ({"products": ("curvature",)}, {"azimuth": 400}, {"altitude": -1}):
        with pytest.raises(InputError):
            terrain_from_dem(out, tmp_path / "bad", **bad)
    assert not (tmp_path / "bad").exists()


def test_a_compound_crs_gives_the_vertical_unit(sample_run, tmp_path):
    """EPSG:2882 + NAVD88 height in metres (5703), no unit of our own on the band: z in metres, scaled as -s."""
    from rasterio.crs import CRS

    out, _ = sample_run
    with rasterio.open(out / "dem.vrt") as src:
        z, profile = src.read(1), src.profile
    profile.update(driver="GTiff", crs=CRS.from_user_input("EPSG:2882+5703"))
    with rasterio.open(tmp_path / "compound.tif", "w", **profile) as dst:
        dst.write(np.where(z == src.nodata, src.nodata, z * (1200 / 3937)).astype(np.float32), 1)
    rep = terrain_from_dem(tmp_path / "compound.tif", tmp_path / "t", products=("slope",))
    assert rep["units"]["vertical"] == "m" and rep["units"]["horizontal"] == "ftUS"
    assert abs(rep["units"]["scale"] - 1200 / 3937) < 1e-12
    assert_equals_gdaldem(tmp_path / "compound.tif", tmp_path / "t", scale=1200 / 3937)


def test_the_command_line(sample_run, tmp_path):
    from click.testing import CliRunner

    from gistools.cli.main import cli

    out, _ = sample_run
    ok = CliRunner().invoke(cli, ["terrain", str(out / "dem.vrt"), "--out", str(tmp_path / "t"), "--products",
                                  "slope,hillshade", "-q"])
    assert ok.exit_code == 0, ok.output
    assert sorted(p.name for p in (tmp_path / "t").glob("*.tif")) == ["hillshade.tif", "slope.tif"]
    again = CliRunner().invoke(cli, ["terrain", str(out / "dem.vrt"), "--out", str(tmp_path / "t"), "--products",
                                     "slope", "-q"])
    assert again.exit_code == 0 and "slope kept" in again.output  # made before with these settings
    other = CliRunner().invoke(cli, ["terrain", str(out / "dem.vrt"), "--out", str(tmp_path / "t"), "--products",
                                     "hillshade", "--azimuth", "200", "-q"])
    assert other.exit_code == 1 and "--overwrite" in other.output  # another light: never silently kept
    bad = CliRunner().invoke(cli, ["terrain", str(out / "dem.vrt"), "--out", str(tmp_path / "b"), "--products", "curv"])
    assert bad.exit_code == 2 and "curv" in bad.output and not (tmp_path / "b").exists()
