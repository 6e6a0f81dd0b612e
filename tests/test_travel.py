"""gistools travel: a walker's minutes from the points last seen, against analytic cases (flat ground, a plane, a
strip of shrub, a river) and an independent cost-distance tool (skimage.graph.MCP_Geometric)."""

from __future__ import annotations

import json
import math

import geopandas as gpd
import numpy as np
import pyproj
import pytest
import rasterio
from shapely.geometry import Point, box

from conftest import SAMPLE
from gistools.errors import InputError, OutOfMemoryError
from gistools.grid import Grid
from gistools.io.raster import write_raster
from gistools.products.travel import NEIGHBOUR_BOUND, TravelSettings, travel_from_dem, travel_minutes

FLAT_KMH = 6.0 * math.exp(-3.5 * 0.05)  # Tobler on flat ground, typed here from Tobler (1993)
M_PER_MIN = FLAT_KMH * 1000.0 / 60.0


def _tobler(s):
    return 6.0 * np.exp(-3.5 * np.abs(s + 0.05))


@pytest.mark.parametrize("neighbours", [16, 8])
def test_flat_open_ground_gives_circles_within_the_stated_bound(neighbours):
    n, cell = 241, 2.0
    t = travel_minutes(np.zeros((n, n)), cell, [(120, 120)], neighbours=neighbours)
    rr, cc = np.mgrid[0:n, 0:n]
    exact = np.hypot(rr - 120, cc - 120) * cell / M_PER_MIN
    bound = NEIGHBOUR_BOUND[neighbours]
    assert bound == pytest.approx({16: 0.0275, 8: 0.0824}[neighbours], abs=5e-4)
    assert np.all(t >= exact * (1 - 1e-12))  # a grid walk is never shorter than the straight line
    assert np.all(t <= exact * (1 + bound) + 1e-12)
    assert np.max(t / np.where(exact > 0, exact, 1) - 1) > 0.8 * bound  # the bound is reached, not loose
    if neighbours == 16:  # the isochrone of 1.5 minutes: a circle of radius 1.5 x the flat speed
        r = 1.5 * M_PER_MIN
        area = np.count_nonzero(t <= 1.5) * cell ** 2
        assert math.sqrt(area / math.pi) == pytest.approx(r, rel=0.02)  # its mean radius within 2 % (1.4 % short)
        inside = np.hypot(rr - 120, cc - 120) * cell
        assert np.all(inside[t <= 1.5] <= r) and np.all(inside[t > 1.5] > r / (1 + bound))  # within 2.75 % everywhere
        # its radius along the axes and the diagonals (moves of the grid) exact to a cell
        assert abs(np.count_nonzero(t[120, 120:] <= 1.5) * cell - r) <= cell


@pytest.mark.parametrize("z_metres", [1.0, 0.3048])  # heights in metres, or in feet on a metre grid
def test_a_uniform_plane_gives_the_analytic_times_up_and_down_the_slope(z_metres):
    n, cell, g = 121, 1.0, 0.1  # slope 10 % rising eastwards
    x = np.arange(n) * cell
    dem = np.tile(x * g / z_metres, (n, 1))
    t = travel_minutes(dem, cell, [(60, 60)], z_metres=z_metres, neighbours=16)
    up = 60 * cell / 1000 / _tobler(g) * 60
    down = 60 * cell / 1000 / _tobler(-g) * 60
    assert t[60, 120] == pytest.approx(up, rel=1e-9)  # straight up the plane: 60 m at Tobler(+0.1)
    assert t[60, 0] == pytest.approx(down, rel=1e-9)  # straight down: Tobler(-0.1)
    assert t[60, 0] < t[60, 120]
    # across the slope (level): the flat speed
    assert t[0, 60] == pytest.approx(60 * cell / M_PER_MIN, rel=1e-9)


def test_heights_in_feet_on_a_metre_grid_read_from_the_band_unit(tmp_path):
    """A plane rising 10 % eastwards written once in metres and once in feet (band unit "ft"): the same minutes,
    equal to Tobler's analytic time up the plane."""
    grid = Grid(rasterio.transform.from_origin(500000.0, 4000060.0, 1.0, 1.0), 61, 60, pyproj.CRS("EPSG:32610"))
    rise = np.tile(np.arange(61) * 0.1, (60, 1))
    write_raster(tmp_path / "m.tif", rise, grid, units="m")
    write_raster(tmp_path / "ft.tif", rise / 0.3048, grid, units="ft")
    for name in ("m", "ft"):
        travel_from_dem(tmp_path / f"{name}.tif", tmp_path / f"out_{name}", "500000.5,4000030.5")
    a, b = _minutes(tmp_path / "out_m" / "travel_minutes.tif"), _minutes(tmp_path / "out_ft" / "travel_minutes.tif")
    np.testing.assert_allclose(a, b, rtol=1e-6)
    assert a[29, 60] == pytest.approx(60 / 1000 / _tobler(0.1) * 60, rel=1e-6)


