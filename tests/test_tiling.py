"""Tiled == untiled: tiles see their neighbours, so a split block gives the unsplit block's mosaic."""

from __future__ import annotations

import laspy
import pyproj
import numpy as np
import pytest

from conftest import read_las_independently, tin_oracle
from gistools import RasterSettings, rasters_from_tiles
from gistools.io.points import read_tile_info, write_tile
from gistools.io.raster import read_raster


def _las_dict(las):
    return {k: np.asarray(getattr(las, k)) for k in
            ("x", "y", "z", "classification", "return_number", "number_of_returns", "intensity")}


def _compare(tiled_out, whole_out):
    for product in ("dsm", "dem", "ndsm"):
        a, ga, _ = read_raster(tiled_out / f"{product}.vrt")
        b, gb, _ = read_raster(whole_out / f"{product}.vrt")
        assert ga.transform == gb.transform and ga.shape == gb.shape, product
        assert np.array_equal(np.isnan(a), np.isnan(b)), f"{product}: nodata differs at {np.sum(np.isnan(a) != np.isnan(b))} cells"
        diff = np.nanmax(np.abs(a - b)) if np.isfinite(a).any() else 0.0
        assert diff <= 0.001 / 0.3048, f"{product}: max abs difference {diff}"


def test_sample_block_tiled_equals_one_file(sample_tiles, sample_run, tmp_path):
    x, y, z, cls, rn, _ = read_las_independently(sample_tiles)
    nr = np.concatenate([np.asarray(laspy.read(p).number_of_returns) for p in sample_tiles])
    crs = read_tile_info(sample_tiles[0]).crs
    whole = tmp_path / "in" / "block.las"
    whole.parent.mkdir()
    write_tile(whole, dict(x=x, y=y, z=z, classification=cls, return_number=rn, number_of_returns=nr),
               crs, version="1.1", point_format=1, offsets=[430000.0, 1810000.0, 0.0])
    rasters_from_tiles([whole], tmp_path / "whole")
    _compare(sample_run[0], tmp_path / "whole")


@pytest.mark.parametrize("cell_size", ["1m", "5ft"])
def test_real_file_split_at_unaligned_edges_equals_unsplit(autzen, tmp_path, cell_size):
    """autzen split into 4 tiles at edges that are not multiples of the cell size."""
    las = laspy.read(autzen)
    pts = _las_dict(las)
    crs = las.header.parse_crs()
    xm = np.quantile(pts["x"], 0.47) + 0.37
    ym = np.quantile(pts["y"], 0.55) + 0.61
    tiles = tmp_path / "tiles"
    for i, mx in enumerate([pts["x"] < xm, pts["x"] >= xm]):
        for j, my in enumerate([pts["y"] < ym, pts["y"] >= ym]):
            m = mx & my
            write_tile(tiles / f"t{i}{j}.las", {k: v[m] for k, v in pts.items()}, crs, version="1.2", point_format=3,
                       offsets=[0.0, 0.0, 0.0])
    s_tiled = rasters_from_tiles([tiles], tmp_path / "tiled", RasterSettings(cell_size=cell_size))
    rasters_from_tiles([autzen], tmp_path / "whole", RasterSettings(cell_size=cell_size))
    assert s_tiled["counts"]["ok"] == 4
    _compare(tmp_path / "tiled", tmp_path / "whole")


def test_parallel_jobs_give_the_same_rasters(sample_tiles, sample_run, tmp_path):
    summary = rasters_from_tiles(sample_tiles, tmp_path, jobs=2)
    assert summary["counts"]["ok"] == 4
    _compare(tmp_path, sample_run[0])


def test_dem_in_strips_equals_dem_in_one_piece(sample_tiles, sample_run, tmp_path):
    """A tile's DEM built in strips of few ground points (bounded memory) equals the one-piece DEM."""
    summary = rasters_from_tiles(sample_tiles, tmp_path, RasterSettings(tin_block_points=9_000))
    assert summary["counts"]["ok"] == 4
    _compare(tmp_path, sample_run[0])


def test_dem_tins_in_small_strips_equal_the_dem_of_one_tin(sample_tiles, sample_run, tmp_path, monkeypatch):
    """The DEM's TINs built on strips of at most 5,000 ground points each (TIN_STRIP_POINTS, within one read
    strip) give the same DEM as one TIN a tile, cell for cell."""
    import gistools.products.rasters as rasters

    monkeypatch.setattr(rasters, "TIN_STRIP_POINTS", 5_000)
    assert max(rasters._strips(np.full(200, 100), 5_000), key=lambda s: s[1] - s[0]) == (0, 50)
    summary = rasters_from_tiles(sample_tiles, tmp_path)
    assert summary["counts"]["ok"] == 4
    for tile in sample_tiles:
        a, _, _ = read_raster(tmp_path / "dem" / f"{tile.stem}.tif")
        b, _, _ = read_raster(sample_run[0] / "dem" / f"{tile.stem}.tif")
        assert np.array_equal(a, b, equal_nan=True), tile.stem


