"""gistools normalize against a scipy TIN of every tile's ground (the block read as one): 1 mm everywhere the
Delaunay triangulation is unique, tile edges included; z replaced; vegetation, road and water classes by their
rules; the real files; what is refused."""

from __future__ import annotations

import hashlib
import json

import laspy
import numpy as np
import pytest
import shapely

from conftest import SAMPLE, reference_tin_heights
from gistools.errors import TilesFailed
from gistools.io.points import write_tile
from gistools.products.normalize import HAG_DIMENSION, NormalizeSettings, normalize_from_tiles

B = SAMPLE / "breaklines.gpkg"


def block(paths):
    """x, y, z, class of every point of the tiles, and the tile each came from."""
    cols = {k: [] for k in ("x", "y", "z", "c", "tile", "index")}
    for p in paths:
        las = laspy.read(p)
        n = len(las.points)
        for k, v in (("x", las.x), ("y", las.y), ("z", las.z), ("c", las.classification)):
            cols[k].append(np.asarray(v))
        cols["tile"].append(np.full(n, p.stem))
        cols["index"].append(np.arange(n))
    return {k: np.concatenate(v) for k, v in cols.items()}


def reference(pts):
    g = np.isin(pts["c"], (2, 9))
    return reference_tin_heights(pts["x"], pts["y"], pts["z"], pts["x"][g], pts["y"][g], pts["z"][g])


def written(out, pts, name=HAG_DIMENSION):
    """The written heights in the block's point order."""
    return np.concatenate([np.asarray(getattr(laspy.read(out / f"{t}.laz"), name), float)
                           for t in dict.fromkeys(pts["tile"])])


