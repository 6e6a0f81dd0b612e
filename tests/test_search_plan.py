"""gistools search-plan: analytic cases (rings on flat open ground, POD by hand, routes on a maze against the travel
raster, a litter carry's slope limit), barriers of a synthetic scene against their known outlines, and the sample
through the command line."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import geopandas as gpd
import numpy as np
import pyproj
import pytest
import rasterio
import shapely

from conftest import SAMPLE
from gistools.errors import InputError
from gistools.grid import Grid, affine_apply
from gistools.io.raster import write_raster
from gistools.products.search_plan import SearchSettings, lost_person_table, search_plan
from gistools.products.travel import TravelSettings, travel_from_dem

X0, Y0 = 500000.0, 4000000.0


def _scene(folder, dem, classes=None, cell=4.0, crs="EPSG:32612"):
    """A DEM (and classes) raster with its north-west corner at (X0, Y0 + rows * cell)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows, cols = dem.shape
    grid = Grid(rasterio.transform.from_origin(X0, Y0 + rows * cell, cell, cell), cols, rows, pyproj.CRS(crs))
    path = write_raster(folder / "dem.tif", dem, grid, units="m")
    cls = write_raster(folder / "classes.tif", classes, grid, dtype="uint8", nodata=255) if classes is not None \
        else None
    return path, cls, grid


def _table(path, rings_km):
    """A categories table of one row: rings in km."""
    with open(path, "w", encoding="utf-8", newline="") as f:
        w = csv.writer(f)
        w.writerow(["category", "ecoregion", "p25_km", "p50_km", "p75_km", "p95_km", "source"])
        w.writerow(["test", "flat", *rings_km, "analytic case"])
    return path


def _read(path):
    with rasterio.open(path) as src:
        a = src.read(1).astype(float)
        if src.nodata is not None:
            a[a == src.nodata] = np.nan
        return a, src.transform


def _centres(transform, shape):
    rows, cols = np.indices(shape)
    return affine_apply(transform, (cols + 0.5, rows + 0.5))


NO_FEATURES = dict(feature_weights=(1, 1, 1, 1, 1))


