"""LAS 1.0-1.4 and LAZ, point formats 0-3 and 6, CRS as GeoTIFF keys or WKT: read, gridded, the same answer."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest
from click.testing import CliRunner

from gistools import rasters_from_tiles
from gistools.cli.main import cli
from gistools.io.points import read_tile_info, write_tile
from gistools.io.raster import read_raster
from gistools.synthetic import make_scene, scene_points

CRS = pyproj.CRS.from_epsg(26917)


@pytest.fixture(scope="module")
def cloud():
    scene = make_scene((500000.0, 4000000.0), (400.0, 400.0), seed=3)
    return scene_points(scene, scene.bounds, spacing=3.0, seed=3)


def _las10(path_11, path_10):
    """LAS 1.0 from a 1.1 file: the same header layout, minor version 0 (laspy writes 1.1 and up)."""
    data = bytearray(path_11.read_bytes())
    data[25] = 0
    path_10.write_bytes(bytes(data))


@pytest.mark.parametrize("version, point_format, suffix", [
    ("1.0", 1, ".las"), ("1.1", 1, ".las"), ("1.2", 0, ".las"), ("1.2", 3, ".laz"), ("1.3", 1, ".las"),
    ("1.4", 6, ".las"), ("1.4", 6, ".laz"),
])
def test_versions_and_formats_give_the_same_rasters(cloud, tmp_path, version, point_format, suffix):
    ref_tile = tmp_path / "ref.las"
    write_tile(ref_tile, cloud, CRS, version="1.2", point_format=1)
    tile = tmp_path / f"t{suffix}"
    if version == "1.0":
        write_tile(tmp_path / "t11.las", cloud, CRS, version="1.1", point_format=point_format)
        _las10(tmp_path / "t11.las", tile)
    else:
        write_tile(tile, cloud, CRS, version=version, point_format=point_format)
    info = read_tile_info(tile)
    assert info.version == version and info.point_format == point_format and info.crs.to_epsg() == 26917
    rasters_from_tiles([ref_tile], tmp_path / "ref")
    rasters_from_tiles([tile], tmp_path / "out")
    for product in ("dsm", "dem", "ndsm"):
        a, ga, _ = read_raster(tmp_path / "ref" / product / "ref.tif")
        b, gb, _ = read_raster(tmp_path / "out" / product / "t.tif")
        assert ga.transform == gb.transform and np.array_equal(a, b, equal_nan=True), product
    r = CliRunner().invoke(cli, ["info", str(tile)])
    assert r.exit_code == 0 and f"LAS {version}, point format {point_format}" in r.output


def test_noise_and_withheld_points_stay_out_of_the_dsm(cloud, tmp_path):
    """Class 7 / 18 (noise) and withheld points (format 6 flag) never reach the DSM by default."""
    import laspy

    write_tile(tmp_path / "clean.las", cloud, CRS, version="1.4", point_format=6)
    n = len(cloud["x"])
    noisy = {k: np.concatenate([v, v[:300]]) for k, v in cloud.items()}
    noisy["z"][n:] += 500.0  # birds and multipath: far above everything
    noisy["classification"][n:n + 100] = 7
    noisy["classification"][n + 100:n + 200] = 18
    noisy["return_number"][n:] = 1
    write_tile(tmp_path / "noisy.las", noisy, CRS, version="1.4", point_format=6)
    las = laspy.read(tmp_path / "noisy.las")
    withheld = np.zeros(len(las.points), bool)
    withheld[n + 200:n + 300] = True  # the last 100 are flagged withheld, class unchanged
    las.withheld = withheld
    las.write(tmp_path / "noisy2.las")
    (tmp_path / "noisy.las").unlink()
    rasters_from_tiles([tmp_path / "clean.las"], tmp_path / "a")
    rasters_from_tiles([tmp_path / "noisy2.las"], tmp_path / "b")
    a, _, _ = read_raster(tmp_path / "a" / "dsm" / "clean.tif")
    b, _, _ = read_raster(tmp_path / "b" / "dsm" / "noisy2.tif")
    assert np.array_equal(a, b, equal_nan=True)
    rasters_from_tiles([tmp_path / "noisy2.las"], tmp_path / "c", settings=__import__("gistools").RasterSettings(
        dsm_classes=tuple(range(0, 32))))
    c, _, _ = read_raster(tmp_path / "c" / "dsm" / "noisy2.tif")
    assert np.nanmax(c) > np.nanmax(a) + 400  # asked for every class: the noise is there (withheld still out)
