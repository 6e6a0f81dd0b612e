"""gistools travel block by block (the graph of one block and its halo at a time): the same minutes as Dijkstra over
the whole grid's graph and as skimage.graph.MCP_Geometric, on scenes whose walks leave a block and come back (a
water maze, a river with one ford), with tiny blocks; the command's route under a small memory limit; cancelling
between blocks."""

from __future__ import annotations

import json

import geopandas as gpd
import numpy as np
import pyproj
import pytest
import rasterio
from shapely.geometry import box

from gistools.errors import Cancelled, OutOfMemoryError
from gistools.grid import Grid
from gistools.io.raster import write_raster
from gistools.terrain.travel import HALO
from gistools.products.travel import (BYTES_PER_CELL, CELL_BYTES, TravelSettings, plan_memory, travel_from_dem,
                                      travel_minutes)

RTOL = 1e-9


def _hills(rows, cols, seed=3):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:rows, 0:cols]
    return 12 * np.sin(xx / 8.0) * np.cos(yy / 6.0) + 0.2 * xx + rng.normal(0.0, 0.4, (rows, cols))


def _maze(rows, cols, ford=True):
    """Walls of water across the grid every 6 rows, each with one gap at alternate ends (the walk snakes down,
    back and forth through the same columns of blocks); below them a winding river (4-connected, one cell wide)
    crossed at one ford of two columns; beyond it a pond enclosed by water (the land inside never reached) and a
    patch without heights. Returns (heights, speed factors, the river's cells, the ford's columns)."""
    factor = np.ones((rows, cols))
    for i, r in enumerate(range(6, 37, 6)):
        factor[r, :] = 0.0
        factor[r, slice(cols - 3, cols - 1) if i % 2 == 0 else slice(1, 3)] = 1.0
    river = np.zeros((rows, cols), dtype=bool)
    path = np.rint(42 + 2.0 * np.sin(np.arange(cols) / 4.0)).astype(int)
    for c in range(cols):
        lo, hi = sorted((path[c], path[max(c - 1, 0)]))
        river[lo:hi + 1, c] = True
    crossing = [28, 29]
    if ford:
        river[:, crossing] = False
    factor[river] = 0.0
    factor[46:52, 14:22] = 0.0
    factor[47:51, 15:21] = 1.0  # land inside the pond
    dem = _hills(rows, cols)
    dem[47:50, 40:44] = np.nan
    return dem, factor, river, crossing


def _same(got, ref):
    ok = np.isfinite(ref)
    np.testing.assert_array_equal(np.isfinite(got), ok)  # the unreached cells too (inf)
    np.testing.assert_allclose(got[ok], ref[ok], rtol=RTOL, atol=0)


@pytest.mark.parametrize("neighbours", [16, 8])
def test_a_water_maze_block_by_block_equals_the_whole_grid(neighbours):
    rows, cols = 53, 58  # not a multiple of the 7 x 9 blocks either way
    dem, factor, river, _ford = _maze(rows, cols)
    whole, info = {}, {}
    ref = travel_minutes(dem, 2.0, [(2, 3)], factor=factor, neighbours=neighbours, info=whole)
    got = travel_minutes(dem, 2.0, [(2, 3)], factor=factor, neighbours=neighbours, block=(7, 9), info=info)
    assert whole["method"] == "whole" and info["method"] == "blocks" and info["blocks"] == 8 * 7
    _same(got, ref)
    # the walk leaves blocks and comes back: blocks were solved again after a neighbour lowered their times
    assert info["block_solves"] > info["blocks_reached"]
    assert np.isinf(got[factor == 0]).all() and np.isinf(got[47:51, 15:21]).all()  # water, the pond's inside
    assert np.isinf(got[47:50, 40:44]).all()  # no heights
    below = np.zeros_like(river)
    below[45:] = True
    assert np.isfinite(got[below]).sum() > 300  # beyond the river, through the ford
    # the ford closed: nothing beyond the river is reached, block by block as over the whole grid
    dem, closed, *_ = _maze(rows, cols, ford=False)
    shut = travel_minutes(dem, 2.0, [(2, 3)], factor=closed, neighbours=neighbours, block=(7, 9))
    _same(shut, travel_minutes(dem, 2.0, [(2, 3)], factor=closed, neighbours=neighbours))
    assert np.isinf(shut[below]).all() and np.isfinite(shut[:36]).sum() > 1500