def test_rings_on_flat_open_ground_are_circles_each_holding_its_share(tmp_path):
    """250 x 250 cells of 4 m, flat, no classes: the four rings are circles at 100, 200, 300, 400 m around the point,
    each cell's probability its ring's share over the ring's cells (by the cell-centre rule); the 95 % ring lies
    within the DEM, so 5 % is the rest of the world."""
    dem, _, grid = _scene(tmp_path / "in", np.zeros((250, 250)))
    cx, cy = X0 + 500.0 + 2.0, Y0 + 500.0 + 2.0  # a cell centre near the middle
    rep = search_plan(dem, tmp_path / "plan", f"{cx},{cy}", "test", SearchSettings(**NO_FEATURES),
                      categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    poa, transform = _read(tmp_path / "plan" / "poa.tif")
    x, y = _centres(transform, poa.shape)
    d = np.hypot(x - cx, y - cy)
    assert rep["rings_m"] == [100.0, 200.0, 300.0, 400.0]
    low = 0.0
    for high, share in zip((100, 200, 300, 400), (0.25, 0.25, 0.25, 0.20)):
        ring = (d >= low) & (d < high)
        assert poa[ring].sum() == pytest.approx(share, abs=1e-12)  # each ring holds its share
        np.testing.assert_allclose(poa[ring], share / ring.sum(), rtol=1e-12)  # uniform by area on open ground
        low = high
    assert np.all(poa[d >= 400] == 0)
    assert rep["rest_of_world"] == pytest.approx(0.05, abs=1e-12)
    assert poa.sum() + rep["rest_of_world"] == pytest.approx(1.0, abs=1e-12)
    rings = gpd.read_file(tmp_path / "plan" / "segments.gpkg", layer="rings")
    for geom, r in zip(rings.geometry, (100, 200, 300, 400)):  # circles at the quartiles (64 segments a quarter)
        outer = shapely.get_exterior_ring(geom)
        radii = np.hypot(*(np.asarray(outer.coords) - (cx, cy)).T)
        assert radii.max() == pytest.approx(r, rel=1e-9) and radii.min() > r * math.cos(math.pi / 256) - 1e-9


def test_rings_beyond_the_dem_give_their_share_off_it_to_the_rest_of_the_world(tmp_path):
    """The point in a corner: each ring keeps the share of its annulus on the DEM (a quarter for a corner far
    inside), and POA plus the rest of the world is 1."""
    dem, _, _grid = _scene(tmp_path / "in", np.zeros((100, 100)), cell=10.0)
    rep = search_plan(dem, tmp_path / "plan", f"{X0 + 5},{Y0 + 5}", "test", SearchSettings(**NO_FEATURES),
                      categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    poa, _ = _read(tmp_path / "plan" / "poa.tif")
    # each annulus's share on the DEM, from shapely's areas of the annuli clipped to the DEM's box
    dem_box, low = shapely.box(X0, Y0, X0 + 1000, Y0 + 1000), 0.0
    centre = shapely.Point(X0 + 5, Y0 + 5)
    for on, high in zip(rep["ring_on_data"], (100, 200, 300, 400)):
        ring = centre.buffer(high, quad_segs=512).difference(centre.buffer(low, quad_segs=512))
        assert on == pytest.approx(ring.intersection(dem_box).area / ring.area, abs=2e-3)
        low = high
    assert poa.sum() + rep["rest_of_world"] == pytest.approx(1.0, abs=1e-12)
    assert rep["ring_held"] == pytest.approx([s * f for s, f in zip((0.25, 0.25, 0.25, 0.2), rep["ring_on_data"])])


def test_pod_of_each_segment_is_koopmans_by_hand(tmp_path):
    """Searcher-hours from a CSV: each segment's coverage is W v t / A and its POD 1 - exp(-coverage), computed here
    from the layer's areas (checked against the segments raster's cells) and the stated sweep widths."""
    classes = np.zeros((120, 120), np.uint8)
    classes[:, 60:] = 1  # light shrub in the east half
    dem, cls, grid = _scene(tmp_path / "in", np.zeros((120, 120)), classes, cell=5.0)
    s = SearchSettings(segment_size="4ha", search_speed=1.5, detection_ranges=(20, 10, 8, 4), visibility="low",
                       **NO_FEATURES)
    first = search_plan(dem, tmp_path / "plan", f"{X0 + 300},{Y0 + 300}", "test", s, classes=cls,
                        categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    n = first["segments"]
    assert n >= 4
    effort = tmp_path / "effort.csv"
    effort.write_text("segment,hours\n" + "".join(f"{k},{k * 1.5}\n" for k in range(1, n + 1)), encoding="utf-8")
    rep = search_plan(dem, tmp_path / "plan", f"{X0 + 300},{Y0 + 300}", "test", s, classes=cls, effort=effort,
                      categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    seg = gpd.read_file(tmp_path / "plan" / "segments.gpkg", layer="segments")
    labels, _ = _read(tmp_path / "plan" / "segments.tif")
    poa, _ = _read(tmp_path / "plan" / "poa.tif")
    for _, row in seg.iterrows():
        cells = labels == row["segment"]
        assert row["area_ha"] == pytest.approx(cells.sum() * 25.0 / 1e4, rel=1e-12)
        assert row["poa"] == pytest.approx(poa[cells].sum(), rel=1e-9)
        light = np.mean(classes[cells] == 1)
        assert row["sweep_width_m"] == pytest.approx(1.1 * (20 * (1 - light) + 10 * light), rel=1e-12)
        hours = row["segment"] * 1.5
        assert row["hours"] == hours
        cov = row["sweep_width_m"] * 1.5 * 1000 * hours / (row["area_ha"] * 1e4)
        assert row["coverage"] == pytest.approx(cov, rel=1e-12)
        assert row["pod"] == pytest.approx(1 - math.exp(-cov), rel=1e-12)
        assert row["pos"] == pytest.approx(row["poa"] * row["pod"], rel=1e-12)
    assert rep["pos_cumulative"] == pytest.approx(seg["pos"].sum(), rel=1e-12)
    ranked = seg.sort_values("rank")
    assert list(ranked["pos_per_hour"]) == sorted(seg["poa"] * seg["pod"] / seg["hours"], reverse=True)
    with pytest.raises(Exception, match=f"no segment {n + 1}"):
        effort.write_text(f"segment,hours\n{n + 1},2\n", encoding="utf-8")
        search_plan(dem, tmp_path / "plan2", f"{X0 + 300},{Y0 + 300}", "test", s, classes=cls, effort=effort,
                    categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    assert not (tmp_path / "plan2" / "poa.tif").exists()


def _maze():
    """A flat 60 x 60 maze of 2 m cells: water walls with one gap each, a heavy shrub block on the way."""
    classes = np.zeros((60, 60), np.uint8)
    classes[15, :50] = 5  # a wall of water open in the east
    classes[30, 10:] = 5  # open in the west
    classes[45, :50] = 5  # open in the east
    classes[35:42, 20:40] = 3  # heavy shrub
    return classes


def test_routes_on_a_maze_follow_the_travel_graph_and_end_at_the_travel_raster_minutes(tmp_path):
    """A route's minutes equal gistools travel's raster from the same staging point at its end cell, and summing
    Tobler's times of its steps by hand (8 neighbours, flat: each step its length over the mean of its two cells'
    speeds) gives the same minutes: the route is a shortest path of the travel graph."""
    classes = _maze()
    dem, cls, grid = _scene(tmp_path / "in", np.zeros((60, 60)), classes, cell=2.0)
    sx, sy = X0 + 5.0, Y0 + 120 - 5.0  # north-west corner
    tx, ty = X0 + 5.0, Y0 + 5.0  # south-west corner: through both gaps and past the shrub
    rep = search_plan(dem, tmp_path / "plan", f"{sx},{sy}", "test", SearchSettings(neighbours=8, **NO_FEATURES),
                      classes=cls, staging=f"{sx},{sy}", route_to=f"{tx},{ty}",
                      categories=_table(tmp_path / "t.csv", (0.01, 0.02, 0.03, 0.04)))
    travel_from_dem(dem, tmp_path / "travel", f"{sx},{sy}", TravelSettings(neighbours=8), classes=cls)
    minutes, transform = _read(tmp_path / "travel" / "travel_minutes.tif")
    routes = gpd.read_file(tmp_path / "plan" / "routes.gpkg", layer="routes")
    route = routes[routes["kind"] == "point"].iloc[0]
    coords = np.asarray(route.geometry.coords)
    col, row = affine_apply(~transform, (coords[:, 0], coords[:, 1]))
    r, c = np.floor(row).astype(int), np.floor(col).astype(int)
    assert (r[-1], c[-1]) == (57, 2) and (r[0], c[0]) == (2, 2)
    assert route["minutes"] == pytest.approx(minutes[r[-1], c[-1]], rel=1e-6)  # float32 raster
    speed = {0: 1.0, 3: 0.75}
    v0 = 6.0 * math.exp(-3.5 * 0.05)
    total = 0.0
    for a, b in zip(zip(r, c), zip(r[1:], c[1:])):
        assert max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1  # one king's move a step
        assert classes[b] != 5
        step = 2.0 * math.hypot(a[0] - b[0], a[1] - b[1])
        total += step / 1000 * 0.5 * (1 / (v0 * speed[classes[a]]) + 1 / (v0 * speed[classes[b]])) * 60
    assert route["minutes"] == pytest.approx(total, rel=1e-9)
    assert route["length_m"] == pytest.approx(route.geometry.length, rel=1e-9)
    assert rep["routes"] >= 1


def test_a_litter_route_never_crosses_a_cell_steeper_than_its_limit(tmp_path):
    """A ridge steeper than 20 degrees between the person and the staging point, with one gentle ramp through it:
    the litter goes round by the ramp; every cell it crosses is within the limit (np.gradient here)."""
    n, cell = 80, 2.0
    dem = np.zeros((n, n))
    rows = np.arange(n)[:, None] * np.ones((1, n))
    dem += np.clip(10 - np.abs(rows - 40) * 2.0, 0, None)  # a ridge along row 40, 45 degrees on its sides
    ramp = slice(60, 70)
    dem[:, ramp] = np.clip(10 - np.abs(rows[:, ramp] - 40) * 0.25, 0, None)  # 7 degrees through the ridge
    path, _, grid = _scene(tmp_path / "in", dem, np.zeros((n, n), np.uint8), cell=cell)
    seen, staging = f"{X0 + 21},{Y0 + 160 - 21}", f"{X0 + 21},{Y0 + 21}"
    rep = search_plan(path, tmp_path / "plan", seen, "test", SearchSettings(litter_max_slope=20.0, **NO_FEATURES),
                      classes=tmp_path / "in" / "classes.tif", staging=staging,
                      categories=_table(tmp_path / "t.csv", (0.01, 0.02, 0.03, 0.04)))
    litter = gpd.read_file(tmp_path / "plan" / "routes.gpkg", layer="litter").iloc[0]
    coords = np.asarray(litter.geometry.coords)
    with rasterio.open(path) as src:
        col, row = affine_apply(~src.transform, (coords[:, 0], coords[:, 1]))
    r, c = np.floor(row).astype(int), np.floor(col).astype(int)
    gy, gx = np.gradient(dem, cell)
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    assert slope[r, c].max() <= 20.0
    assert np.all((c[(r > 30) & (r < 50)] >= 60) & (c[(r > 30) & (r < 50)] < 70))  # over the ridge by the ramp
    assert rep["litter"]["minutes"] > 0


def test_barriers_of_a_known_cliff_pond_and_thicket_are_found_within_one_cell(tmp_path):
    """A 10 m step (a cliff along a straight line), a round pond and a square thicket: their outlines in
    barriers.gpkg lie within one cell (Hausdorff) of the true shapes' cells."""
    n, cell = 100, 2.0
    dem = np.zeros((n, n))
    dem[:, 70:] = 10.0  # the cliff between columns 69 and 70
    classes = np.zeros((n, n), np.uint8)
    rr, cc = np.indices((n, n))
    pond = np.hypot(rr - 30 + 0.5, cc - 30 + 0.5) < 12
    classes[pond] = 5
    classes[60:80, 20:45] = 3  # the thicket, 40 x 50 m
    path, cls, grid = _scene(tmp_path / "in", dem, classes, cell=cell)
    search_plan(path, tmp_path / "plan", f"{X0 + 101},{Y0 + 101}", "test", SearchSettings(**NO_FEATURES),
                classes=cls, categories=_table(tmp_path / "t.csv", (0.01, 0.02, 0.03, 0.04)))
    barriers = gpd.read_file(tmp_path / "plan" / "barriers.gpkg", layer="barriers")
    t = grid.transform
    kinds = {k: shapely.union_all(barriers[barriers["kind"] == k].geometry) for k in ("cliff", "water", "thicket")}
    top = Y0 + n * cell
    step = shapely.LineString([(X0 + 70 * cell, top), (X0 + 70 * cell, Y0)])
    assert kinds["cliff"].hausdorff_distance(step.buffer(cell, cap_style="flat")) <= cell + 1e-9
    from rasterio.features import shapes

    pond_true = shapely.union_all([shapely.geometry.shape(g) for g, v in shapes(pond.astype(np.uint8), mask=pond,
                                                                                 transform=t)])
    assert kinds["water"].hausdorff_distance(pond_true) <= cell + 1e-9
    thicket_true = shapely.box(X0 + 20 * cell, top - 80 * cell, X0 + 45 * cell, top - 60 * cell)
    assert kinds["thicket"].hausdorff_distance(thicket_true) <= cell + 1e-9
    codes, _ = _read(tmp_path / "plan" / "barriers.tif")
    assert np.all(codes[pond] == 2) and np.all(codes[60:80, 20:45] == 3)


def test_refusals_before_any_output(tmp_path):
    dem, _, _ = _scene(tmp_path / "in", np.zeros((20, 20)))
    with pytest.raises(InputError, match="not in the categories table"):
        search_plan(dem, tmp_path / "o1", f"{X0 + 10},{Y0 + 10}", "nobody")
    with pytest.raises(InputError, match="outside the DEM"):
        search_plan(dem, tmp_path / "o2", f"{X0 + 10},{Y0 + 10}", "hiker", staging=f"{X0 - 10},{Y0}")
    with pytest.raises(InputError, match="not an area"):
        search_plan(dem, tmp_path / "o3", f"{X0 + 10},{Y0 + 10}", "hiker", SearchSettings(segment_size="10 parsecs"))
    assert not any((tmp_path / f"o{i}").exists() for i in (1, 2, 3))


def test_the_shipped_table_has_its_categories_in_increasing_rings():
    table = lost_person_table()
    assert {"hiker", "hunter", "dementia", "child_1_3", "despondent", "autistic"} <= {r["category"] for r in table}
    dementia = next(r for r in table if r["category"] == "dementia")
    assert dementia["ecoregion"] == "temperate_mountainous"
    # Koester's dementia, temperate mountainous, in miles: 0.2, 0.5, 1.2, 5.1
    assert dementia["rings_m"] == pytest.approx([v * 1609.344 for v in (0.2, 0.5, 1.2, 5.1)], abs=0.1)
    from gistools.products.search_plan import category_row

    assert category_row(table, "Child 1-3", "Temperate")["category"] == "child_1_3"  # as a person writes it


def test_the_sample_plan_through_the_command_line(tmp_path):
    """The shrub chain's folder of the sample, a point last seen and a staging point: one command, every output."""
    b = SAMPLE / "breaklines.gpkg"
    from gistools.products.shrub import shrub_from_tiles

    shrub_from_tiles(SAMPLE, tmp_path / "out", roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                     waterbodies=f"{b}:WATERBODY", make_map=False)
    cmd = [sys.executable, "-m", "gistools.cli.main", "search-plan", str(tmp_path / "plan"), "--dem",
           str(tmp_path / "out"), "--from", "431000,1811000", "--category", "dementia", "--staging",
           "431200,1810600", "--search-speed", "1.5", "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert "segments" in done.stdout and "litter carry out" in done.stdout
    rep = json.loads((tmp_path / "plan" / "report.json").read_text(encoding="utf-8"))
    assert rep["rings_m"] == pytest.approx([v * 1609.344 for v in (0.2, 0.5, 1.2, 5.1)], abs=0.1)
    poa, _ = _read(tmp_path / "plan" / "poa.tif")
    assert poa.sum() + rep["rest_of_world"] == pytest.approx(1.0, abs=1e-9)  # no nodata: 0 off the data
    seg = gpd.read_file(tmp_path / "plan" / "segments.gpkg", layer="segments")
    assert {"segment", "area_ha", "poa", "sweep_width_m", "hours", "coverage", "pod"} <= set(seg.columns)
    assert seg["poa"].sum() == pytest.approx(np.nansum(poa), rel=1e-9)
    for name in ("routes.gpkg", "barriers.gpkg", "segments.tif", "barriers.tif"):
        assert (tmp_path / "plan" / name).exists()
    again = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert again.returncode == 0 and "kept" in again.stdout
    other = subprocess.run(cmd[:-3] + ["--search-speed", "2", "-q"], capture_output=True, text=True, check=False)
    assert other.returncode != 0 and "Traceback" not in other.stderr and "search" in other.stderr


def test_a_thicket_is_its_own_segment_and_a_person_in_shrub_is_carried_out(tmp_path):
    """A 1 ha thicket smaller than a quarter of the target is not joined to open ground; the person last seen in
    heavy shrub beside it is carried out at the litter's own speed (minutes of the same order as the walk)."""
    n, cell = 100, 4.0
    classes = np.zeros((n, n), np.uint8)
    classes[40:65, 40:65] = 3  # 100 m x 100 m of heavy shrub: 1 ha
    dem, cls, _grid = _scene(tmp_path / "in", np.zeros((n, n)), classes, cell=cell)
    seen = f"{X0 + 41 * cell + 2},{Y0 + (n - 41) * cell - 2}"  # a cell inside the thicket, by its corner
    rep = search_plan(dem, tmp_path / "plan", seen, "test", SearchSettings(segment_size="10ha", **NO_FEATURES),
                      classes=cls, staging=f"{X0 + 10},{Y0 + 10}",
                      categories=_table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4)))
    labels, _ = _read(tmp_path / "plan" / "segments.tif")
    inside = np.unique(labels[42:63, 42:63])
    assert len(inside) == 1 and not np.isin(inside, labels[classes == 0]).any()
    assert rep["litter"] is not None and 1 < rep["litter"]["minutes"] < 60  # about 300 m at up to 1 km/h


def test_a_scarp_beside_a_hole_keeps_its_slope():
    from gistools.terrain.search import slope_degrees

    z = np.array([[0.0, 10.0, np.nan], [0.0, 10.0, np.nan]])
    s = slope_degrees(z, 5.0, 1.0)
    assert s[0, 1] == pytest.approx(math.degrees(math.atan(2.0)))  # one-sided: 10 m up over 5 m
    assert np.isnan(s[0, 2])


def test_effort_and_table_mistakes_are_one_line(tmp_path):
    from gistools.errors import DataFileError

    dem, _, _ = _scene(tmp_path / "in", np.zeros((40, 40)))
    effort = tmp_path / "e.csv"
    for text, match in (("segment,hours\n1.7,2\n", "not a whole number"), ("segment,hours\ninf,2\n", "needed"),
                        ("segment,hours\n1,-2\n", "at least 0")):
        effort.write_text(text, encoding="utf-8")
        with pytest.raises(DataFileError, match=match) as err:
            search_plan(dem, tmp_path / "o", f"{X0 + 10},{Y0 + 10}", "hiker", effort=effort)
        assert "cannot read" not in str(err.value)
    table = tmp_path / "t.csv"
    table.write_text("\ufeffcategory,ecoregion,p25_km,p50_km,p75_km,p95_km\nx,flat,0.1,0.2,0.3,0.4,extra\n",
                     encoding="utf-8")
    rep = search_plan(dem, tmp_path / "o2", f"{X0 + 10},{Y0 + 10}", "x", categories=table)
    assert rep["rings_m"] == [100.0, 200.0, 300.0, 400.0]
    assert not (tmp_path / "o" / "poa.tif").exists()


def test_walked_rings_on_flat_ground_lie_within_the_grid_bound_and_a_river_pushes_them(tmp_path):
    """--distance walk on flat open ground: the cells of each ring (one probability level each) lie between the
    ring's distances as the crow flies, up to the 16 neighbours' 2.75 %; across a river without a bridge, cells
    close as the crow flies fall to later rings."""
    from gistools.products.travel import NEIGHBOUR_BOUND

    dem, _, _ = _scene(tmp_path / "in", np.zeros((250, 250)))
    cx, cy = X0 + 500.0 + 2.0, Y0 + 500.0 + 2.0
    table = _table(tmp_path / "t.csv", (0.1, 0.2, 0.3, 0.4))
    rep = search_plan(dem, tmp_path / "plan", f"{cx},{cy}", "test", SearchSettings(distance="walk", **NO_FEATURES),
                      categories=table)
    poa, transform = _read(tmp_path / "plan" / "poa.tif")
    x, y = _centres(transform, poa.shape)
    d = np.hypot(x - cx, y - cy)
    levels = sorted({float(v) for v in poa[poa > 0]}, reverse=True)
    assert len(levels) == 4 and rep["rest_of_world"] == pytest.approx(0.05, abs=1e-9)
    bound = 1 + NEIGHBOUR_BOUND[16]
    low = 0.0
    rings = {}
    for high in (100.0, 200.0, 300.0, 400.0):  # the ring of each cell by its level
        rings[high] = (low, high)
        low = high
    for v in levels:
        cells = poa == v
        inner, outer = d[cells].min(), d[cells].max()
        ring = next(r for r in rings.values() if r[0] / bound - 4 <= inner and outer < r[1] + 1e-9)
        assert poa[cells].sum() == pytest.approx((0.25, 0.25, 0.25, 0.2)[list(rings.values()).index(ring)], abs=1e-9)
    # a river (water) 44 m east of the point, ending 100 m south of it: a cell just across it is walked round its
    # end (about 230 m: the third ring) while a cell as far on this side is in the first
    classes = np.zeros((250, 250), np.uint8)
    classes[:150, 136:139] = 5
    dem2, cls, _ = _scene(tmp_path / "in2", np.zeros((250, 250)), classes)
    search_plan(dem2, tmp_path / "plan2", f"{cx},{cy}", "test", SearchSettings(distance="walk", **NO_FEATURES),
                classes=cls, categories=table)
    poa2, _ = _read(tmp_path / "plan2" / "poa.tif")
    west, east = poa2[125, 125 - 15], poa2[125, 125 + 15]  # 60 m either way, the east one across the river
    levels2 = sorted({float(v) for v in poa2[poa2 > 0]}, reverse=True)
    assert west == levels2[0] and east in levels2[2:]  # the first ring's level; the east cell's a later ring's


def test_no_segment_is_a_cell_walled_in_or_an_island_amid_cliffs():
    """A searchable cell whose four sides are drainage cells, and one amid unsearchable cells (a ledge in a cliff),
    are not segments of their own: the first joins the segment around it, the second the nearest segment; the
    open ground around them stays one segment (1 m cells, a 400 m2 target)."""
    from gistools.terrain.search import segment_cells

    searchable = np.ones((20, 20), bool)
    searchable[3:6, 3:6] = False
    searchable[4, 4] = True  # a ledge amid cliffs
    walls = np.zeros((20, 20), bool)
    walls[13:16, 13:16] = True
    walls[14, 14] = False  # a cell walled in by drainages
    labels = segment_cells(searchable, walls, 1.0, 400.0)
    sizes = np.bincount(labels[labels > 0])
    assert labels[4, 4] > 0 and labels[14, 14] > 0
    assert sizes[labels[4, 4]] > 1 and sizes[labels[14, 14]] > 1
    assert sizes[1:].min() >= 400 // 4 // 16


def test_a_target_of_a_cell_or_two_keeps_every_cell_a_segment():
    """A target of one or two cells (a 100 m2 target on 10 m cells) cuts the area into single cells: none is
    joined to another, however small."""
    from gistools.terrain.search import segment_cells

    walls = np.zeros((12, 12), bool)
    for cell, target in ((1.0, 1.0), (1.0, 2.0), (10.0, 100.0)):
        labels = segment_cells(np.ones((12, 12), bool), walls, cell, target)
        assert labels.max() == 144 and np.bincount(labels.ravel())[1:].max() == 1, (cell, target)
