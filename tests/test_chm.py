"""gistools chm on a synthetic conifer stand: conical crowns whose first returns go deep into the crown one time in
four, which leaves a 0.5 m p2r CHM full of pits; pitfree must remove >= 90 % of them and keep the tree tops."""

from __future__ import annotations

import laspy
import numpy as np
import pyproj
import pytest
import rasterio

from gistools.errors import InputError
from gistools.io.points import write_tile
from gistools.lidar.chm import pits
from gistools.products.chm import ChmSettings, chm_from_tiles

SIZE = 80.0  # m
X0, Y0 = 500_000.0, 4_900_000.0


def stand(seed=7):
    """(points, trees): first returns on conical crowns (a quarter of them deep inside the crown), ground returns
    under and between them; trees as (x, y, height)."""
    rng = np.random.default_rng(seed)
    trees = []
    while len(trees) < 45:
        x, y = rng.uniform(6, SIZE - 6, 2)
        if all(np.hypot(x - a, y - b) > 5.5 for a, b, _ in trees):
            trees.append((x, y, rng.uniform(12, 25)))
    trees = np.array(trees)
    n = int(10 * SIZE * SIZE)  # 10 first returns per m2: 2.5 per 0.5 m cell
    x, y = rng.uniform(0, SIZE, n), rng.uniform(0, SIZE, n)
    ground = 100 + 0.03 * x
    surface = ground.copy()
    for tx, ty, h in trees:
        r = np.hypot(x - tx, y - ty)
        radius = 0.16 * h
        crown = h - 0.6 * h * r / radius  # a cone: from the apex down to 40 % of the height at the crown's edge
        inside = r < radius
        surface[inside] = np.maximum(surface[inside], (100 + 0.03 * tx) + crown[inside])
    canopy = surface > ground + 0.5
    deep = canopy & (rng.random(n) < 0.25)
    z = surface.copy()
    z[deep] = ground[deep] + rng.uniform(0.2, 0.85, deep.sum()) * (surface[deep] - ground[deep])
    gx, gy = rng.uniform(0, SIZE, 2 * int(SIZE * SIZE)), rng.uniform(0, SIZE, 2 * int(SIZE * SIZE))
    pts = {"x": np.concatenate([x, gx]) + X0, "y": np.concatenate([y, gy]) + Y0,
           "z": np.concatenate([z, 100 + 0.03 * gx]),
           "classification": np.concatenate([np.where(canopy, 5, 2), np.full(len(gx), 2)]).astype(np.uint8),
           "return_number": np.concatenate([np.ones(n), np.full(len(gx), 2)]).astype(np.uint8),
           "number_of_returns": np.full(n + len(gx), 2, np.uint8)}
    trees[:, 0] += X0
    trees[:, 1] += Y0
    return pts, trees


@pytest.fixture(scope="module")
def conifers(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stand")
    pts, trees = stand()
    crs = pyproj.CRS.from_epsg(26917)
    write_tile(folder / "whole" / "stand.las", pts, crs, scale=0.001)
    west = pts["x"] < X0 + SIZE / 2  # the same stand as two tiles
    for name, m in (("west", west), ("east", ~west)):
        write_tile(folder / "two" / f"{name}.las", {k: v[m] for k, v in pts.items()}, crs, scale=0.001)
    return folder, pts, trees


def chm_of(folder, out, **kw):
    report = chm_from_tiles(folder, out, ChmSettings(cell_size="0.5m", **kw))
    assert report["counts"]["failed"] == 0
    with rasterio.open(out / "chm.vrt") as src:
        return src.read(1, masked=True).filled(np.nan).astype(float), src.transform, report


def test_pitfree_removes_the_pits_of_p2r_and_keeps_the_tree_tops(conifers, tmp_path):
    folder, pts, trees = conifers
    p2r, transform, rep_p2r = chm_of(folder / "whole", tmp_path / "p2r", method="p2r")
    free, _, rep_free = chm_of(folder / "whole", tmp_path / "free", method="pitfree")
    pits_p2r, pits_free = pits(p2r, 1.0).sum(), pits(free, 1.0).sum()
    assert pits_p2r > 60, pits_p2r  # the p2r CHM of dense crowns at 0.5 m is full of them
    assert pits_free <= 0.1 * pits_p2r, (pits_free, pits_p2r)
    assert rep_p2r["pits"] == pits_p2r and rep_free["pits"] == pits_free
    # lidR's pitfree() defaults remove fewer on these steep crowns (README "Canopy height")
    lidr, _, _ = chm_of(folder / "whole", tmp_path / "lidr", method="pitfree", thresholds=("0m", "2m", "5m", "10m", "15m"),
                        threshold_step="0", max_edge=("0", "1m"))
    assert pits_free < pits(lidr, 1.0).sum() < pits_p2r
    # tree tops: near each apex the CHM reaches the highest first return there (within a cell's slope of the cone),
    # and never rises above it
    rows, cols = np.indices(free.shape)
    cx, cy = transform * (cols + 0.5, rows + 0.5)
    first = pts["return_number"] == 1
    kept = 0
    for tx, ty, _h in trees:
        near_pts = first & (np.hypot(pts["x"] - tx, pts["y"] - ty) < 1.0)
        top = (pts["z"][near_pts] - (100 + 0.03 * (pts["x"][near_pts] - X0))).max()
        near = np.hypot(cx - tx, cy - ty) < 1.0
        best = np.nanmax(free[near])
        assert best <= top + 0.01
        kept += best >= top - 1.0
    assert kept >= 0.95 * len(trees), kept


def test_tiles_equal_the_whole_stand(conifers, tmp_path):
    folder, _, _ = conifers
    for method in ("pitfree", "p2r", "tin"):
        whole, tw, _ = chm_of(folder / "whole", tmp_path / f"w_{method}", method=method)
        tiled, tt, rep = chm_of(folder / "two", tmp_path / f"t_{method}", method=method)
        assert rep["counts"]["ok"] == 2 and tw == tt
        np.testing.assert_allclose(tiled, whole, rtol=0, atol=1e-4, equal_nan=True, err_msg=method)


def test_bad_chm_options_are_refused_before_anything_is_written(tmp_path):
    with pytest.raises(InputError, match="method .spikefree."):  # Python calls: the messages name the fields
        chm_from_tiles(tmp_path, tmp_path / "o", ChmSettings(method="spikefree"))
    with pytest.raises(InputError, match="max_edge"):
        chm_from_tiles(tmp_path, tmp_path / "o", ChmSettings(max_edge=("1m",)))
    assert not (tmp_path / "o").exists()


def test_a_tile_without_ground_fails_with_its_name(conifers, tmp_path):
    _, pts, _ = conifers
    keep = pts["classification"] != 2
    write_tile(tmp_path / "in" / "bare.las", {k: v[keep] for k, v in pts.items()}, pyproj.CRS.from_epsg(26917))
    write_tile(tmp_path / "in" / "far.las", {**pts, "x": pts["x"] + 1e4}, pyproj.CRS.from_epsg(26917))
    report = chm_from_tiles(tmp_path / "in", tmp_path / "o", ChmSettings(method="p2r"))
    status = {t["name"]: t for t in report["tiles"]}
    assert status["far"]["status"] == "ok"
    assert status["bare"]["status"] == "failed" and "bare.las" in status["bare"]["error"]
    assert "no ground" in status["bare"]["error"]
    assert laspy.open(tmp_path / "in" / "bare.las").header.point_count == keep.sum()  # the input untouched