def _scene(tmp_path, classes=None, crs="EPSG:32610", n=100, cell=1.0):
    tmp_path.mkdir(parents=True, exist_ok=True)
    grid = Grid(rasterio.transform.from_origin(500000.0, 4000000.0 + n * cell, cell, cell), n, n, pyproj.CRS(crs))
    dem = write_raster(tmp_path / "dem.tif", np.zeros((n, n)), grid, units="m")
    cls = None
    if classes is not None:
        cls = write_raster(tmp_path / "classes.tif", classes, grid, dtype="uint8", nodata=255)
    return dem, cls, grid


def _minutes(path):
    with rasterio.open(path) as src:
        a = src.read(1).astype(float)
        a[a == src.nodata] = np.nan
        return a


def test_a_strip_of_heavy_shrub_slows_by_exactly_its_factor(tmp_path):
    classes = np.zeros((100, 100), np.uint8)
    classes[:, 40:60] = 3  # 20 m of heavy shrub across the whole scene
    dem, cls, grid = _scene(tmp_path, classes)
    x0, y0 = 500000.5, 4000049.5  # the centre of row 50, column 0
    rep = travel_from_dem(dem, tmp_path / "out", f"{x0},{y0}", classes=cls)
    t = _minutes(tmp_path / "out" / "travel_minutes.tif")
    flat = 99 / M_PER_MIN
    assert t[50, 99] == pytest.approx(flat + 20 / M_PER_MIN * (1 / 0.75 - 1), rel=1e-6)  # float32 raster
    assert t[50, 39] == pytest.approx(39 / M_PER_MIN, rel=1e-6)
    assert rep["speed_model"]["shrub_factors"]["heavy"] == 0.75
    seen = gpd.read_file(tmp_path / "out" / "travel.gpkg", layer="last_seen")
    assert len(seen) == 1 and seen.geometry[0].equals(Point(x0, y0))


def test_a_river_is_not_crossed_and_is_with_wading(tmp_path):
    dem, _cls, grid = _scene(tmp_path)
    river = gpd.GeoDataFrame(geometry=[box(500040.0, 3999000.0, 500050.0, 4001000.0)], crs="EPSG:32610")
    river.to_file(tmp_path / "water.gpkg", layer="WATERBODY", driver="GPKG")
    src = "500000.5,4000049.5"
    travel_from_dem(dem, tmp_path / "dry", src, waterbodies=f"{tmp_path / 'water.gpkg'}:WATERBODY")
    t = _minutes(tmp_path / "dry" / "travel_minutes.tif")
    assert np.isnan(t[:, 40:]).all() and np.isfinite(t[:, :40]).all()  # the river and beyond: unreached
    rep = travel_from_dem(dem, tmp_path / "wet", src, TravelSettings(wade_speed=1.0),
                          waterbodies=f"{tmp_path / 'water.gpkg'}:WATERBODY")
    t = _minutes(tmp_path / "wet" / "travel_minutes.tif")
    wade = 10 / 1000 / 1.0 * 60  # 10 m at 1 km/h (cell centres 39.5 ... 49.5 ... : the steps' halves)
    assert t[50, 99] == pytest.approx(89 / M_PER_MIN + wade, rel=1e-6)
    assert rep["speed_model"]["water_cells"] == 10 * 100
    # water without ground under it (a DEM from ground returns has none): waded all the same, the steps level
    grid = Grid(rasterio.transform.from_origin(500000.0, 4000100.0, 1.0, 1.0), 100, 100, pyproj.CRS("EPSG:32610"))
    holes = np.zeros((100, 100))
    holes[:, 40:50] = np.nan
    write_raster(tmp_path / "holes.tif", holes, grid, units="m")
    travel_from_dem(tmp_path / "holes.tif", tmp_path / "holes", src, TravelSettings(wade_speed=1.0),
                    waterbodies=f"{tmp_path / 'water.gpkg'}:WATERBODY")
    np.testing.assert_array_equal(_minutes(tmp_path / "holes" / "travel_minutes.tif"), t)
    with pytest.raises(InputError, match="water"):
        travel_from_dem(dem, tmp_path / "in_water", "500045,4000050", waterbodies=f"{tmp_path / 'water.gpkg'}:WATERBODY")
    with rasterio.open(tmp_path / "wet" / "isochrone_bands.tif") as b:
        assert b.colormap(1)[1][:3] == (0x1a, 0x98, 0x50) and b.dtypes[0] == "uint8"


def test_isotropic_8_neighbours_equals_skimage_mcp_geometric():
    from skimage.graph import MCP_Geometric

    rng = np.random.default_rng(7)
    n, cell = 90, 3.0
    yy, xx = np.mgrid[0:n, 0:n] * cell
    dem = 20 * np.sin(xx / 70) * np.cos(yy / 50) + 0.05 * xx
    factor = rng.choice([1.0, 0.92, 0.83, 0.75], size=(n, n))
    factor[30:33, 10:80] = 0.0  # a wall of water
    # the speed grid, independently: each cell's steepest slope (central differences) taken uphill
    gy, gx = np.gradient(dem, cell)
    speed = _tobler(np.hypot(gx, gy)) * factor  # km/h
    with np.errstate(divide="ignore"):
        cost = np.where(factor > 0, 60.0 / (1000.0 * speed), np.inf)  # minutes per metre
    mcp = MCP_Geometric(cost, fully_connected=True, sampling=(cell, cell))
    ref, _ = mcp.find_costs([(5, 5), (70, 80)])
    got = travel_minutes(dem, cell, [(5, 5), (70, 80)], factor=factor, neighbours=8, isotropic=True)
    ok = np.isfinite(ref)
    assert ok.sum() > 0.9 * n * n
    np.testing.assert_array_equal(np.isfinite(got), ok)
    np.testing.assert_allclose(got[ok], ref[ok], rtol=1e-6)