def test_dsm_only_run(sample_tiles, sample_run, tmp_path):
    summary = rasters_from_tiles(sample_tiles, tmp_path, RasterSettings(products=("dsm",)))
    assert sorted(summary["mosaics"]) == ["dsm"] and not (tmp_path / "dem").exists()
    a, _, _ = read_raster(tmp_path / "dsm.vrt")
    b, _, _ = read_raster(sample_run[0] / "dsm.vrt")
    assert np.array_equal(a, b, equal_nan=True)


def test_overlapping_tiles_read_each_other_whole(sample_tiles, tmp_path):
    """Two deliveries of the same area (overlapping tiles): each tile's DEM uses all of the other's ground."""
    laz = sample_tiles[0]
    a = tmp_path / "in" / "a.las"
    b = tmp_path / "in" / "b.las"
    las = laspy.read(laz)
    pts = _las_dict(las)
    crs = las.header.parse_crs()
    even = np.arange(len(pts["x"])) % 2 == 0
    write_tile(a, {k: v[even] for k, v in pts.items()}, crs, version="1.1", point_format=1)
    write_tile(b, {k: v[~even] for k, v in pts.items()}, crs, version="1.1", point_format=1)
    rasters_from_tiles([a, b], tmp_path / "split")
    rasters_from_tiles([laz], tmp_path / "whole")
    for name in ("a", "b"):
        x, _, _ = read_raster(tmp_path / "split" / "dem" / f"{name}.tif")
        w, _, _ = read_raster(tmp_path / "whole" / "dem" / f"{laz.stem}.tif")
        assert x.shape == w.shape
        assert np.array_equal(np.isnan(x), np.isnan(w)) and np.nanmax(np.abs(x - w)) < 1e-3


def test_scratch_holds_a_front_of_tiles_not_the_block(sample_tiles, sample_run, tmp_path):
    """16 tiles of 500 ft read north to south: a tile's scratch is deleted once its neighbours are gridded,
    so at most a few rows of tiles are on disk at once; the mosaic is unchanged."""
    x, y, z, cls, rn, _ = read_las_independently(sample_tiles)
    nr = np.concatenate([np.asarray(laspy.read(p).number_of_returns) for p in sample_tiles])
    crs = read_tile_info(sample_tiles[0]).crs
    tiles = tmp_path / "tiles"
    for i in range(4):
        for j in range(4):
            w, s = 430000.0 + 500 * i, 1810000.0 + 500 * j
            m = (x >= w) & (x < w + 500) & (y >= s) & (y < s + 500)
            write_tile(tiles / f"t{i}{j}.las", dict(x=x[m], y=y[m], z=z[m], classification=cls[m], return_number=rn[m],
                                                    number_of_returns=nr[m]), crs, version="1.1", point_format=1)
    summary = rasters_from_tiles([tiles], tmp_path / "out", jobs=1)  # in parallel each worker reads a tile ahead
    assert summary["counts"]["ok"] == 16
    assert summary["scratch_peak_tiles"] <= 12, summary["scratch_peak_tiles"]  # about 3 rows of 4, not all 16
    _compare(tmp_path / "out", sample_run[0])


def test_tiles_with_different_scales_and_offsets(sample_tiles, sample_run, tmp_path):
    """Neighbours whose LAS integers mean different things (scale 0.001 / 0.01 / 0.0025, shifted offsets): the
    scratch keeps each tile's integers with its own scale and offset, so the block gives the same rasters."""
    tiles = tmp_path / "in"
    layouts = [(0.001, (0.5, 0.25, 3.0)), (0.01, (-1000.0, 2000.0, -50.0)), (0.0025, (0.25, 0.75, 0.5)), (0.01, None)]
    for path, (scale, shift) in zip(sample_tiles, layouts):
        las = laspy.read(path)
        offsets = None if shift is None else [float(las.header.offsets[k]) + shift[k] for k in range(3)]
        write_tile(tiles / f"{path.stem}.las", _las_dict(las), las.header.parse_crs(), version="1.2", point_format=1,
                   scale=scale, offsets=offsets)
        again = laspy.read(tiles / f"{path.stem}.las")
        assert float(again.header.scales[0]) == scale
        assert np.allclose(np.asarray(again.x), np.asarray(las.x), atol=1e-6, rtol=0)  # the same points
    summary = rasters_from_tiles([tiles], tmp_path / "out")
    assert summary["counts"]["ok"] == 4
    dem, grid, _ = read_raster(tmp_path / "out" / "dem.vrt")
    ref, interior, nodata, decided = tin_oracle(grid, sample_tiles, summary["dem_max_distance"])  # from the original tiles
    assert np.array_equal(np.isnan(dem)[decided], nodata[decided])  # nodata by an independent rule
    both = interior & np.isfinite(dem)
    assert both.sum() > 0.8 * grid.width * grid.height
    assert np.max(np.abs(dem[both] - ref[both])) < 0.001 / 0.3048  # 1 mm, in ftUS
    _compare(tmp_path / "out", sample_run[0])


