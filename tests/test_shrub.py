"""The shrub chain on the sample block against the generator's truth, and on the real Megaplot file."""

from __future__ import annotations

import json
from pathlib import Path

import geopandas as gpd
import numpy as np
import pyproj
import pytest
import shapely
from click.testing import CliRunner

from conftest import SAMPLE, SHARED_DATA
from gistools.cli.main import cli
from gistools.errors import CRSMismatchError, InputError
from gistools.grid import cell_centres
from gistools.io.points import write_tile
from gistools.io.raster import read_raster
from gistools.synthetic import Scene, scene_points
from gistools.products.shrub import ShrubSettings, shrub_from_tiles

B = SAMPLE / "breaklines.gpkg"
VECTORS = dict(roads=f"{B}:ROADBREAKLINE", hydro=f"{B}:HYDROGRAPHICFEATURE", waterbodies=f"{B}:WATERBODY",
               wetlands=f"{B}:WETLAND", tile_index=f"{B}:FOOTPRINT")
CODE = {"light": 1, "medium": 2, "heavy": 3}


@pytest.fixture(scope="session")
def shrub_run(tmp_path_factory, sample_tiles):
    out = tmp_path_factory.mktemp("shrub")
    report = shrub_from_tiles(sample_tiles, out, **VECTORS)
    return out, report


def centres(grid):
    xs, ys = cell_centres(grid)
    return np.meshgrid(xs, ys)