def test_many_sources_give_the_time_from_the_nearest():
    dem = np.zeros((50, 80))
    a = travel_minutes(dem, 1.0, [(25, 10)])
    b = travel_minutes(dem, 1.0, [(25, 70)])
    both = travel_minutes(dem, 1.0, [(25, 10), (25, 70)])
    np.testing.assert_allclose(both, np.minimum(a, b), rtol=1e-12)


def test_cancel_leaves_no_output(tmp_path):
    from gistools.errors import Cancelled

    dem, _cls, _grid = _scene(tmp_path)
    with pytest.raises(Cancelled):
        travel_from_dem(dem, tmp_path / "out", "500010,4000010",
                        progress=lambda f, m="": not m.startswith("the walk's graph: move 3"))
    assert not list((tmp_path / "out").glob("*.tif")) and not (tmp_path / "out" / "travel.gpkg").exists()


def test_refusals_before_any_output(tmp_path):
    dem, _cls, _grid = _scene(tmp_path)
    with pytest.raises(InputError, match="outside the DEM"):
        travel_from_dem(dem, tmp_path / "o1", "1,2")
    with pytest.raises(InputError, match="isochrones"):
        travel_from_dem(dem, tmp_path / "o2", "500010,4000010", TravelSettings(isochrones=(0, 30)))
    # 160,000 cells: about 96 MB of whole graph, 12.8 MB of cell arrays (80 bytes a cell) even block by block
    big, _cls, _grid = _scene(tmp_path / "big", n=400)
    with pytest.raises(OutOfMemoryError, match=r"400 x 400 cells needs about 0\.01 GB .*0\.10 GB\), more than "
                                                r"the 0\.01 GB"):
        travel_from_dem(big, tmp_path / "o3", "500010,4000010", TravelSettings(max_memory=0.01))
    assert not any((tmp_path / f"o{i}").exists() for i in (1, 2, 3))


def test_the_sample_from_a_point_last_seen(tmp_path, sample_run):
    """The sample's DEM (gistools rasters), roads and water from its breaklines: times against independent bounds."""
    out_rasters, _ = sample_run
    b = SAMPLE / "breaklines.gpkg"
    x0, y0 = 431000.0, 1811000.0
    rep = travel_from_dem(out_rasters, tmp_path / "travel", [f"{x0},{y0}"], TravelSettings(isochrones=(2, 4, 6)),
                          roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE", waterbodies=f"{b}:WATERBODY")
    with rasterio.open(tmp_path / "travel" / "travel_minutes.tif") as src:
        t = src.read(1).astype(float)
        t[t == src.nodata] = np.nan
        assert src.crs.to_epsg() == 2882 and src.profile["compress"] == "deflate" and src.nodata == -9999
        r0, c0 = src.index(x0, y0)
        rows, cols = np.mgrid[0:src.height, 0:src.width]
        xs, ys = (np.reshape(v, rows.shape) for v in rasterio.transform.xy(src.transform, rows, cols))
        cx, cy = rasterio.transform.xy(src.transform, r0, c0)  # the start cell's centre
    assert t[r0, c0] == 0
    # never faster than a straight walk from the start cell at Tobler's top speed (6 km/h); US survey feet to metres
    dist_m = np.hypot(xs - cx, ys - cy) * 1200 / 3937
    ok = np.isfinite(t)
    assert np.all(t[ok] >= dist_m[ok] / (6000 / 60) * (1 - 1e-6))
    # the water of the breaklines is left unreached: the water polygons' cells have no time
    water = rep["speed_model"]["water_cells"]
    assert water > 1000 and (~ok).sum() >= water
    assert 0.9 < rep["reached_share"] < 1.0
    iso = gpd.read_file(tmp_path / "travel" / "travel.gpkg", layer="isochrones")
    for minutes, area in zip(iso["minutes"], iso["area"]):  # the polygons hold exactly the cells within them
        assert area == pytest.approx(np.count_nonzero(ok & (t <= minutes + 1e-4)) * 25.0, rel=1e-3)
    assert iso["hectares"].iloc[-1] == pytest.approx(iso["area"].iloc[-1] * (1200 / 3937) ** 2 / 1e4, rel=1e-9)
    assert list(iso["minutes"]) == [2, 4, 6]
    stored = json.loads((tmp_path / "travel" / "report.json").read_text())
    assert stored["tool"] == "gistools travel" and stored["unit"] == "ftUS"
