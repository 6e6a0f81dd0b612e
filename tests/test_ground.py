"""gistools ground: noise and ground classes on scenes of known ground, tiled == merged, nothing else changed,
virtual point clouds and COPC, and DEM quality on the real files of ../shared/data."""

from __future__ import annotations

import json
from pathlib import Path

import laspy
import numpy as np
import pytest
from click.testing import CliRunner

from conftest import AUTZEN, MEGAPLOT, SHARED_DATA, need_shared, need_kernel
from gistools.cli.main import cli
from gistools.io.points import read_tile_info, write_tile
from gistools.lidar.ground import SmrfParams, classify_ground_and_noise, smrf_ground
from gistools.products.ground import GroundSettings, ground_from_tiles

SAMPLE = Path(__file__).resolve().parents[1] / "sample_tiles"
LASR = SHARED_DATA / "lidar" / "lasr"
FIELDS = ("x", "y", "z", "return_number", "number_of_returns", "classification", "intensity", "gps_time")


def _scene(seed=1, n=300_000):
    """A 300 m square in metres: a 30 % slope, 2 m terraces on its north half, 20 m buildings 8 m high, shrub
    0.5-2 m on 30 % of the points; the truth is which points lie on the ground."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, 300, n), rng.uniform(0, 300, n)
    ground = 0.30 * x + np.where(y > 150, 2.0 * np.floor(x / 40), 0) + 0.5 * np.sin(y / 20)
    z = ground + rng.normal(0, 0.03, n)
    truth = np.ones(n, bool)
    building = ((x % 100) > 40) & ((x % 100) < 60) & ((y % 100) > 40) & ((y % 100) < 60) & (y < 150)
    z[building] += 8
    shrub = (rng.uniform(size=n) < 0.3) & ~building
    z[shrub] += rng.uniform(0.5, 2, shrub.sum())
    truth[building | shrub] = False
    return x, y, z, truth, ground


def test_smrf_finds_the_ground_of_a_scene_with_slopes_terraces_buildings_and_shrub():
    x, y, z, truth, _ = _scene()
    ground, _ = smrf_ground(x, y, z, np.ones(len(x), bool), SmrfParams(cell=1, slope=0.1, window=18, threshold=0.15,
                                                                       scalar=0.5))
    type1 = np.mean(~ground[truth])  # ground called non-ground
    type2 = np.mean(ground[~truth])  # objects called ground
    assert type1 < 0.03 and type2 < 0.02, (type1, type2)
    # PDAL's defaults on the same scene take much of the shrub for ground (why the defaults differ)
    pdal, _ = smrf_ground(x, y, z, np.ones(len(x), bool), SmrfParams(cell=1, slope=0.15, window=18, threshold=0.5,
                                                                     scalar=1.25))
    assert np.mean(pdal[~truth]) > 0.1


def test_injected_noise_is_found_and_real_points_are_not():
    x, y, z, truth, ground = _scene(seed=2)
    rng = np.random.default_rng(3)
    k = 600
    pick = rng.choice(len(x), k, replace=False)
    nx, ny = x[pick] + rng.normal(0, 0.2, k), y[pick] + rng.normal(0, 0.2, k)
    low = np.arange(k) < k // 2
    gz = 0.30 * nx + np.where(ny > 150, 2.0 * np.floor(nx / 40), 0) + 0.5 * np.sin(ny / 20)
    nz = np.where(low, gz - rng.uniform(20, 50, k), gz + rng.uniform(30, 80, k))  # multipath below, birds above
    nz[:20] = nz[0] + rng.normal(0, 0.3, 20)  # a cluster of 20 low points together: IVF alone keeps them
    nx[:20], ny[:20] = nx[0] + rng.normal(0, 1, 20), ny[0] + rng.normal(0, 1, 20)
    X, Y, Z = np.r_[x, nx], np.r_[y, ny], np.r_[z, nz]
    ones = np.ones(len(X), np.uint8)
    cls = classify_ground_and_noise(X, Y, Z, ones, ones, ones, method="smrf",
                                    smrf=SmrfParams(cell=1, slope=0.1, window=18, threshold=0.15, scalar=0.5))
    noise = cls[len(x):]
    assert np.mean(np.isin(noise, (7, 18))) >= 0.99
    assert np.mean(noise[low] == 7) >= 0.99 and np.mean(noise[~low] == 18) >= 0.99
    assert np.mean(np.isin(cls[: len(x)], (7, 18))) <= 0.005


def _wiped(tiles, folder: Path) -> list[Path]:
    crs = read_tile_info(tiles[0]).crs
    out = []
    for p in tiles:
        las = laspy.read(p)
        d = {k: np.asarray(getattr(las, k)) for k in FIELDS}
        d["classification"] = np.ones(len(las.x), np.uint8)
        out.append(write_tile(folder / f"{p.stem}.las", d, crs, version="1.2", point_format=1,
                              offsets=[430000.0, 1810000.0, 0.0]))
    return out


@pytest.mark.parametrize("method", ["smrf", "smrftin", "adaptive"])
def test_a_tiled_run_equals_the_run_on_the_merged_tiles(tmp_path, method):
    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    wiped = _wiped(tiles, tmp_path / "tiles")
    merged = {k: np.concatenate([np.asarray(getattr(laspy.read(p), k)) for p in wiped]) for k in FIELDS}
    write_tile(tmp_path / "merged" / "all.las", merged, read_tile_info(tiles[0]).crs, version="1.2", point_format=1,
               offsets=[430000.0, 1810000.0, 0.0])
    tiled = ground_from_tiles(tmp_path / "tiles", tmp_path / "out_tiled", GroundSettings(method=method))
    assert tiled["counts"]["ok"] == 4
    assert all(len(t["neighbours"]) == 3 for t in tiled["tiles"])
    ground_from_tiles(tmp_path / "merged", tmp_path / "out_merged", GroundSettings(method=method))
    a = np.concatenate([np.asarray(laspy.read(tmp_path / "out_tiled" / f"{p.stem}.laz").classification) for p in wiped])
    b = np.asarray(laspy.read(tmp_path / "out_merged" / "all.laz").classification)
    assert np.array_equal(a, b)
    # against the delivered ground of the sample (the generator's truth), on land: its water (class 9, 2.7 % of
    # the points) is wiped with the rest, and a flat water surface is ground to a filter that is not told of it
    delivered = np.concatenate([np.asarray(laspy.read(p).classification) for p in tiles])
    land = delivered != 9
    assert np.mean(((a == 2) == (delivered == 2))[land]) > 0.99


def test_a_large_surveys_noise_measured_in_blocks_is_the_same_tiled_and_merged(tmp_path, monkeypatch):
    """smrftin measures the noise of a survey of 4 x NOISE_POINTS points or more in every stride-th block of 100 m
    each way: the same noise and classes tiled and merged, and the noise within a millimetre of that of every point.
    The sample (258,950 points) stands in for a large survey: NOISE_POINTS lowered to 60,000 (every 2nd block)."""
    from gistools.lidar import ground as lg

    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    wiped = _wiped(tiles, tmp_path / "tiles")
    merged = {k: np.concatenate([np.asarray(getattr(laspy.read(p), k)) for p in wiped]) for k in FIELDS}
    crs = read_tile_info(tiles[0]).crs
    write_tile(tmp_path / "merged" / "all.las", merged, crs, version="1.2", point_format=1,
               offsets=[430000.0, 1810000.0, 0.0])
    monkeypatch.setattr(lg, "NOISE_POINTS", 60_000)
    assert lg.noise_stride(len(merged["x"])) == 2
    tiled = ground_from_tiles(tmp_path / "tiles", tmp_path / "out_tiled", GroundSettings(method="smrftin"))
    whole = ground_from_tiles(tmp_path / "merged", tmp_path / "out_merged", GroundSettings(method="smrftin"))
    assert tiled["counts"]["ok"] == 4
    assert tiled["units"]["ground_noise"] == whole["units"]["ground_noise"]
    a = np.concatenate([np.asarray(laspy.read(tmp_path / "out_tiled" / f"{p.stem}.laz").classification) for p in wiped])
    assert np.array_equal(a, np.asarray(laspy.read(tmp_path / "out_merged" / "all.laz").classification))
    # against the noise measured on every point (the library, one stride)
    from gistools.products.ground import _params

    p = _params(GroundSettings(method="smrftin"), read_tile_info(wiped[0]))
    every = lg.noise_from_histogram(lg.survey_noise_histogram(
        merged["x"], merged["y"], merged["z"], merged["return_number"], merged["number_of_returns"],
        merged["classification"], np.ones(len(merged["x"]), bool), p.smrftin, p.noise, p.z_metres, 1), p.z_metres)
    assert abs(tiled["units"]["ground_noise"] - every) * p.z_metres <= 0.001


def test_noise_blocks_that_miss_the_surveys_ground_give_way_to_every_point(tmp_path, monkeypatch):
    """A survey too small for the blocks of its stride (here the sample with NOISE_POINTS lowered to 4,000: every
    8th block of 100 m, one block reaching the sample) is measured on every point: the noise of the whole, tiled
    and merged, and the library's call on the merged arrays gives the command's classes."""
    from gistools.lidar import ground as lg
    from gistools.products.ground import _params

    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    wiped = _wiped(tiles, tmp_path / "tiles")
    merged = {k: np.concatenate([np.asarray(getattr(laspy.read(p), k)) for p in wiped]) for k in FIELDS}
    monkeypatch.setattr(lg, "NOISE_POINTS", 4_000)
    assert lg.noise_stride(len(merged["x"])) == 8
    p = _params(GroundSettings(method="smrftin"), read_tile_info(wiped[0]))
    fields = (merged["x"], merged["y"], merged["z"], merged["return_number"], merged["number_of_returns"],
              merged["classification"], np.ones(len(merged["x"]), bool), p.smrftin, p.noise, p.z_metres)
    assert 0 < lg.survey_noise_histogram(*fields, 8).sum() < lg.NOISE_ENOUGH  # the blocks alone: too few
    every = lg.noise_from_histogram(lg.survey_noise_histogram(*fields, 1), p.z_metres)
    tiled = ground_from_tiles(tmp_path / "tiles", tmp_path / "out_tiled", GroundSettings(method="smrftin"))
    assert tiled["units"]["ground_noise"] == every
    got = np.concatenate([np.asarray(laspy.read(tmp_path / "out_tiled" / f"{q.stem}.laz").classification)
                          for q in wiped])
    lib = classify_ground_and_noise(merged["x"], merged["y"], merged["z"], merged["return_number"],
                                    merged["number_of_returns"], merged["classification"], method="smrftin",
                                    smrftin=p.smrftin, noise=p.noise, z_metres=p.z_metres)
    assert np.array_equal(got, lib)


def _same_points_but_classes(src: Path, dst: Path):
    a, b = laspy.read(src), laspy.read(dst)
    assert a.header.point_format.id == b.header.point_format.id and str(a.header.version) == str(b.header.version)
    assert list(a.point_format.dimension_names) == list(b.point_format.dimension_names)
    for name in a.point_format.dimension_names:
        if name != "classification":
            assert np.array_equal(np.asarray(a[name]), np.asarray(b[name])), name
    assert [v.record_id for v in a.header.vlrs] == [v.record_id for v in b.header.vlrs]
    return a, b


def test_point_order_and_every_other_attribute_are_kept(tmp_path):
    ground_from_tiles(SAMPLE, tmp_path / "out")
    for p in sorted(SAMPLE.glob("*.la[sz]")):
        a, b = _same_points_but_classes(p, tmp_path / "out" / f"{p.stem}.laz")
        water = np.asarray(a.classification) == 9
        assert np.array_equal(np.asarray(b.classification)[water], np.asarray(a.classification)[water])  # others kept


@pytest.mark.parametrize("name", ["las14_pdrf6.laz", "extra_byte.las"])
def test_las14_point_format_6_and_extra_bytes_round_trip(tmp_path, name):
    need_shared(LASR)
    src = LASR / name
    fmt = "las" if name.endswith(".las") else "laz"
    r = CliRunner().invoke(cli, ["ground", str(src), "--out", str(tmp_path / "out"), "--crs", "EPSG:26917", "-q",
                                 "--format", fmt])
    assert r.exit_code == 0, r.output
    _, b = _same_points_but_classes(src, tmp_path / "out" / f"{src.stem}.{fmt}")
    if name == "extra_byte.las":
        assert "Amplitude" in b.point_format.extra_dimension_names


def test_the_vpc_follows_the_spec_and_is_an_input(tmp_path):
    report = ground_from_tiles(SAMPLE, tmp_path / "out")
    vpc = json.loads(Path(report["vpc"]).read_text())
    assert vpc["type"] == "FeatureCollection" and len(vpc["features"]) == 4
    for item in vpc["features"]:
        props = item["properties"]
        assert item["stac_version"] == "1.0.0" and item["type"] == "Feature"
        assert props["pc:count"] == laspy.open(tmp_path / "out" / item["assets"]["data"]["href"]).header.point_count
        assert props["proj:epsg"] == 2882 and "PROJCRS" in props["proj:wkt2"]
        assert len(props["proj:bbox"]) == 6 and props["proj:geometry"]["type"] == "Polygon"
        lon0, lat0, _, lon1, lat1, _ = item["bbox"]
        assert -83.5 < lon0 < lon1 < -82 and 28 < lat0 < lat1 < 30  # Florida West, in WGS84
        assert item["assets"]["data"]["href"].startswith("./")
    r = CliRunner().invoke(cli, ["rasters", report["vpc"], "--out", str(tmp_path / "r"), "-q"])
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "r" / "dem").glob("*.tif"))) == 4


def test_a_copc_file_is_read_by_bounds():
    need_shared(LASR)
    from gistools.io.points import points_in_box

    src = LASR / "example.copc.laz"
    info = read_tile_info(src, "EPSG:26917")
    assert info.copc and not read_tile_info(sorted(SAMPLE.glob("*.las"))[0], None).copc  # its "copc" record
    las = laspy.read(src)
    x, y = np.asarray(las.x), np.asarray(las.y)
    box = (float(np.median(x)), float(y.min()), float(x.max()) + 10, float(np.median(y)))
    got = points_in_box(info, box)
    want = (x >= box[0]) & (x <= box[2]) & (y >= box[1]) & (y <= box[3])
    assert 0 < len(got["x"]) == want.sum()
    assert sorted(got["z"]) == sorted(np.asarray(las.z)[want])


TOPOGRAPHY, MIXED_CONIFER = (SHARED_DATA / "lidar" / "lidr" / f for f in ("Topography.laz", "MixedConifer.laz"))
SURVEYS = [("smrf", AUTZEN), ("smrf", MEGAPLOT), ("smrftin", AUTZEN), ("smrftin", MEGAPLOT),
           *(("adaptive", q) for q in (AUTZEN, MEGAPLOT, TOPOGRAPHY, MIXED_CONIFER))]


@pytest.mark.parametrize("method,path", SURVEYS, ids=[f"{m}-{q.stem}" for m, q in SURVEYS])
def test_dem_from_classified_ground_is_close_to_the_providers_on_real_files(tmp_path, path, method):
    """Wipe the classes, classify, and compare TIN DEMs at 1 m from our ground and from the provider's. The
    default (adaptive) holds the ground lines on every real survey: mean bias within +-0.05 m, RMSE <= 0.15 m, but
    on Topography, where the provider's ground is one in about three of the returns at ground level (its DEM is
    the coarser one) and the default's RMSE is 0.19 m. smrftin holds them on autzen and Megaplot. On Topography the
    default keeps the provider's ground in the hollows of its rough floor (down to three thresholds below its
    surface): at most a fifth of it is left out (29 % with SMRF's symmetric test)."""
    need_shared(path)
    from gistools.grid import snapped_grid
    from gistools.lidar.gridding import dem_from_ground_points

    las = laspy.read(path)
    info = read_tile_info(path)
    d = {k: np.asarray(getattr(las, k)) for k in FIELDS if k in "xyz" or k in las.point_format.dimension_names}
    truth = d["classification"] == 2
    d["classification"] = np.ones(len(las.x), np.uint8)
    wiped = write_tile(tmp_path / "in" / "tile.las", d, info.crs, version="1.2", point_format=1,
                       offsets=list(las.header.offsets), scale=float(las.header.scales[0]))
    report = ground_from_tiles(wiped, tmp_path / "out", GroundSettings(method=method))
    ours = np.asarray(laspy.read(tmp_path / "out" / "tile.laz").classification) == 2
    m = 1 / info.unit.metres
    x, y, z = d["x"], d["y"], d["z"]
    grid = snapped_grid((x.min(), y.min(), x.max(), y.max()), 1 * m)
    ref = dem_from_ground_points(x[truth], y[truth], z[truth], grid, max_distance=10 * m)
    new = dem_from_ground_points(x[ours], y[ours], z[ours], grid, max_distance=10 * m)
    both = np.isfinite(ref) & np.isfinite(new)
    err = (new - ref)[both] * info.z_unit.metres
    assert both.sum() > 0.95 * np.isfinite(ref).sum()
    rmse, bias = np.sqrt(np.mean(err ** 2)), np.mean(err)
    if method == "adaptive":
        assert rmse <= (0.20 if path == TOPOGRAPHY else 0.15) and abs(bias) <= 0.05, (rmse, bias)
        if path == TOPOGRAPHY:
            assert np.count_nonzero(truth & ~ours) <= 0.20 * np.count_nonzero(truth)
        multi = np.mean(d["number_of_returns"] >= 2)  # the canopy measure, counted here
        assert report["units"]["multi_return_share"] == pytest.approx(multi)
        assert report["units"]["cell"] * info.unit.metres == pytest.approx(1.75 if multi >= 0.10 else 1.5)
    elif method == "smrftin":
        assert rmse <= 0.15 and abs(bias) <= 0.05, (rmse, bias)
        # the provider's ground of Megaplot is exactly z = 0 (heights already normalised): no noise to measure
        assert report["units"]["ground_noise"] * info.z_unit.metres < (0.005 if path == MEGAPLOT else 0.04)
    else:
        assert rmse <= 0.20 and np.percentile(np.abs(err), 95) <= 0.45


def test_plane_residuals_equal_least_squares_planes_through_qhulls_delaunay_neighbours():
    """Each point against the plane through its Delaunay neighbours: the kernel's triangles and the closed-form
    normal equations against scipy's Qhull triangulation and numpy.linalg.lstsq per point (inner points)."""
    from scipy.spatial import Delaunay

    from gistools.lidar.ground import plane_residuals

    rng = np.random.default_rng(4)
    x, y = rng.uniform(500000, 500200, 3000), rng.uniform(4100000, 4100200, 3000)
    z = 100 + 0.2 * (x - 500000) - 0.1 * (y - 4100000) + rng.normal(0, 0.05, 3000)
    got = plane_residuals(x, y, z)
    tri = Delaunay(np.column_stack([x - 500000, y - 4100000]))
    indptr, nb = tri.vertex_neighbor_vertices
    want = np.full(len(x), np.nan)
    inner = np.setdiff1d(np.arange(len(x)), tri.convex_hull.ravel())  # a hull point leaves out one hull neighbour
    for i in inner:
        j = nb[indptr[i]:indptr[i + 1]]
        a = np.column_stack([np.ones(len(j)), x[j] - x[i], y[j] - y[i]])
        want[i] = z[i] - (z[i] + np.linalg.lstsq(a, z[j] - z[i], rcond=None)[0][0])
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got[inner], want[inner], atol=1e-9)