def test_report_has_areas_by_band_and_class(shrub_run):
    out, report = shrub_run
    assert report["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    assert set(report["class_area"]) == {"none", "light", "medium", "heavy", "road", "water"}
    assert set(report["band_area"]) == {"B0", "B1", "B2", "B3"}
    assert report["area_unit"] == "US survey foot squared"
    assert report["band_thresholds"] == pytest.approx([3937 / 1200, 2 * 3937 / 1200, 19.685])
    assert sum(report["class_area"].values()) == pytest.approx(2000 * 2000)
    assert json.loads((out / "report.json").read_text())["class_area"] == report["class_area"]
    # where the time went, by stage: the rasters' and each step's seconds summed over the tiles, the map's once
    stages = report["stage_seconds"]
    assert set(stages) == {"read", "merge", "dem", "write", "bands", "clip", "density", "classes", "polygons_and_map"}
    assert all(v >= 0 for v in stages.values()) and sum(stages.values()) <= 2 * report["seconds"]
    for name in ("shrub_map.png", "shrub_map.pdf", "shrub_classes.gpkg", "classes.vrt", "cover.vrt", "density.vrt",
                 "bands.vrt", "veg.vrt", "wetveg.vrt"):
        assert (out / name).exists(), name


def test_each_patch_interior_gets_its_class(shrub_run):
    out, _ = shrub_run
    classes, grid, _ = read_raster(out / "classes.vrt")
    cx, cy = centres(grid)
    truth = gpd.read_file(SAMPLE / "truth.gpkg", layer="SHRUB_TRUTH")
    checked = 0
    for _, patch in truth.iterrows():
        inner = patch.geometry.buffer(-25)  # cells whose whole 25 ft neighbourhood is in the patch
        m = shapely.contains_xy(inner, cx, cy) if not inner.is_empty else np.zeros(cx.shape, bool)
        if m.sum() < 20:
            continue
        share = np.mean(classes[m] == CODE[patch["cover"]])
        assert share >= 0.9, (patch["cover"], patch["band"], share)
        checked += 1
    assert checked >= 15


def test_no_vegetation_in_roads_or_water(shrub_run):
    out, _ = shrub_run
    veg, grid, _ = read_raster(out / "veg.vrt")
    cx, cy = centres(grid)
    for layer in ("ROAD_TRUTH", "WATER_TRUTH"):
        poly = gpd.read_file(SAMPLE / "truth.gpkg", layer=layer).union_all().buffer(-1.0)
        inside = shapely.contains_xy(poly, cx, cy)
        assert inside.sum() > 1000
        assert not np.any((veg[inside] >= 1) & (veg[inside] <= 3)), layer
    classes, _, _ = read_raster(out / "classes.vrt")
    road = shapely.contains_xy(gpd.read_file(SAMPLE / "truth.gpkg", layer="ROAD_TRUTH").union_all().buffer(-1.0), cx, cy)
    assert np.mean(classes[road] == 4) > 0.99


def test_band_areas_against_true_crowns(shrub_run, record_property):
    """Band areas within 2 % of the generator's crown areas per band.

    The report's band_area_from_returns (share of first returns in each band x area) is the unbiased
    estimate; band_area counts band-raster cells, where a cell counts whole when any of its ~1.6
    first returns hits a crown, so it runs 6-9 % high on crown edges (printed, bounded at 12 %).
    """
    out, report = shrub_run
    crowns = gpd.read_file(SAMPLE / "truth.gpkg", layer="SHRUB_CROWNS")
    for band in ("B1", "B2", "B3"):
        true_area = crowns[crowns.band == band].area.sum()
        from_returns = report["band_area_from_returns"][band] / true_area
        from_cells = report["band_area"][band] / true_area
        record_property(f"{band}_returns_ratio", from_returns)
        print(f"{band}: true crowns {true_area:,.0f} ft2; from returns x{from_returns:.4f}, from cells x{from_cells:.4f}")
        assert abs(from_returns - 1) <= 0.02, band
        assert 0.95 < from_cells < 1.12, band


def test_vegetation_inside_wetland(shrub_run):
    out, _ = shrub_run
    wetveg, grid, _ = read_raster(out / "wetveg.vrt")
    cx, cy = centres(grid)
    wet = gpd.read_file(B, layer="WETLAND").union_all()
    inside = shapely.contains_xy(wet, cx, cy)
    assert np.any((wetveg >= 1) & (wetveg <= 3))
    assert not np.any(((wetveg >= 1) & (wetveg <= 3)) & ~inside)


def test_map_colours_at_known_patches(shrub_run):
    import matplotlib.image as mpimg
    import matplotlib.colors as mcolors

    from gistools.plot import SHRUB_COLOURS, shrub_map
    from gistools.units import LinearUnit

    out, _ = shrub_run
    truth = gpd.read_file(SAMPLE / "truth.gpkg", layer="SHRUB_TRUTH")
    big = truth[truth.geometry.buffer(-30).area > 500]
    probes = [(p.geometry.buffer(-30).representative_point().x, p.geometry.buffer(-30).representative_point().y)
              for p in big.itertuples()]
    result = shrub_map(out / "classes.vrt", out / "probe_map", title="probe", unit=LinearUnit("US survey foot", 1200 / 3937),
                       probes=probes)
    img = mpimg.imread(result["paths"][0])[:, :, :3]
    for (col, row), cover in zip(result["probes"], big["cover"]):
        want = np.array(mcolors.to_rgb(SHRUB_COLOURS[CODE[cover]][1]))
        assert np.abs(img[row, col] - want).max() < 0.05, (cover, img[row, col], want)


def test_the_map_caption_states_what_made_it(shrub_run):
    # the run's defaults as the README states them: 5 ft cells, 25 ft density radius, cover breaks 0.30 / 0.70
    from gistools.plot import map_parameters
    from gistools.units import LinearUnit

    out, _ = shrub_run
    text = map_parameters(out / "classes.vrt", out / "cover.vrt", LinearUnit("US survey foot", 1200 / 3937))
    assert text == "cell 5 ftUS; density radius 25 ftUS; cover: light <= 0.30 < medium <= 0.70 < heavy"


def test_class_polygons_are_valid_dissolved_and_exact():
    """Regions of one code meeting at a corner, a hole holding another code: one valid MultiPolygon per code,
    each with exactly its cells' area, the hole kept."""
    from affine import Affine

    from gistools.vector.regions import class_polygons

    codes = np.zeros((6, 7), np.uint8)
    codes[1:5, 1:5] = 1
    codes[2:4, 2:4] = 2  # a hole in the 1s
    codes[5, 5] = 1  # touches the 1s' block only at a corner
    codes[0, 6] = 3
    tr = Affine(2.5, 0, 1000.0, 0, -2.5, 500.0)
    polys = class_polygons(codes, tr, mask=codes > 0)
    assert sorted(polys) == [1, 2, 3]
    for code, geom in polys.items():
        assert geom.geom_type == "MultiPolygon" and geom.is_valid
        assert geom.area == pytest.approx(np.count_nonzero(codes == code) * 2.5 * 2.5)
    assert len(polys[1].geoms) == 2 and len(polys[1].geoms[0].interiors) + len(polys[1].geoms[1].interiors) == 1
    assert polys[3].bounds == (1015.0, 497.5, 1017.5, 500.0)


def test_class_polygons_layer(shrub_run, shrub_area=None):
    out, report = shrub_run
    gdf = gpd.read_file(out / "shrub_classes.gpkg", layer="shrub_classes")
    assert gdf.crs.to_epsg() == 2882
    assert set(gdf["class"]) == {"light", "medium", "heavy", "road", "water"}
    assert gdf.is_valid.all() and (gdf.groupby(["tile", "class"]).size() == 1).all()  # one dissolved row per tile and class
    assert list(gdf["tile"]) == sorted(gdf["tile"])  # rows by tile, whichever worker finished first
    for name in ("light", "medium", "heavy"):
        assert gdf.loc[gdf["class"] == name, "area"].sum() == pytest.approx(report["class_area"][name], rel=1e-6)
    assert np.allclose(gdf["area_acres"], gdf["area"] * (1200 / 3937) ** 2 / 4046.8564224)


def test_bare_sloping_rough_ground_has_no_shrub(tmp_path):
    """Only ground: steep slope plus 0.3 ft roughness. No cell may come out as B1-B3 or as shrub."""
    import numpy as np

    scene = Scene(origin=(500000.0, 1800000.0), size=(600.0, 600.0))
    pts = scene_points(scene, scene.bounds, spacing=4.0, seed=5)
    rng = np.random.default_rng(1)
    pts["z"] = pts["z"] + 0.08 * (pts["x"] - 500000.0) + rng.normal(0, 0.3, pts["z"].size)  # 8 % slope, rough
    assert set(np.unique(pts["classification"])) == {2}
    write_tile(tmp_path / "bare.las", pts, pyproj.CRS.from_epsg(2882), version="1.2", point_format=1)
    report = shrub_from_tiles([tmp_path / "bare.las"], tmp_path / "out")
    assert report["band_area"]["B1"] == report["band_area"]["B2"] == report["band_area"]["B3"] == 0
    assert report["class_area"]["light"] == report["class_area"]["medium"] == report["class_area"]["heavy"] == 0


def test_vector_crs_mismatch_is_refused(sample_tiles, tmp_path):
    roads = gpd.read_file(B, layer="ROADBREAKLINE").to_crs(4326)
    roads.to_file(tmp_path / "roads_wgs84.gpkg", layer="roads")
    with pytest.raises(CRSMismatchError) as err:
        shrub_from_tiles(sample_tiles, tmp_path / "out", roads=f"{tmp_path / 'roads_wgs84.gpkg'}:roads")
    assert "EPSG:4326" in str(err.value) and "EPSG:2882" in str(err.value) and "reproject_vectors=True" in str(err.value)
    assert not (tmp_path / "out" / "dsm").exists()  # refused before the raster stage, not after it
    report = shrub_from_tiles(sample_tiles, tmp_path / "out2", roads=f"{tmp_path / 'roads_wgs84.gpkg'}:roads",
                              reproject_vectors=True, make_map=False)
    assert report["class_area"]["road"] > 50000


def test_megaplot_with_its_lake(megaplot, tmp_path, record_property):
    lake = SHARED_DATA / "lidar" / "megaplot" / "lake_polygons_UTM17.shp"
    report = shrub_from_tiles([megaplot], tmp_path, ShrubSettings(), waterbodies=str(lake))
    assert report["counts"]["ok"] == 1 and report["horizontal_unit"] == "metre"
    veg, grid, _ = read_raster(tmp_path / "veg.vrt")
    cx, cy = centres(grid)
    inside = shapely.contains_xy(gpd.read_file(lake).union_all().buffer(-0.5), cx, cy)
    assert inside.sum() > 100
    assert not np.any((veg[inside] >= 1) & (veg[inside] <= 3))
    print("\nMegaplot:", json.dumps({k: report[k] for k in ("band_area", "class_area", "nodata_share")}))
    for k, v in report["class_area"].items():
        record_property(f"megaplot_{k}_m2", v)
    assert report["class_area"]["water"] > 0 and report["class_area"]["heavy"] + report["class_area"]["medium"] > 0


def test_cli_shrub(sample_tiles, tmp_path):
    args = ["shrub", str(SAMPLE), "--out", str(tmp_path), "-q", "--no-map"]
    for k, v in VECTORS.items():
        args += [f"--{k.replace('_', '-')}", v]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert "4 tiles ok" in result.output and "heavy" in result.output
    assert (tmp_path / "classes.vrt").exists() and not (tmp_path / "shrub_map.png").exists()


def _metre_copy(sample_tiles, dest):
    """The sample in NAD83(HARN) / Florida West metres (EPSG:2778): same projection, coordinates x 1200/3937."""
    import laspy

    k = 1200 / 3937
    dest.mkdir()
    for p in sample_tiles:
        las = laspy.read(p)
        pts = {n: np.asarray(getattr(las, n)) for n in ("x", "y", "z", "classification", "return_number",
                                                       "number_of_returns", "intensity")}
        pts["x"], pts["y"], pts["z"] = pts["x"] * k, pts["y"] * k, pts["z"] * k
        write_tile(dest / p.name, pts, pyproj.CRS.from_epsg(2778), version="1.2", point_format=1, scale=0.001,
                   vertical_epsg=5703)
    vectors = {}
    for key, spec in VECTORS.items():
        path, layer = spec.rsplit(":", 1)
        gdf = gpd.read_file(path, layer=layer)
        gdf = gdf.set_geometry(shapely.transform(gdf.geometry, lambda c: c * k)).set_crs(2778, allow_override=True)
        gdf.to_file(dest / "breaklines.gpkg", layer=layer)
        vectors[key] = f"{dest / 'breaklines.gpkg'}:{layer}"
    return vectors


def test_the_same_run_in_metres_gives_the_same_areas(sample_tiles, shrub_run, tmp_path):
    out, feet = shrub_run
    vectors = _metre_copy(sample_tiles, tmp_path / "m")
    s = ShrubSettings()
    # the feet run's lengths, given (on metre data the defaults are round metres: 1.5 m, 7.5 m, 18 m ...)
    same = ShrubSettings(raster=s.raster.__class__(cell_size="5ftUS"), radius="25ftUS", max_road_width="60ftUS",
                         snap="0.2ftUS", max_hydro_width="500ftUS", single_line_width="8ftUS")
    metres = shrub_from_tiles(sorted((tmp_path / "m").glob("*.la[sz]")), tmp_path / "out", same, make_map=False,
                              **vectors)
    assert metres["horizontal_unit"] == "metre" and metres["vertical_unit"] == "metre"
    assert metres["band_thresholds"] == pytest.approx([1.0, 2.0, 6.0])
    ft2 = (1200 / 3937) ** 2
    for key in ("band_area", "class_area"):
        for name, a_ft2 in feet[key].items():
            a_m2 = metres[key][name]
            assert a_m2 == pytest.approx(a_ft2 * ft2, rel=0.005, abs=50 * 0.3 ** 2), (key, name)


def test_tiled_equals_untiled_for_density_and_classes(sample_tiles, shrub_run, tmp_path):
    import laspy

    out, _ = shrub_run
    parts = [laspy.read(p) for p in sample_tiles]
    pts = {n: np.concatenate([np.asarray(getattr(l, n)) for l in parts])
           for n in ("x", "y", "z", "classification", "return_number", "number_of_returns", "intensity")}
    write_tile(tmp_path / "block.las", pts, pyproj.CRS.from_epsg(2882), version="1.1", point_format=1,
               offsets=[430000.0, 1810000.0, 0.0], vertical_epsg=6360)
    shrub_from_tiles([tmp_path / "block.las"], tmp_path / "out", make_map=False, **VECTORS)
    for product in ("bands", "veg", "classes"):
        a, _, _ = read_raster(out / f"{product}.vrt")
        b, _, _ = read_raster(tmp_path / "out" / f"{product}.vrt")
        assert np.array_equal(a, b), (product, int(np.sum(a != b)))
    for product in ("density", "cover"):
        a, _, _ = read_raster(out / f"{product}.vrt")
        b, _, _ = read_raster(tmp_path / "out" / f"{product}.vrt")
        assert np.allclose(a, b, equal_nan=True, atol=1e-6), product


def test_killed_run_resumes_to_identical_outputs(sample_tiles, shrub_run, tmp_path):
    """SIGKILL mid-way (no clean-up possible), then the same command again: identical outputs, no partial files."""
    import shutil
    import signal
    import subprocess
    import sys
    import time

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for p in sample_tiles:
        shutil.copy(p, tiles / p.name)
    out = tmp_path / "out"
    args = [sys.executable, "-m", "gistools.cli.main", "shrub", str(tiles), "--out", str(out), "-q", "--no-map",
            "--chunk-size", "5000"]
    for k, v in VECTORS.items():
        args += [f"--{k.replace('_', '-')}", v]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + 60
    while not list((out / "dem").glob("*.tif")) if (out / "dem").exists() else True:
        if time.time() > deadline:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert not (out / "classes.vrt").exists()  # it was stopped before the end
    again = subprocess.run(args, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert not list(out.rglob("*.partial*")) and not list(out.glob(".gistools-scratch-*"))
    ref_out, ref = shrub_run
    report = json.loads((out / "report.json").read_text())
    assert report["class_area"] == ref["class_area"] and report["band_area"] == ref["band_area"]
    assert report["band_area_from_returns"] == ref["band_area_from_returns"]
    for product in ("dsm", "dem", "ndsm", "bands", "veg", "cover", "classes"):
        a, _, _ = read_raster(ref_out / f"{product}.vrt")
        b, _, _ = read_raster(out / f"{product}.vrt")
        assert np.array_equal(a, b, equal_nan=True), product


def test_rerun_keeps_complete_tiles_and_their_figures(sample_tiles, shrub_run, tmp_path):
    """The chain again on a complete output folder: every tile kept (skipped), and the report still has each
    tile's point counts and the band areas from first returns (read back from tile_reports/)."""
    import shutil

    ref_out, ref = shrub_run
    out = tmp_path / "out"
    shutil.copytree(ref_out, out)
    before = {p.name: p.stat().st_mtime_ns for p in (out / "dem").glob("*.tif")}
    report = shrub_from_tiles(sample_tiles, out, **VECTORS)
    assert [t["status"] for t in report["tiles"]] == ["ok"] * 4  # the chain's steps ran; the rasters were kept
    assert {p.name: p.stat().st_mtime_ns for p in (out / "dem").glob("*.tif")} == before
    raster_stage = {t["name"]: t for t in report["tiles"]}
    for t in ref["tiles"]:
        assert raster_stage[t["name"]]["points_by_class"] == t["points_by_class"] and t["points"] > 0
        assert raster_stage[t["name"]]["first_return_bands"] == t["first_return_bands"]
    assert report["band_area_from_returns"] == ref["band_area_from_returns"] is not None
    assert report["band_area"] == ref["band_area"] and report["class_area"] == ref["class_area"]
    # a tile whose rasters exist but whose tile report does not (killed in between) is computed again
    victim = sample_tiles[0].stem
    (out / "tile_reports" / f"{victim}.json").unlink()
    again = shrub_from_tiles(sample_tiles, out, **VECTORS)
    assert (out / "dem" / f"{victim}.tif").stat().st_mtime_ns != before[f"{victim}.tif"]
    assert (out / "tile_reports" / f"{victim}.json").exists()
    assert again["band_area_from_returns"] == ref["band_area_from_returns"]


def test_steps_one_by_one(sample_tiles, tmp_path):
    """gistools density / classify / map rerun one step on an existing output folder, keeping what is before."""
    out = tmp_path / "out"
    args = ["shrub", str(SAMPLE), "--out", str(out), "-q"]
    for k, v in VECTORS.items():
        args += [f"--{k.replace('_', '-')}", v]
    assert CliRunner().invoke(cli, args).exit_code == 0
    first = json.loads((out / "report.json").read_text())
    bands_before = (out / "bands" / f"{sample_tiles[0].stem}.tif").stat().st_mtime_ns
    r = CliRunner().invoke(cli, ["density", str(out), "-q", "--radius", "50ft", "--no-map"])
    assert r.exit_code == 0, r.output
    wider = json.loads((out / "report.json").read_text())
    assert wider["density_radius"] == 50.0 and wider["band_area"] == first["band_area"]
    assert wider["class_area"] != first["class_area"]
    assert (out / "bands" / f"{sample_tiles[0].stem}.tif").stat().st_mtime_ns == bands_before  # kept
    r = CliRunner().invoke(cli, ["classify", str(out), "-q", "--classify", "jenks", "--no-map"])
    assert r.exit_code == 0, r.output
    jenks = json.loads((out / "report.json").read_text())
    assert jenks["class_breaks"] != [0.3, 0.7] and 0 < jenks["class_breaks"][0] < jenks["class_breaks"][1] <= 1
    r = CliRunner().invoke(cli, ["map", str(out), "--title", "Sample block"])
    assert r.exit_code == 0 and (out / "shrub_map.png").exists() and (out / "shrub_map.pdf").exists()
    r = CliRunner().invoke(cli, ["density", str(tmp_path), "-q"])
    assert r.exit_code == 1 and "no report.json" in r.output


def test_band_points_and_a_bad_tile(sample_tiles, tmp_path):
    """--band-points writes Raster To Point output; a broken tile is reported and the chain completes the rest."""
    import shutil

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for p in sample_tiles:
        shutil.copy(p, tiles / p.name)
    (tiles / "broken.las").write_bytes(sample_tiles[0].read_bytes()[:5000])
    args = ["shrub", str(tiles), "--out", str(tmp_path / "out"), "-q", "--no-map", "--band-points"]
    for k, v in VECTORS.items():
        args += [f"--{k.replace('_', '-')}", v]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 1 and "broken.las" in r.output and "4 tiles ok, 1 failed" in r.output
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert {t["name"]: t["status"] for t in report["tiles"]}["broken"] == "failed"
    name = sample_tiles[0].stem
    pts = gpd.read_file(tmp_path / "out" / "band_points" / f"{name}.gpkg", layer="band_points")
    bands, grid, _ = read_raster(tmp_path / "out" / "bands" / f"{name}.tif")
    assert len(pts) == np.count_nonzero(bands <= 3) and pts.crs.to_epsg() == 2882
    b1 = pts[pts.band == "B1"]
    assert len(b1) and (b1.grid_code > 0).all() and (b1.grid_code <= 3937 / 1200 + 1e-6).all()


@pytest.mark.parametrize("method", ["jenks", "quantile"])
def test_breaks_from_the_data_are_the_same_per_tile_and_per_block_of_a_mosaic(shrub_run, tmp_path, method):
    """The chain (per tile), gistools classify (per tile) and the step on the mosaic (per block, QGIS's
    gistools:classify) sample the same lattice cells, so they choose the same breaks and give the same classes."""
    import shutil

    from gistools.products.steps import classes_from_cover

    ref_out, _ = shrub_run
    out = tmp_path / "out"
    shutil.copytree(ref_out, out)
    result = CliRunner().invoke(cli, ["classify", str(out), "--classify", method, "-q", "--no-map"])
    assert result.exit_code == 0, result.output
    chain = json.loads((out / "report.json").read_text())
    for block in (64, 150, 2048):  # blocks cut across the tiles in every way
        step = classes_from_cover(out / "cover.vrt", tmp_path / f"c{block}.tif", veg=out / "veg.vrt", method=method,
                                  block=block)
        assert step["breaks"] == pytest.approx(tuple(chain["class_breaks"]), abs=0)
        a, _, _ = read_raster(out / "classes.vrt")
        b, _, _ = read_raster(step["classes"])
        assert np.array_equal(a, b)
    assert tuple(chain["class_breaks"]) != (0.3, 0.7)


def test_a_step_rerun_records_what_it_used_and_keeps_the_earlier_steps_parameters(shrub_run, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(shrub_run[0], out)
    assert CliRunner().invoke(cli, ["density", str(out), "-q", "--radius", "50ft", "--no-map"]).exit_code == 0
    first = json.loads((out / "report.json").read_text())
    assert first["density_radius"] == pytest.approx(50.0)
    assert CliRunner().invoke(cli, ["classify", str(out), "-q", "--classify", "quantile", "--no-map"]).exit_code == 0
    second = json.loads((out / "report.json").read_text())
    assert second["density_radius"] == pytest.approx(50.0) and second["class_method"] == "quantile"
    assert second["band_thresholds"] == first["band_thresholds"]


def test_each_command_keeps_its_record_and_a_step_rerun_redoes_the_later_steps_as_they_were_made(shrub_run, tmp_path):
    """gistools bands reruns clip with the chain's breaklines (road and water areas unchanged) and density with its
    radius; gistools rasters afterwards keeps the chain's class areas; report.json has one line per command."""
    import shutil

    out = tmp_path / "out"
    shutil.copytree(shrub_run[0], out)
    chain = json.loads((out / "report.json").read_text())
    assert chain["settings"]["roads"] == str(Path(VECTORS["roads"].rsplit(":", 1)[0]).resolve()) + ":ROADBREAKLINE"
    r = CliRunner().invoke(cli, ["bands", str(out), "-q", "--noise-floor", "0.05m", "--bands", "text_literal", "--no-map"])
    assert r.exit_code == 0, r.output
    rerun = json.loads((out / "report.json").read_text())
    assert rerun["tool"] == "gistools bands" and rerun["settings"]["noise_floor"] == "0.05m"
    assert rerun["band_thresholds"] != chain["band_thresholds"] and rerun["settings"]["bands"] == "text_literal"
    assert {k: rerun["class_area"][k] for k in ("road", "water")} == {k: chain["class_area"][k] for k in ("road", "water")}
    assert rerun["density_radius"] == chain["density_radius"] and rerun["settings"]["radius"] == chain["settings"]["radius"]
    r = CliRunner().invoke(cli, ["rasters", str(SAMPLE), "--out", str(out), "-q"])
    assert r.exit_code == 0, r.output
    after = json.loads((out / "report.json").read_text())
    assert after["tool"] == "gistools rasters" and after["class_area"] == rerun["class_area"]
    assert after["settings"] == rerun["settings"] and "steps_predate_rasters" not in after  # every tile kept
    assert [run["tool"] for run in after["runs"]][-2:] == ["gistools bands", "gistools rasters"]
    assert after["runs"][-2]["settings"]["noise_floor"] == "0.05m"
    assert after["map_title"] == chain["map_title"] and chain["map_title"].startswith("Shrub density - ")


def test_the_map_keeps_the_chains_title(shrub_run, tmp_path, monkeypatch):
    import shutil

    import gistools.plot as plot
    from gistools.products.shrub import map_from_classes

    out = tmp_path / "out"
    shutil.copytree(shrub_run[0], out)
    seen = {}
    monkeypatch.setattr(plot, "shrub_map", lambda *a, **kw: seen.update(kw) or {"paths": []})
    map_from_classes(out)
    assert seen["title"] == json.loads((out / "report.json").read_text())["map_title"] != f"Shrub density - {out.name}"


@pytest.mark.parametrize("step, own, others", [
    ("bands", ["--bands", "--band-breaks", "--noise-floor"], ["--roads", "--radius", "--breaks"]),
    ("clip", ["--roads", "--hydro", "--max-road-width", "--snap"], ["--bands", "--radius", "--classify"]),
    ("density", ["--radius", "--density-bands"], ["--roads", "--bands", "--breaks"]),
    ("classify", ["--classify", "--breaks"], ["--roads", "--radius", "--noise-floor"]),
])
def test_each_step_help_shows_its_own_options(step, own, others):
    text = CliRunner().invoke(cli, [step, "--help"]).output
    assert all(o in text for o in own) and not any(o + " " in text for o in others), text


def test_a_step_refuses_another_steps_setting(shrub_run):
    from gistools.products.shrub import step_settings

    with pytest.raises(InputError, match="radius: not a setting of the bands step"):
        step_settings(shrub_run[0], "bands", radius="50ft")


def test_the_nodata_share_is_given_per_cause(shrub_run):
    report = shrub_run[1] if isinstance(shrub_run[1], dict) and "nodata_by_cause" in shrub_run[1] else \
        json.loads((shrub_run[0] / "report.json").read_text())
    causes = report["nodata_by_cause"]
    assert set(causes) == {"no_first_return", "water", "no_ground_near"}
    assert sum(causes.values()) == pytest.approx(report["nodata_share"], abs=1e-9)
    assert causes["no_first_return"] > 0.05 and causes["water"] > 0  # the sample: 5 ft cells, a pond and a river


def test_each_tiles_nodata_causes_are_those_of_its_written_rasters(shrub_run):
    """The chain takes a tile's nodata causes from its rasters stage (the arrays in memory): they equal the shares
    counted here from the DSM, DEM and top-class GeoTIFFs it wrote (nodata read as rasterio's mask)."""
    import rasterio

    out, report = shrub_run
    tiles = [t for t in report["tiles"] if t["status"] == "ok"]
    assert tiles
    for t in tiles:
        with rasterio.open(out / "dsm" / f"{t['name']}.tif") as a, rasterio.open(out / "dem" / f"{t['name']}.tif") as b, \
                rasterio.open(out / "topclass" / f"{t['name']}.tif") as c:
            no_dsm = np.ma.getmaskarray(a.read(1, masked=True))
            no_dem = np.ma.getmaskarray(b.read(1, masked=True)) & ~no_dsm
            water = c.read(1) == 9
        cells = no_dsm.size
        expect = {"no_first_return": no_dsm.sum() / cells, "water": (no_dem & water).sum() / cells,
                  "no_ground_near": (no_dem & ~water).sum() / cells}
        assert t["nodata_by_cause"] == pytest.approx(expect, abs=1e-12), t["name"]


def test_a_users_own_qml_beside_the_class_polygons_is_kept(shrub_run, tmp_path):
    """Nothing lost: a style the user saved as shrub_classes.qml survives a rerun; gistools' own is rewritten."""
    import shutil

    out = tmp_path / "out"
    shutil.copytree(shrub_run[0], out)
    qml = out / "shrub_classes.qml"
    assert "gistools style" in qml.read_text()
    qml.write_text("<!DOCTYPE qgis><qgis><!-- my colours --></qgis>\n")
    assert CliRunner().invoke(cli, ["classify", str(out), "-q", "--no-map"]).exit_code == 0
    assert qml.read_text() == "<!DOCTYPE qgis><qgis><!-- my colours --></qgis>\n"
    qml.unlink()
    assert CliRunner().invoke(cli, ["classify", str(out), "-q", "--no-map"]).exit_code == 0
    assert "gistools style" in qml.read_text()