def test_tiles_narrower_than_two_buffers_equal_one_file(sample_tiles, tmp_path):
    """Stripes 150 ft wide with the 98 ft buffer: a tile's points near its west and its east edge overlap, and
    a neighbour still gets every point it needs from the halo strips (tiled == one file)."""
    x, y, z, cls, rn, _ = read_las_independently(sample_tiles)
    nr = np.concatenate([np.asarray(laspy.read(p).number_of_returns) for p in sample_tiles])
    crs = read_tile_info(sample_tiles[0]).crs
    pts = dict(x=x, y=y, z=z, classification=cls, return_number=rn, number_of_returns=nr)
    edges = np.arange(x.min(), x.max() + 150.0, 150.0)
    tiles = tmp_path / "stripes"
    for k in range(len(edges) - 1):
        m = (x >= edges[k]) & (x < edges[k + 1])
        write_tile(tiles / f"s{k:02d}.las", {a: v[m] for a, v in pts.items()}, crs, version="1.2", point_format=1,
                   offsets=[430000.0, 1810000.0, 0.0])
    whole = tmp_path / "in" / "block.las"
    write_tile(whole, pts, crs, version="1.2", point_format=1, offsets=[430000.0, 1810000.0, 0.0])
    summary = rasters_from_tiles([tiles], tmp_path / "tiled")
    assert summary["counts"]["ok"] == len(edges) - 1 >= 8 and summary["buffer"] > 150.0 / 2
    rasters_from_tiles([whole], tmp_path / "whole")
    _compare(tmp_path / "tiled", tmp_path / "whole")


def test_a_strip_read_by_box_holds_exactly_the_strips_points_in_the_box(tmp_path):
    """A neighbour's strip is kept in the order of a grid of its tile and read by the grid cells that reach a box:
    for boxes inside, across and beyond the tile, edges on points' coordinates, every point of the strip in the box
    and no other (laspy reads the tile independently); a strip by a rule holds what the rule keeps."""
    from gistools.engine.buffered import EVERYWHERE, _strip_in_box, _strip_tile

    rng = np.random.default_rng(4)
    n = 20_000
    x, y = rng.uniform(1000, 1500, n), rng.uniform(2000, 2400, n)
    x[:50] = 1500.0  # points on the east edge of the tile
    d = {"x": x, "y": y, "z": rng.uniform(0, 30, n), "classification": np.ones(n, np.uint8),
         "return_number": np.ones(n, np.uint8), "number_of_returns": np.ones(n, np.uint8),
         "intensity": rng.integers(0, 60000, n).astype(np.uint16)}
    path = write_tile(tmp_path / "t.las", d, pyproj.CRS.from_epsg(32617), version="1.2", point_format=1, offsets=[1000.0, 2000.0, 0.0])
    las = laspy.read(path)
    X, Y, I = np.asarray(las.x), np.asarray(las.y), np.asarray(las.intensity)
    strip = _strip_tile("t", str(path), None, 60.0, str(tmp_path))
    iw, is_, ie, in_ = strip["inner"]
    edge = ~((X > iw) & (X < ie) & (Y > is_) & (Y < in_))
    boxes = [EVERYWHERE, (940, 1940, 1560, 2460), (1450, 1900, 1600, 2500), (900, 2350, 1100, 2500), (0, 0, 10, 10),
             (X[7], Y[9], X[7] + 75, Y[9] + 40), (1500.0, 2000, 1500.0, 2400)]
    boxes += [tuple(sorted(rng.uniform(950, 1550, 2))[i] if k % 2 == 0 else sorted(rng.uniform(1950, 2450, 2))[i]
                    for k, i in ((0, 0), (1, 0), (2, 1), (3, 1))) for _ in range(30)]
    for w, s, e, n_ in boxes:
        got = _strip_in_box(strip["strip"], (w, s, e, n_))
        want = edge & (X >= w) & (X <= e) & (Y >= s) & (Y <= n_)
        assert sorted(zip(got["x"], got["y"], got["intensity"])) == sorted(zip(X[want], Y[want], I[want]))
    ruled = _strip_tile("r", str(path), None, 60.0, str(tmp_path), rule=lambda a, b: a < 1100)
    got = _strip_in_box(ruled["strip"], EVERYWHERE)
    assert sorted(got["x"]) == sorted(X[X < 1100])