def test_plane_residuals_of_the_kernel_are_those_of_its_numpy_form_bit_for_bit():
    """The compiled pass and the numpy form (installs without a C compiler) give the same float64 residuals, repeated
    positions (no triangle: NaN) and a straight hull edge included."""
    from gistools.lidar import ground
    from gistools.lidar.tin import delaunay_triangles

    need_kernel()
    rng = np.random.default_rng(12)
    x, y = rng.uniform(0, 300, 5000), rng.uniform(0, 300, 5000)
    x[:40], y[:40] = np.arange(40) * 7.5, 0.0  # collinear points along the hull
    x[100:110], y[100:110] = x[90:100], y[90:100]  # repeated positions
    z = 30 + 0.3 * x + rng.normal(0, 0.05, 5000)
    got = ground.plane_residuals(x, y, z)
    want = ground._plane_residuals_numpy(x, y, z, delaunay_triangles(x, y), np.full(len(x), np.nan))
    assert np.isnan(got).sum() >= 10
    assert np.array_equal(got, want, equal_nan=True)


def test_raised_patches_of_the_kernel_are_those_of_its_numpy_form_and_find_roofs_not_terraces():
    """The compiled pass (union-find) and the numpy form (scipy's connected components) mark the same points, on
    rolling ground with roofs, a terrace step, a pit and empty cells; the roofs (narrower than the patch width,
    standing above all around) are marked, the terrace (joined to the ground along its length) and the ground are
    not."""
    from gistools.lidar import ground

    need_kernel()
    rng = np.random.default_rng(5)
    n = 60_000
    x, y = rng.uniform(0, 400, n), rng.uniform(0, 300, n)
    z = 100 + 0.05 * x + 2 * np.sin(y / 40) + rng.normal(0, 0.05, n)
    roofs = np.zeros(n, bool)
    for cx, cy in ((80, 80), (200, 150), (320, 240), (120, 250)):
        on = (np.abs(x - cx) < 12) & (np.abs(y - cy) < 8)
        z[on] += 6
        roofs |= on
    terrace = (x > 250) & (y < 100)
    z[terrace] += 3  # a step along its whole length: joins the ground beyond its far sides
    pit = (np.hypot(x - 40, y - 200) < 3)
    z[pit] -= 4
    keep = ~((x > 150) & (x < 170) & (y > 20) & (y < 60))  # empty cells (a pond)
    x, y, z, roofs, terrace = x[keep], y[keep], z[keep], roofs[keep], terrace[keep]
    is_ground = rng.uniform(size=len(x)) < 0.9
    args = (x, y, z, is_ground, 1.5, 1.0, 60.0)
    got = ground.raised_patches(*args)
    zimin, _c, _r, flat = ground.min_surface(x[is_ground], y[is_ground], z[is_ground], 1.5)
    want = np.zeros(len(x), bool)
    want[np.flatnonzero(is_ground)[ground._raised_cells_numpy(zimin, 1.5, 1.0, 60.0)[flat]]] = True
    assert np.array_equal(got, want)
    assert np.mean(got[roofs & is_ground]) > 0.95
    assert not got[terrace & ~roofs].any()
    assert not got[~roofs].any()