def test_sources_in_several_blocks_roads_and_wading():
    rows, cols = 53, 61
    dem = _hills(rows, cols, seed=11)
    factor = np.random.default_rng(5).choice([1.0, 0.92, 0.83, 0.75], size=(rows, cols))
    fixed = np.full((rows, cols), np.nan)
    factor[:, 30:33] = 0.0
    fixed[:, 30:33] = 1.0  # a river waded at 1 km/h
    fixed[20, :] = 5.0  # a road at 5 km/h, across it (a bridge)
    dem[:, 30:33] = np.nan  # no ground under the water
    sources = [(3, 4), (50, 58), (26, 20), (26, 21)]
    ref = travel_minutes(dem, 1.5, sources, factor=factor, fixed_speed=fixed, z_metres=0.3048)
    for block in [(7, 9), (4, 11), 16, (60, 70)]:
        got = travel_minutes(dem, 1.5, sources, factor=factor, fixed_speed=fixed, z_metres=0.3048, block=block)
        _same(got, ref)
    for r, c in sources:
        assert got[r, c] == 0.0


def test_isotropic_block_by_block_equals_skimage_mcp_geometric():
    from skimage.graph import MCP_Geometric

    rows, cols, cell = 53, 67, 3.0
    dem, factor, *_ = _maze(rows, cols)
    dem = np.nan_to_num(dem)  # MCP has no heights to lose: the patch without heights is left out here
    gy, gx = np.gradient(dem, cell)
    speed = 6.0 * np.exp(-3.5 * np.abs(np.hypot(gx, gy) + 0.05)) * factor  # Tobler, km/h, typed here
    with np.errstate(divide="ignore"):
        cost = np.where(factor > 0, 60.0 / (1000.0 * speed), np.inf)  # minutes per metre
    ref, _ = MCP_Geometric(cost, fully_connected=True, sampling=(cell, cell)).find_costs([(2, 3), (45, 60)])
    info = {}
    got = travel_minutes(dem, cell, [(2, 3), (45, 60)], factor=factor, neighbours=8, isotropic=True, block=(7, 9),
                         info=info)
    assert info["block_solves"] > info["blocks_reached"]
    _same(got, ref)


def test_the_memory_plan():
    shape = (1000, 1200)
    assert plan_memory(shape, 16, 1e9)["method"] == "whole"  # 0.72 GB
    plan = plan_memory(shape, 16, 0.5e9)
    side = plan["block"][0]
    assert plan["method"] == "blocks" and plan["block"] == (side, side)
    # the largest block whose graph with its halo fits beside the cell arrays
    assert CELL_BYTES * 1.2e6 + BYTES_PER_CELL[16] * (side + 2 * HALO) ** 2 <= 0.5e9
    assert CELL_BYTES * 1.2e6 + BYTES_PER_CELL[16] * (side + 1 + 2 * HALO) ** 2 > 0.5e9
    assert plan["bytes"] <= 0.5e9 and plan["graph_bytes"] == 600 * 1.2e6
    with pytest.raises(OutOfMemoryError, match=r"1,000 x 1,200 cells needs about 0\.10 GB .* than the 0\.05 GB"):
        plan_memory(shape, 16, 0.05e9)


