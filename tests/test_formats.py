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


def test_las14_laz_decodes_only_the_layers_pass_1_uses_with_the_same_rasters(cloud, tmp_path):
    """A LAS 1.4 point format 6 LAZ is compressed in layers: pass 1 decodes X, Y, returns, Z, classification and
    the flags (withheld), not GPS time, intensity, scan angle, user data or point source; the rasters equal those
    of the same points as LAS, withheld points (high above the scene) still left out."""
    import laspy

    from gistools.io.points import iter_chunks

    rng = np.random.default_rng(7)
    write_tile(tmp_path / "src.las", cloud, CRS, version="1.4", point_format=6)
    las = laspy.read(tmp_path / "src.las")
    n = len(las.points)
    las.intensity = rng.integers(0, 60000, n)
    las.gps_time = rng.uniform(1e8, 2e8, n)
    las.scan_angle = rng.integers(-9000, 9000, n)
    las.user_data = rng.integers(0, 255, n)
    las.point_source_id = rng.integers(1, 500, n)
    high = rng.choice(n, 200, replace=False)
    las.Z[high] += 50_000  # 500 m up: in the DSM if their withheld flag were not decoded
    withheld = np.zeros(n, bool)
    withheld[high] = True
    las.withheld = withheld
    las.write(tmp_path / "t.las")
    las.write(tmp_path / "t.laz")
    ref = laspy.read(tmp_path / "t.las")
    chunks = list(iter_chunks(read_tile_info(tmp_path / "t.laz"), 10_000, only_fields=True))
    for name in ("classification", "return_number", "number_of_returns", "withheld"):
        assert np.array_equal(np.concatenate([getattr(c, name) for c in chunks]), np.asarray(getattr(ref, name))), name
    for name in ("X", "Y", "Z"):
        assert np.array_equal(np.concatenate([np.asarray(getattr(c.raw, name)) for c in chunks]), getattr(ref, name))
    # the GPS time layer was skipped: each LAZ chunk repeats its first point's (50,000 points a chunk)
    skipped = np.concatenate([np.asarray(c.raw.gps_time) for c in chunks])
    assert len(np.unique(skipped)) <= n // 50_000 + 1 and len(np.unique(ref.gps_time)) == n
    rasters_from_tiles([tmp_path / "t.las"], tmp_path / "a")
    rasters_from_tiles([tmp_path / "t.laz"], tmp_path / "b")
    for product in ("dsm", "dem", "ndsm"):
        a, _, _ = read_raster(tmp_path / "a" / product / "t.tif")
        b, _, _ = read_raster(tmp_path / "b" / product / "t.tif")
        assert np.array_equal(a, b, equal_nan=True), product
    dsm, _, _ = read_raster(tmp_path / "b" / "dsm" / "t.tif")
    assert np.nanmax(dsm) < np.max(cloud["z"]) + 1  # the withheld points, 500 m up, are out