@pytest.mark.parametrize("unit", [1.0, 0.3048])
def test_the_measured_ground_noise_is_the_noise_of_a_tilted_plane(unit):
    """Ground of a known normal noise (4 cm) on a 20 % slope, in metres and in feet: the measured noise is that
    standard deviation, up to what the neighbours' plane adds (sqrt(1 + 1/6), about 8 %)."""
    from gistools.lidar.ground import noise_from_histogram, noise_histogram, plane_residuals

    rng = np.random.default_rng(9)
    n, sigma = 40_000, 0.04
    x, y = rng.uniform(0, 400, n), rng.uniform(0, 400, n)
    z = 0.2 * x + rng.normal(0, sigma, n)
    got = noise_from_histogram(noise_histogram(plane_residuals(x / unit, y / unit, z / unit), unit), unit) * unit
    assert sigma <= got <= 1.15 * sigma, got


def test_a_rerun_that_keeps_finished_tiles_classifies_the_others_as_a_whole_run(tmp_path):
    """smrftin measures the survey's noise over every tile, the kept ones too: a rerun after an interrupted run makes
    the remaining tiles exactly as the complete run made them."""
    import shutil

    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    _wiped(tiles, tmp_path / "tiles")
    whole = ground_from_tiles(tmp_path / "tiles", tmp_path / "whole", GroundSettings(method="smrftin"))
    (tmp_path / "part").mkdir()
    for p in tiles[:2]:  # the first two were finished before the interruption
        shutil.copy(tmp_path / "whole" / f"{p.stem}.laz", tmp_path / "part" / f"{p.stem}.laz")
    again = ground_from_tiles(tmp_path / "tiles", tmp_path / "part", GroundSettings(method="smrftin"))
    assert again["counts"]["skipped"] == 2 and again["counts"]["ok"] == 2
    assert again["units"]["ground_noise"] == whole["units"]["ground_noise"]
    for p in tiles[2:]:
        assert np.array_equal(np.asarray(laspy.read(tmp_path / "part" / f"{p.stem}.laz").classification),
                              np.asarray(laspy.read(tmp_path / "whole" / f"{p.stem}.laz").classification))


