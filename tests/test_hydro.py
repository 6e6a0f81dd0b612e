"""Hydro-flattening on the sample's ponds: inside each water body the DEM is flat, filled, at the lowest ground
point of its shore (computed here from the LAS files and the polygons), across the tiles it spans; the nDSM
follows; a resumed run stays flat."""

from __future__ import annotations

import geopandas as gpd
import laspy
import numpy as np
import pytest
import rasterio
import shapely

from conftest import SAMPLE
from gistools.errors import InputError
from gistools.grid import affine_apply
from gistools.products.rasters import RasterSettings, rasters_from_tiles

WATER = f"{SAMPLE / 'breaklines.gpkg'}:WATERBODY"


def centres_inside(path, poly):
    with rasterio.open(path) as src:
        a = src.read(1, masked=True).filled(np.nan).astype(float)
        rows, cols = np.indices(a.shape)
        x, y = affine_apply(src.transform, (cols + 0.5, rows + 0.5))
    return a, shapely.contains_xy(poly, x, y)


def _ground(sample_tiles):
    pts = [laspy.read(p) for p in sample_tiles]
    g = [np.asarray(p.classification) == 2 for p in pts]
    return [np.concatenate([np.asarray(getattr(p, k))[m] for p, m in zip(pts, g)]) for k in "xyz"]


def test_a_lake_is_flat_filled_and_at_its_lowest_shore_point(tmp_path, sample_tiles):
    plain = rasters_from_tiles(SAMPLE, tmp_path / "plain")
    report = rasters_from_tiles(SAMPLE, tmp_path / "flat", RasterSettings(hydro_flatten=WATER))
    assert report["counts"]["ok"] == 4 and plain["counts"]["ok"] == 4
    shore = report["hydro_flatten"]["shore_width"]
    assert shore == pytest.approx(10.0)  # two 5 ft cells
    gx, gy, gz = _ground(sample_tiles)
    bodies = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="WATERBODY").geometry
    kinds = {k: v["kind"] for k, v in report["hydro_flatten"]["bodies"].items()}
    assert sorted(kinds.values()) == ["lake", "river"]  # the pond, and the river (44 ft wide, 2,130 ft long)
    key = next(k for k, v in kinds.items() if v == "lake")
    poly = bodies[int(key)]
    band = poly.buffer(shore).difference(poly)
    lowest = gz[shapely.contains_xy(band, gx, gy)].min()
    dem, inside = centres_inside(tmp_path / "flat" / "dem.vrt", poly)
    before, _ = centres_inside(tmp_path / "plain" / "dem.vrt", poly)
    assert inside.sum() > 100
    assert np.isfinite(dem[inside]).all()  # filled
    assert np.all(dem[inside] == np.float32(lowest))  # flat, at the lowest ground point of the shore
    assert report["hydro_flatten"]["bodies"][key]["elevation"] == pytest.approx(lowest)
    assert np.isnan(before[inside]).any() or (before[inside] > lowest).any()  # it changed something
    # outside the water bodies the DEM is the plain run's
    others = ~shapely.contains_xy(shapely.union_all(list(bodies)), *np.meshgrid(*_centres(tmp_path / "flat" / "dem.vrt")))
    np.testing.assert_array_equal(dem[others], before[others])
    # the nDSM is the DSM minus the flattened DEM
    with rasterio.open(tmp_path / "flat" / "dsm.vrt") as a, rasterio.open(tmp_path / "flat" / "ndsm.vrt") as b:
        dsm, ndsm = (s.read(1, masked=True).filled(np.nan) for s in (a, b))
    ok = np.isfinite(dsm) & np.isfinite(dem)
    np.testing.assert_allclose(ndsm[ok], (dsm - dem.astype(np.float32))[ok], atol=1e-4)
    # a resumed run keeps the tiles and stays flat
    again = rasters_from_tiles(SAMPLE, tmp_path / "flat", RasterSettings(hydro_flatten=WATER))
    assert again["counts"]["skipped"] == 4
    dem2, _ = centres_inside(tmp_path / "flat" / "dem.vrt", poly)
    assert np.array_equal(dem2[inside], dem[inside], equal_nan=True)


def test_a_river_steps_down_along_its_flow_never_above_its_banks(tmp_path, sample_tiles):
    """The sample's river runs west to east across two tiles: filled, its level falling monotonically along the
    flow (the medians of 100 ft slices), and no higher than the lowest bank point within 30 ft of the cell (for more
    than 99 % of the cells: the levels are steps of 4 grid cells along the river)."""
    report = rasters_from_tiles(SAMPLE, tmp_path / "flat", RasterSettings(hydro_flatten=WATER))
    key = next(k for k, v in report["hydro_flatten"]["bodies"].items() if v["kind"] == "river")
    river = report["hydro_flatten"]["bodies"][key]
    assert river["highest"] > river["elevation"]  # it steps
    poly = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="WATERBODY").geometry[int(key)]
    dem, inside = centres_inside(tmp_path / "flat" / "dem.vrt", poly)
    assert inside.sum() > 1000 and np.isfinite(dem[inside]).all()
    xs, ys = np.meshgrid(*_centres(tmp_path / "flat" / "dem.vrt"))
    x, y, level = xs[inside], ys[inside], dem[inside]
    assert {t for t in report["hydro_flatten"]["tiles"]} >= {"35712", "35812"} or len(report["hydro_flatten"]["tiles"]) >= 2
    slices = np.floor((x - x.min()) / 100).astype(int)
    medians = np.array([np.median(level[slices == k]) for k in np.unique(slices)])
    steps = np.diff(medians)
    assert np.all(steps <= 1e-4) or np.all(steps >= -1e-4)  # monotone, one way along the river
    gx, gy, gz = _ground(sample_tiles)
    band = poly.buffer(report["hydro_flatten"]["shore_width"]).difference(poly)
    on = shapely.contains_xy(band, gx, gy)
    from scipy.spatial import cKDTree

    tree = cKDTree(np.column_stack([gx[on], gy[on]]))
    beside = tree.query_ball_point(np.column_stack([x, y]), r=30.0)
    ok = [not b or lv <= gz[on][b].min() + 1e-4 for lv, b in zip(level, beside)]
    assert np.mean(ok) > 0.99