def test_heights_equal_one_tin_of_every_tile_within_a_millimetre(tmp_path, sample_tiles):
    before = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in sample_tiles}
    out = tmp_path / "n"
    report = normalize_from_tiles(SAMPLE, out, NormalizeSettings())
    assert report["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    pts = block(sample_tiles)
    want, tied = reference(pts)
    got = written(out, pts)
    sure = np.isfinite(want) & ~tied
    assert sure.mean() > 0.999
    assert np.max(np.abs(got[sure] - want[sure])) < 0.001 / 0.3048006  # 1 mm, in US survey feet
    # the points near the tiles' inner edges are among them (the neighbours' ground was read)
    edge_x = sorted({laspy.open(p).header.maxs[0] for p in sample_tiles})[0]
    near = sure & (np.abs(pts["x"] - edge_x) < 20)
    assert near.sum() > 1000 and np.max(np.abs(got[near] - want[near])) < 0.0033
    # every other dimension as it was; the inputs untouched; a VPC of the four tiles
    a, b = laspy.read(sample_tiles[0]), laspy.read(out / f"{sample_tiles[0].stem}.laz")
    for dim in ("X", "Y", "Z", "classification", "intensity", "return_number"):
        assert np.array_equal(np.asarray(a[dim]), np.asarray(b[dim])), dim
    assert "ftUS" in b.point_format.dimension_by_name(HAG_DIMENSION).description
    assert {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in sample_tiles} == before
    vpc = json.loads((out / "normalized.vpc").read_text())
    assert len(vpc["features"]) == 4


def test_replace_z_writes_the_heights_as_z(tmp_path, sample_tiles):
    out = tmp_path / "z"
    normalize_from_tiles(SAMPLE, out, NormalizeSettings(replace_z=True))
    pts = block(sample_tiles)
    want, tied = reference(pts)
    got = written(out, pts, "z")
    sure = np.isfinite(want) & ~tied
    assert np.max(np.abs(got[sure] - want[sure])) <= 0.005 + 0.0033  # the LAS z scale (0.01 ft) rounds them
    assert HAG_DIMENSION not in laspy.read(out / f"{sample_tiles[0].stem}.laz").point_format.dimension_names


def test_vegetation_road_and_water_classes_follow_their_rules(tmp_path, sample_tiles):
    import geopandas as gpd

    from gistools.vector.breaklines import road_polygons

    out = tmp_path / "v"
    report = normalize_from_tiles(SAMPLE, out, NormalizeSettings(classify_vegetation=True),
                                  roads=f"{B}:ROADBREAKLINE", waterbodies=f"{B}:WATERBODY")
    pts = block(sample_tiles)
    h, tied = reference(pts)
    new = np.concatenate([np.asarray(laspy.read(out / f"{t}.laz").classification) for t in dict.fromkeys(pts["tile"])])
    ft = 1 / 0.3048006
    sure = np.isfinite(h) & ~tied & (np.abs(h - np.round(h / ft) * ft) > 0.01)  # not on a band limit to the mm
    open_ = np.isin(pts["c"], (0, 1)) & sure
    water = shapely.union_all(gpd.read_file(B, layer="WATERBODY").geometry)
    in_water = shapely.contains_xy(water, pts["x"], pts["y"])
    roads = gpd.read_file(B, layer="ROADBREAKLINE").geometry
    in_road = np.zeros(len(h), bool)
    for p in sample_tiles:
        w, s = laspy.open(p).header.mins[:2]
        e, n = laspy.open(p).header.maxs[:2]
        mine = pts["tile"] == p.stem
        in_road[mine] = shapely.contains_xy(road_polygons(list(roads), shapely.box(w, s, e, n), snap=0.2, max_width=60),
                                            pts["x"][mine], pts["y"][mine])
    floor = 0.1 * ft
    surface = sure & np.isin(pts["c"], (0, 1, 2)) & (h <= floor)
    expect = pts["c"].copy()
    expect[open_ & (h > floor) & (h <= 1 * ft)] = 3
    expect[open_ & (h > 1 * ft) & (h <= 6 * ft)] = 4
    expect[open_ & (h > 6 * ft)] = 5
    expect[surface & in_road] = 11
    expect[surface & in_water] = 9
    checked = sure | ~np.isin(pts["c"], (0, 1, 2))
    assert np.array_equal(new[checked], expect[checked])
    counts = {k: sum(t["reclassified"].get(k, 0) for t in report["tiles"]) for k in (3, 4, 5, 11)}
    assert all(v > 100 for v in counts.values()), counts


def test_the_real_files_within_a_millimetre(tmp_path, real_tile):
    out = tmp_path / "n"
    normalize_from_tiles(real_tile, out, NormalizeSettings(format="las"))
    las = laspy.read(real_tile)
    pts = {"x": np.asarray(las.x), "y": np.asarray(las.y), "z": np.asarray(las.z), "c": np.asarray(las.classification)}
    want, tied = reference(pts)
    got = np.asarray(getattr(laspy.read(out / f"{real_tile.stem}.las"), HAG_DIMENSION), float)
    sure = np.isfinite(want) & ~tied
    unit = 1.0 if "megaplot" in str(real_tile).lower() else 0.3048
    assert sure.mean() > 0.9
    assert np.max(np.abs(got[sure] - want[sure])) * unit < 0.001
    # outside the ground's hull the heights are extrapolated (inverse distance, as lidR), never missing
    assert np.isfinite(got).all()


def test_a_tile_without_ground_fails_alone_with_one_line(tmp_path, sample_tiles):
    import shutil

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    shutil.copy(sample_tiles[0], tiles)
    las = laspy.read(sample_tiles[0])
    far = {"x": np.asarray(las.x) + 1e5, "y": np.asarray(las.y), "z": np.asarray(las.z),
           "classification": np.ones(len(las.points), np.uint8), "return_number": np.ones(len(las.points), np.uint8),
           "number_of_returns": np.ones(len(las.points), np.uint8)}
    write_tile(tiles / "bare.las", far, laspy.open(sample_tiles[0]).header.parse_crs())
    report = normalize_from_tiles(tiles, tmp_path / "n")
    status = {t["name"]: t for t in report["tiles"]}
    assert status[sample_tiles[0].stem]["status"] == "ok"
    assert status["bare"]["status"] == "failed" and "no ground" in status["bare"]["error"]
    assert "\n" not in status["bare"]["error"]
    with pytest.raises(TilesFailed):
        normalize_from_tiles(tiles / "bare.las", tmp_path / "n2")


def test_copc_holds_the_heights_as_z_and_refuses_the_extra_dimension(tmp_path, sample_tiles):
    from gistools.errors import InputError

    with pytest.raises(InputError, match="replace_z"):  # a Python call: the message names the argument
        normalize_from_tiles(SAMPLE, tmp_path / "no", NormalizeSettings(format="copc"))
    assert not (tmp_path / "no").exists()
    report = normalize_from_tiles(sample_tiles[0], tmp_path / "c", NormalizeSettings(format="copc", replace_z=True))
    assert report["counts"]["ok"] == 1
    with laspy.CopcReader.open(report["tiles"][0]["output"]) as reader:
        z = np.asarray(reader.query().z)
    assert len(z) == laspy.open(sample_tiles[0]).header.point_count and z.min() > -1 and z.max() < 200