def test_bad_options_are_refused_before_anything_is_written(tmp_path):
    for args in (["--slope", "-1"], ["--method", "magic"], ["--cell", "0m"], ["--format", "e57"]):
        r = CliRunner().invoke(cli, ["ground", str(SAMPLE), "--out", str(tmp_path / "o"), "-q", *args])
        assert r.exit_code != 0
        assert not (tmp_path / "o").exists()
    with pytest.raises(Exception, match="csf_rigidness"):  # a Python call: the message names the argument
        GroundSettings(csf_rigidness=5).validate()


def test_info_shows_files_without_a_crs_or_with_a_broken_one(tmp_path):
    need_shared(LASR)
    r = CliRunner().invoke(cli, ["info", str(LASR / "extra_byte.las"), "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.output)[0]
    assert s["crs"] == "no CRS" and "has no CRS" in s["crs_note"] and s["points"] == 62
    r = CliRunner().invoke(cli, ["info", str(LASR / "las14_pdrf6.laz"), "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.output[r.output.index("["):])[0]
    assert "compound CRS should have at least 2 components" in s["crs_note"] and "horizontal part" in s["crs_note"]
    assert "UTM" in s["crs"] and s["horizontal_unit"].startswith("metre")
    # a command that needs the CRS names what is wrong, not "no CRS" for a broken one
    r = CliRunner().invoke(cli, ["rasters", str(LASR / "extra_byte.las"), "--out", str(tmp_path / "r"), "-q"])
    assert r.exit_code == 1 and "header has no CRS" in r.output


def test_the_shrub_chain_on_tiles_without_ground_classes_matches_the_delivered_classes(tmp_path):
    """--classify-ground smrf on the sample with every class wiped (all points 1, water returns included: the
    chain marks those inside its water polygons 9 before the ground filter): every class area within 3 % of the
    run on the delivered classes."""
    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    crs = read_tile_info(tiles[0]).crs
    for p in tiles:
        las = laspy.read(p)
        d = {k: np.asarray(getattr(las, k)) for k in FIELDS}
        d["classification"] = np.ones(len(las.x), np.uint8)
        write_tile(tmp_path / "raw" / f"{p.stem}.las", d, crs, version="1.2", point_format=1,
                   offsets=[430000.0, 1810000.0, 0.0])
    b = SAMPLE / "breaklines.gpkg"
    vectors = ["--roads", f"{b}:ROADBREAKLINE", "--hydro", f"{b}:HYDROGRAPHICFEATURE", "--waterbodies", f"{b}:WATERBODY",
               "--wetlands", f"{b}:WETLAND", "--tile-index", f"{b}:FOOTPRINT", "-q", "--no-map"]
    areas = {}
    for name, src, extra in (("delivered", SAMPLE, []), ("classified", tmp_path / "raw", ["--classify-ground", "smrf"])):
        r = CliRunner().invoke(cli, ["shrub", str(src), "--out", str(tmp_path / name), *vectors, *extra])
        assert r.exit_code == 0, r.output
        areas[name] = json.loads((tmp_path / name / "report.json").read_text())["class_area"]
    assert (tmp_path / "classified" / "classified" / "ground.vpc").exists()
    for cls, area in areas["delivered"].items():
        assert areas["classified"][cls] == pytest.approx(area, rel=0.03), cls


def test_the_compiled_morphology_equals_the_numpy_one(monkeypatch):
    """The kernel's progressive filter and gap filling give the values of the numpy code they replace."""
    from gistools.lidar import ground as G

    if G._PROGRESSIVE is None or G._FILL is None:
        need_kernel()
    rng = np.random.default_rng(3)
    a = np.cumsum(rng.normal(size=(300, 400)), axis=1) * 0.1 + rng.uniform(0, 3, (300, 400)) * (rng.uniform(size=(300, 400)) < 0.2)
    holes = a.copy()
    holes[rng.uniform(size=a.shape) < 0.5] = np.nan
    holes[100:150, 100:180] = np.nan
    compiled = G.progressive_filter(a, 1.0, 0.15, 18.0), G.fill_gaps(holes)
    monkeypatch.setattr(G, "_PROGRESSIVE", None)
    monkeypatch.setattr(G, "_FILL_FRONT", None)  # the ring kernel over the whole grid, then numpy
    assert np.array_equal(G.fill_gaps(holes), compiled[1], equal_nan=True)
    monkeypatch.setattr(G, "_FILL", None)
    assert np.array_equal(G.progressive_filter(a, 1.0, 0.15, 18.0), compiled[0])
    assert np.array_equal(G.fill_gaps(holes), compiled[1])
    for rings in (1, 3):  # the front kernel stops after the same rings
        monkeypatch.undo()
        few = G.fill_gaps(holes, rings)
        monkeypatch.setattr(G, "_FILL_FRONT", None)
        monkeypatch.setattr(G, "_FILL", None)
        assert np.array_equal(G.fill_gaps(holes, rings), few)


@pytest.mark.parametrize("shape", [(300, 400), (1, 50), (40, 1), (2, 2)])
def test_the_compiled_point_steps_of_smrf_equal_the_numpy_ones(monkeypatch, shape):
    """Sampling the surfaces at the points, the slope threshold and ZIfin's cell means: the kernel's values are the
    numpy code's, to the bit (the same operations in the same order), on grids of one row or column too."""
    from gistools.lidar import ground as G

    if G._BILINEAR is None:
        need_kernel()
    rng = np.random.default_rng(5)
    n = 20 * shape[0] * shape[1]
    x, y = rng.uniform(0, shape[1], n) + 1000.0, rng.uniform(0, shape[0], n) + 5000.0
    z = np.sin(x / 7.0) * 3 + y * 0.05 + rng.normal(0, 0.1, n) + rng.uniform(0, 4, n) * (rng.uniform(size=n) < 0.3)
    cand = rng.uniform(size=n) < 0.8
    p = G.SmrfParams(cell=1.0, slope=0.15, window=18.0, threshold=0.5, scalar=1.25)
    compiled = G.smrf_ground(x, y, z, cand, p)
    for name in ("_BILINEAR", "_SLOPE_THRESHOLD", "_CELL_MEAN"):
        monkeypatch.setattr(G, name, None)
    if min(shape) > 1:  # numpy.gradient needs two cells along each axis; the kernel takes a flat surface there
        numpy = G.smrf_ground(x, y, z, cand, p)
        assert np.array_equal(numpy[0], compiled[0]) and np.array_equal(numpy[1], compiled[1])
    assert compiled[0][cand].mean() > 0.5


@pytest.mark.parametrize("shape", [(7, 5), (129, 40), (257, 3), (1, 60)])
def test_the_striped_dilations_equal_the_numpy_ones_at_stripe_edges(monkeypatch, shape):
    from gistools.lidar import ground as G

    if G._PROGRESSIVE is None:
        need_kernel()
    a = np.random.default_rng(4).normal(0, 3, shape).cumsum(0)
    compiled = G.progressive_filter(a, 1.0, 0.15, 40.0)
    monkeypatch.setattr(G, "_PROGRESSIVE", None)
    assert np.array_equal(G.progressive_filter(a, 1.0, 0.15, 40.0), compiled)


def test_ivf_counts_from_the_voxel_grid_equal_the_sorted_key_search(monkeypatch):
    # the dense count grid (tiles) and the sparse search (extents too large for a grid) count the same neighbours
    from gistools.lidar import noise as N

    rng = np.random.default_rng(8)
    x, y, z = rng.uniform(0, 900, 60000), rng.uniform(0, 900, 60000), rng.normal(100, 8, 60000)
    z[:40] -= 250  # multipath far below, and a few lone points far out
    x[40:50] += 2000
    for res in (1.0, 5.0, 15.0):
        dense = N.isolated_points(x, y, z, res=res, n=6)
        monkeypatch.setattr(N, "_DENSE_VOXELS", 0)
        sparse = N.isolated_points(x, y, z, res=res, n=6)
        monkeypatch.undo()
        assert np.array_equal(dense, sparse) and dense[:50].all()


def test_copc_output_is_read_back_by_bounds_with_the_classes_of_the_laz_output(tmp_path):
    pytest.importorskip("copclib")
    laz = ground_from_tiles(SAMPLE, tmp_path / "laz")
    copc = ground_from_tiles(SAMPLE, tmp_path / "copc", GroundSettings(format="copc"))
    assert copc["counts"]["ok"] == 4 and json.loads(Path(copc["vpc"]).read_text())["features"][0]["assets"]["data"][
        "href"].endswith(".copc.laz")
    for t in laz["tiles"]:
        ref = laspy.read(t["output"])
        path = tmp_path / "copc" / f"{t['name']}.copc.laz"
        x, y = np.asarray(ref.x), np.asarray(ref.y)
        w, e = np.percentile(x, [20, 55])
        s, n = np.percentile(y, [30, 70])
        with laspy.CopcReader.open(path) as reader:
            assert reader.header.point_format.id == 6 and str(reader.header.version) == "1.4"
            # the CRS in a regular VLR (where QGIS looks), with the WKT bit set
            assert any(v.record_id == 2112 for v in reader.header.vlrs) and reader.header.global_encoding.wkt
            assert reader.header.parse_crs().to_epsg() == 2882
            every = reader.query()
            part = reader.query(laspy.copc.Bounds(np.array([w, s]), np.array([e, n])))
        inside = (x >= w) & (x <= e) & (y >= s) & (y <= n)
        assert len(every) == len(x) and len(part) == inside.sum()
        # the same points with the same classes, in the octree's order
        key = lambda p: np.lexsort((np.asarray(p.gps_time), np.asarray(p.z), np.asarray(p.y), np.asarray(p.x)))  # noqa: E731
        a, b = key(ref), key(every)
        assert np.array_equal(np.asarray(ref.classification)[a], np.asarray(every.classification)[b])
        assert np.allclose(np.asarray(ref.x)[a], np.asarray(every.x)[b])


def test_a_damaged_neighbour_fails_alone_and_the_others_say_what_they_missed(tmp_path):
    import shutil

    tiles = tmp_path / "tiles"
    shutil.copytree(SAMPLE, tiles)
    good = (tiles / "35813.laz").read_bytes()
    (tiles / "35813.laz").write_bytes(good[: int(len(good) * 0.6)])  # the header reads, the points do not
    r = CliRunner().invoke(cli, ["ground", str(tiles), "--out", str(tmp_path / "out"), "-q"])
    assert r.exit_code == 1 and "35813" in r.output
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    by = {t["name"]: t for t in report["tiles"]}
    assert by["35813"]["status"] == "failed"
    for name in ("35712", "35713", "35812"):
        assert by[name]["status"] == "ok" and any("35813" in w for w in by[name]["warnings"])
    assert not list((tmp_path / "out").glob(".gistools-scratch-*"))  # the strips' scratch folder is gone


@pytest.mark.parametrize("shape", [(1, 7), (6, 1), (1, 1), (5, 8)])
def test_the_slope_thresholds_numpy_form_equals_the_kernels_on_grids_of_one_row_or_column(shape, monkeypatch):
    """The numpy form (where the kernel is not built) on grids one cell wide, as a small tile's edge gives: no
    slope along an axis of one cell, the kernel's values exactly."""
    from gistools import kernel
    from gistools.lidar import ground

    if not kernel.loaded():
        pytest.fail("the compiled kernel is not built: the numpy form has nothing to be checked against")
    z = np.random.default_rng(5).normal(100, 3, shape)
    p = ground.SmrfParams(cell=1.5, slope=0.15, window=24.0, threshold=0.4, scalar=1.0, z_per_xy=1.0)
    compiled = ground.slope_threshold(z, p)
    monkeypatch.setattr(ground, "_SLOPE_THRESHOLD", None)
    np.testing.assert_allclose(ground.slope_threshold(z, p), compiled, rtol=0, atol=1e-12)


def _cloth_scene(n: int = 120_000):
    """A 300 m square of ground on a slope with 40 % of the points on 2-12 m canopy above it (metres)."""
    rng = np.random.default_rng(5)
    x, y = rng.uniform(0, 300, n), rng.uniform(0, 300, n)
    ground = rng.random(n) > 0.4
    z = 0.05 * x + rng.normal(0, 0.03, n) + np.where(ground, 0.0, rng.uniform(2, 12, n))
    return x, y, z, ground


def test_csf_from_the_main_process_runs_in_a_helper_that_leaves_the_interpreter_free():
    """The cloth library holds the interpreter's lock for its whole call: from the main process it runs in a helper
    process, so another thread of this process keeps running throughout (a stop signal's watchdog, QGIS's Cancel),
    and its ground is the library's own call's, in this process, point for point."""
    import threading
    import time

    pytest.importorskip("CSF")
    from gistools.lidar.cloth import cloth_ground_indices
    from gistools.lidar.ground import CsfParams, csf_ground

    x, y, z, truth = _cloth_scene()
    p = CsfParams(resolution=0.5)
    ticks, done = [], threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.02)

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    started = time.monotonic()
    got = csf_ground(x, y, z, np.ones(len(x), bool), p)
    took = time.monotonic() - started
    done.set()
    ticker.join()
    gaps = np.diff([started, *ticks])
    assert took > 0.5 and gaps.max() < 0.5, (took, gaps.max())  # the thread ran all along
    pts = np.column_stack([x, y, z])
    settings = {"bSloopSmooth": p.slope_smooth, "cloth_resolution": p.resolution, "class_threshold": p.threshold,
                "rigidness": p.rigidness, "time_step": p.time_step, "interations": p.iterations}
    direct = np.zeros(len(x), bool)
    direct[cloth_ground_indices(pts - pts.min(axis=0), settings)] = True
    np.testing.assert_array_equal(got, direct)
    assert (got == truth).mean() > 0.95  # and it is ground: the slope under the canopy


def test_a_csf_helper_killed_between_calls_is_replaced_and_the_run_ends_it():
    """The system ending the helper between two tiles (out of memory, a kill) costs nothing: the next call starts a
    new one; close_helper (the end of a ground run) leaves no helper process."""
    import os
    import signal

    pytest.importorskip("CSF")
    from gistools.lidar import cloth
    from gistools.lidar.ground import CsfParams, csf_ground

    x, y, z, _truth = _cloth_scene(20_000)
    p = CsfParams(resolution=1.0)
    first = csf_ground(x, y, z, np.ones(len(x), bool), p)
    pool = cloth._HELPER["pool"]
    helpers = list(pool.pool._processes.values())
    assert helpers
    for proc in helpers:
        os.kill(proc.pid, signal.SIGKILL)
        proc.join(timeout=30)
    second = csf_ground(x, y, z, np.ones(len(x), bool), p)
    np.testing.assert_array_equal(first, second)
    assert cloth._HELPER["pool"] is not pool
    last = list(cloth._HELPER["pool"].pool._processes.values())
    cloth.close_helper()
    assert "pool" not in cloth._HELPER and not any(proc.is_alive() for proc in last)


def test_the_default_keeps_a_dense_noisy_forest_floor_at_its_true_height():
    """A dense forest survey made here (20 pulses/m², a canopy over three quarters of them, understory returns
    0.15-1.5 m up, ground returns with 6 cm of noise on a sloping, rolling surface): the default's ground gives a
    DEM (scipy's linear interpolation) within 5 cm of the true surface on average and takes no understory. Its
    canopy cell shrinks with the density (about 10 last returns a cell): on 1.75 m cells the lowest of some 60
    returns a cell lies 2.4 sigma low, and the DEM 7.6 cm."""
    from scipy.interpolate import LinearNDInterpolator

    from gistools.lidar.ground import CANOPY_DENSITY_M2, canopy_cell, survey_density, survey_returns

    rng = np.random.default_rng(3)
    side, pulses = 150.0, 20 * 150 * 150
    px, py = rng.uniform(0, side, pulses), rng.uniform(0, side, pulses)

    def terrain(x, y):
        return 100 + 0.15 * x + 2 * np.sin(x / 20) * np.cos(y / 25)

    canopy = rng.uniform(size=pulses) < 0.75
    under = rng.uniform(size=pulses) < 0.35
    ground = rng.uniform(size=pulses) < np.where(canopy, 0.25, 0.9)
    count = canopy.astype(np.uint8) + under + ground
    seen = np.zeros(pulses, np.uint8)
    parts = []
    for hit, height, is_ground in ((canopy, rng.uniform(12, 25, pulses), False),
                                   (under, rng.uniform(0.15, 1.5, pulses), False),
                                   (ground, rng.normal(0, 0.06, pulses), True)):
        i = np.flatnonzero(hit)
        seen[i] += 1
        parts.append((px[i], py[i], terrain(px[i], py[i]) + height[i], seen[i].copy(), count[i],
                      np.full(len(i), is_ground)))
    x, y, z, rn, nr, truth = (np.concatenate(a) for a in zip(*parts))
    cls = classify_ground_and_noise(x, y, z, rn, nr, np.ones(len(x), np.uint8), method="adaptive")
    g = cls == 2
    assert np.mean(g[~truth]) < 0.001  # no understory, no canopy
    qx, qy = np.meshgrid(np.arange(10.0, side - 10), np.arange(10.0, side - 10))
    dem = LinearNDInterpolator(np.column_stack([x[g], y[g]]), z[g])(qx.ravel(), qy.ravel())
    err = dem - terrain(qx.ravel(), qy.ravel())
    bias, rmse = np.nanmean(err), np.sqrt(np.nanmean(err ** 2))
    assert abs(bias) <= 0.05 and rmse <= 0.06, (bias, rmse)
    # the cell it took: 1.75 m x sqrt(3.2 / the last returns per m² over the 25 m cells that hold a point)
    n, _multi, last, cells = survey_returns(x, y, rn, nr, 25.0)
    density = survey_density(last, len(cells), 25.0)
    assert density == pytest.approx(last / side ** 2, rel=0.02)  # 36 cells of 25 m, all full
    assert canopy_cell((1.75, 0.05, 0.2, 0.1, CANOPY_DENSITY_M2, 0.5), density) == pytest.approx(
        1.75 * np.sqrt(CANOPY_DENSITY_M2 / density))


@pytest.mark.parametrize("args,needles", [
    (["--threshold", "0.3m"], ["--threshold 0.3m", "--method smrf", "adaptive"]),
    (["--method", "smrf", "--smrftin-patch", "30m"], ["--smrftin-patch 30m", "--method smrftin", "smrf"]),
    (["--method", "smrftin", "--csf-iterations", "10"], ["--csf-iterations 10", "--method csf", "smrftin"]),
])
def test_an_option_of_another_filter_is_refused_before_anything_is_written(tmp_path, args, needles):
    result = CliRunner().invoke(cli, ["ground", str(SAMPLE), "--out", str(tmp_path / "out"), *args])
    assert result.exit_code == 1 and all(n in result.output for n in needles), result.output
    assert not (tmp_path / "out").exists()


def test_a_rerun_that_keeps_every_tile_reports_the_set_the_tiles_were_made_with(tmp_path):
    first = ground_from_tiles(SAMPLE, tmp_path / "out", GroundSettings())
    again = ground_from_tiles(SAMPLE, tmp_path / "out", GroundSettings())
    assert again["counts"]["skipped"] == 4
    assert again["units"] == first["units"] and first["units"]["ground_noise"] is not None


def test_adaptive_measured_in_the_blocks_of_a_large_survey_is_the_same_tiled_and_merged(tmp_path, monkeypatch):
    """adaptive's measures (noise, share of multi-return points, density of last returns) taken in every 2nd block
    of 100 m: the same figures and classes tiled and merged (NOISE_POINTS lowered so that the sample is large)."""
    from gistools.lidar import ground as lg

    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    wiped = _wiped(tiles, tmp_path / "tiles")
    merged = {k: np.concatenate([np.asarray(getattr(laspy.read(p), k)) for p in wiped]) for k in FIELDS}
    write_tile(tmp_path / "merged" / "all.las", merged, read_tile_info(tiles[0]).crs, version="1.2", point_format=1,
               offsets=[430000.0, 1810000.0, 0.0])
    monkeypatch.setattr(lg, "NOISE_POINTS", 60_000)
    tiled = ground_from_tiles(tmp_path / "tiles", tmp_path / "out_tiled", GroundSettings())
    whole = ground_from_tiles(tmp_path / "merged", tmp_path / "out_merged", GroundSettings())
    assert tiled["units"] == whole["units"] and tiled["units"]["multi_return_share"] is not None
    a = np.concatenate([np.asarray(laspy.read(tmp_path / "out_tiled" / f"{p.stem}.laz").classification) for p in wiped])
    assert np.array_equal(a, np.asarray(laspy.read(tmp_path / "out_merged" / "all.laz").classification))