def _scene(tmp_path, n=200):
    """A 200 x 200 hillside of 1 m cells with a river across it (one ford) and a pond: 24 MB of whole graph."""
    grid = Grid(rasterio.transform.from_origin(500000.0, 4000000.0 + n, 1.0, 1.0), n, n, pyproj.CRS("EPSG:32610"))
    dem = write_raster(tmp_path / "dem.tif", _hills(n, n) * 2, grid, units="m")
    water = gpd.GeoDataFrame(geometry=[box(500120.0, 3999000.0, 500125.0, 4000140.0),
                                       box(500120.0, 4000150.0, 500125.0, 4001000.0),  # the ford: 10 m of dry land
                                       box(500030.0, 4000030.0, 500060.0, 4000060.0)], crs="EPSG:32610")
    water.to_file(tmp_path / "water.gpkg", layer="WATERBODY", driver="GPKG")
    return dem, f"{tmp_path / 'water.gpkg'}:WATERBODY"


def _read(path):
    with rasterio.open(path) as src:
        return src.read(1), src.profile


def _same_outputs(a, b):
    for name in ("travel_minutes.tif", "isochrone_bands.tif"):
        (x, px), (y, py) = _read(a / name), _read(b / name)
        assert px == py
        np.testing.assert_array_equal(x, y)  # float32 minutes, equal to the cell
    ia, ib = (gpd.read_file(p / "travel.gpkg", layer="isochrones") for p in (a, b))
    np.testing.assert_allclose(ia["area"], ib["area"], rtol=1e-12)
    assert all(g.equals(h) for g, h in zip(ia.geometry, ib.geometry))


def test_a_small_memory_limit_goes_block_by_block_with_the_same_outputs(tmp_path):
    from click.testing import CliRunner

    from gistools.cli.main import cli

    dem, water = _scene(tmp_path)
    seen = ["500010.5,4000180.5", "500190.5,4000020.5"]
    settings = TravelSettings(isochrones=(1, 2, 3))
    whole = travel_from_dem(dem, tmp_path / "whole", seen, settings, waterbodies=water)
    blocks = travel_from_dem(dem, tmp_path / "blocks", seen, TravelSettings(isochrones=(1, 2, 3), max_memory=0.01),
                             waterbodies=water)
    assert whole["solver"] == {"method": "whole", "block": None}
    assert blocks["solver"]["method"] == "blocks" and blocks["solver"]["block"] == [102, 102]  # 2 x 2 blocks
    assert blocks["memory_estimate"] <= 0.01e9 < blocks["graph_bytes_estimate"]
    assert blocks["solver"]["blocks"] == 4 and blocks["solver"]["block_solves"] >= 4
    assert 0.9 < blocks["reached_share"] < 1.0 and blocks["reached_share"] == whole["reached_share"]
    _same_outputs(tmp_path / "whole", tmp_path / "blocks")
    ran = CliRunner().invoke(cli, ["travel", str(tmp_path / "cli"), "--dem", str(dem), "--from", seen[0], "--from",
                                   seen[1], "--waterbodies", water, "--isochrones", "1,2,3", "--max-memory", "0.01",
                                   "-q"])
    assert ran.exit_code == 0, ran.output
    assert json.loads((tmp_path / "cli" / "report.json").read_text())["solver"]["method"] == "blocks"
    _same_outputs(tmp_path / "whole", tmp_path / "cli")


def test_cancel_between_blocks_writes_nothing(tmp_path):
    dem, water = _scene(tmp_path)
    told = []

    def progress(fraction, message=""):
        told.append(message)
        return "solve 3," not in message

    with pytest.raises(Cancelled):
        travel_from_dem(dem, tmp_path / "out", "500010.5,4000180.5", TravelSettings(max_memory=0.01),
                        waterbodies=water, progress=progress)
    solves = [m for m in told if m.startswith("shortest walks by blocks: solve")]
    # a word before each block's solve: the first holds the point last seen, the third was refused
    assert solves[0] == "shortest walks by blocks: solve 1, block 1,1 of 2 x 2, 0 more waiting"
    assert len(solves) == 3 and solves[1].startswith("shortest walks by blocks: solve 2, block ")
    assert not list((tmp_path / "out").glob("*.tif")) and not (tmp_path / "out" / "travel.gpkg").exists()
    assert not (tmp_path / "out" / "report.json").exists()