def _centres(path):
    with rasterio.open(path) as src:
        cols, rows = np.arange(src.width), np.arange(src.height)
        return src.transform.c + (cols + 0.5) * src.transform.a, src.transform.f + (rows + 0.5) * src.transform.e


def _meets(path, poly):
    with rasterio.open(path) as src:
        return poly.intersects(shapely.box(*src.bounds))


def test_hydro_flatten_needs_the_dem_and_a_polygon_layer(tmp_path):
    with pytest.raises(InputError, match="add dem"):
        rasters_from_tiles(SAMPLE, tmp_path / "a", RasterSettings(products=("dsm",), hydro_flatten=WATER))
    with pytest.raises(InputError, match="shore_width"):
        rasters_from_tiles(SAMPLE, tmp_path / "b", RasterSettings(hydro_flatten=WATER, shore_width="-3ft"))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_dem_voids_are_filled_by_a_tin_across_or_left(tmp_path, sample_tiles):
    """A 150 ft square with its ground taken out (a big roof): beyond --dem-max-distance the DEM is void; --dem-fill
    tin fills those cells with a TIN of the ground around them (scipy's, here), idw with values between the
    ground's, none leaves them; report.json counts them."""
    from scipy.interpolate import LinearNDInterpolator

    from gistools.io.points import read_tile_info, write_tile

    src = sample_tiles[0]
    las = laspy.read(src)
    x, y = np.asarray(las.x), np.asarray(las.y)
    cx, cy = (x.min() + x.max()) / 2, (y.min() + y.max()) / 2
    roof = (np.abs(x - cx) < 75) & (np.abs(y - cy) < 75)
    keep = ~(roof & (np.asarray(las.classification) == 2))
    tiles = tmp_path / "tiles"
    pts = {k: np.asarray(getattr(las, k))[keep] for k in ("x", "y", "z", "classification", "return_number",
                                                          "number_of_returns", "intensity")}
    write_tile(tiles / "roof.las", pts, read_tile_info(src).crs)
    runs = {m: rasters_from_tiles(tiles, tmp_path / m, RasterSettings(dem_fill=m, dem_max_distance="5m"))
            for m in ("none", "tin", "idw")}
    dems = {m: rasterio.open(tmp_path / m / "dem" / "roof.tif").read(1, masked=True).filled(np.nan) for m in runs}
    void = np.isnan(dems["none"])
    assert void.sum() > 50 and runs["none"]["tiles"][0]["dem_filled_cells"] == 0
    with rasterio.open(tmp_path / "tin" / "dem" / "roof.tif") as r:
        rows, cols = np.nonzero(void)
        qx, qy = affine_apply(r.transform, (cols + 0.5, rows + 0.5))
    g = pts["classification"] == 2
    want = LinearNDInterpolator(np.column_stack([pts["x"][g] - cx, pts["y"][g] - cy]), pts["z"][g])(qx - cx, qy - cy)
    got = dems["tin"][void]
    ok = np.isfinite(want)
    assert runs["tin"]["tiles"][0]["dem_filled_cells"] == np.isfinite(got).sum() >= ok.sum() * 0.99
    assert np.mean(np.abs(got[ok] - want[ok]) < 1e-3) > 0.99  # a TIN across (but for ties between cocircular points)
    near = pts["z"][g][(np.abs(pts["x"][g] - cx) < 120) & (np.abs(pts["y"][g] - cy) < 120)]
    in_roof = (np.abs(qx - cx) < 75) & (np.abs(qy - cy) < 75)
    assert in_roof.sum() > 50
    idw = dems["idw"][void][in_roof]
    assert np.isfinite(idw).all() and near.min() <= idw.min() and idw.max() <= near.max()
    assert np.array_equal(dems["tin"][~void], dems["none"][~void])
    with pytest.raises(InputError, match="dem_fill"):
        rasters_from_tiles(tiles, tmp_path / "bad", RasterSettings(dem_fill="kriging"))


def test_river_levels_fall_along_the_flow_whichever_way_it_runs():
    from gistools.lidar.hydro import river_levels

    rng = np.random.default_rng(4)
    s = rng.uniform(0, 1000, 400)
    z = 50 - 0.01 * s + rng.uniform(0, 0.5, 400)  # banks falling toward larger s, rough
    for flip in (False, True):
        ss = 1000 - s if flip else s
        edges, levels, forward = river_levels(ss, z, 50.0)
        assert forward is not flip
        d = np.diff(levels)
        assert np.all(d <= 0) if forward else np.all(d >= 0)
        bins = np.minimum((ss / 50).astype(int), len(levels) - 1)
        for k in range(len(levels)):  # never above the lowest bank point of its bin or of the bins beside it
            near = (bins >= k - 1) & (bins <= k + 1)
            assert levels[k] <= z[near].min() + 1e-12
