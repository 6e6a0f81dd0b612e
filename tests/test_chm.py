"""gistools chm on a synthetic conifer stand: conical crowns whose first returns go deep into the crown one time in
four, which leaves a 0.5 m p2r CHM full of pits; pitfree must remove >= 90 % of them and keep the tree tops. On two
real stands (lidR's MixedConifer and Megaplot, ../shared/data) the same lines, counted here with scipy."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np
import pyproj
import pytest
import rasterio

from scipy import interpolate, ndimage

from conftest import MEGAPLOT, SHARED_DATA, need_shared
from gistools.errors import InputError
from gistools.grid import affine_apply
from gistools.io.points import write_tile
from gistools.lidar.chm import pits
from gistools.products.chm import ChmSettings, chm_from_tiles

SIZE = 80.0  # m
X0, Y0 = 500_000.0, 4_900_000.0
MIXED_CONIFER = SHARED_DATA / "lidar" / "lidr" / "MixedConifer.laz"


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
    cx, cy = affine_apply(transform, (cols + 0.5, rows + 0.5))
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


def real_file(path):
    """A file of ../shared/data (need_shared: missing, the test fails in CI and is skipped, with the reason, in a
    fresh clone without ../shared)."""
    need_shared(path)
    return path


def pit_count(chm, depth=1.0) -> int:
    """Cells more than ``depth`` below the lowest of their 8 neighbours, all 8 with a value (scipy.ndimage's minimum
    over the ring of 8; an empty neighbour counts as -inf, so its cell is no pit)."""
    ring = np.ones((3, 3), bool)
    ring[1, 1] = False
    low = ndimage.minimum_filter(np.where(np.isnan(chm), -np.inf, chm), footprint=ring, mode="constant", cval=-np.inf)
    return int(np.count_nonzero(np.isfinite(chm) & (chm < low - depth)))


def pinholes_interpolated(chm):
    """The empty cells linearly interpolated from the others (scipy's Delaunay of their centres; lidR's
    ``p2r(na.fill = tin())``). A cell beside an empty one is never a pit, and p2r leaves 28 % of MixedConifer's
    0.5 m cells and 75 % of Megaplot's empty: counted raw, its pits are 35 and 0."""
    rows, cols = np.indices(chm.shape)
    ok = np.isfinite(chm)
    out = chm.copy()
    out[~ok] = interpolate.griddata((rows[ok], cols[ok]), chm[ok], (rows[~ok], cols[~ok]), method="linear")
    return out


def tree_tops(chm, cell):
    """Cells above 2 m that are the highest in a circle of diameter 3 m + 0.1 x their height (lidR's variable
    window example for lmf()); ``cell`` in m."""
    h = np.where(np.isfinite(chm), chm, -np.inf)
    radius = np.round((3 + 0.1 * np.maximum(h, 0)) / 2 / cell).astype(int)
    tops = np.zeros(chm.shape, bool)
    for r in np.unique(radius[h > 2]):
        dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
        highest = ndimage.maximum_filter(h, footprint=np.hypot(dy, dx) <= r, mode="constant", cval=-np.inf)
        tops |= (radius == r) & (h == highest) & (h > 2)
    return tops


@pytest.mark.parametrize("path", [MIXED_CONIFER, MEGAPLOT], ids=["MixedConifer", "Megaplot"])
def test_pitfree_leaves_a_tenth_of_the_pits_of_p2r_on_real_stands_and_lowers_no_tree_top(path, tmp_path):
    p2r, _, _ = chm_of(real_file(path), tmp_path / "p2r", method="p2r")
    free, _, report = chm_of(path, tmp_path / "free", method="pitfree")
    baseline, left = pit_count(pinholes_interpolated(p2r)), pit_count(free)
    assert baseline > 400, baseline  # MixedConifer 490, Megaplot 1,092
    assert left <= 0.1 * baseline, (left, baseline)  # 10 and 5
    assert report["pits"] == left  # gistools.lidar.chm.pits counts the same cells
    hit = np.isfinite(p2r)
    assert np.all(free[hit] >= p2r[hit])  # no cell below its highest return: crowns are not lowered
    tops = tree_tops(p2r, 0.5)
    change = free[tops] - p2r[tops]
    assert tops.sum() > 150 and change.min() >= 0.0, (tops.sum(), change.min())  # 181 and 1,052 tops
    assert change.mean() < 0.05, change.mean()  # 0.000 and 0.015 m: a top is raised only by a taller crown nearby


@pytest.mark.parametrize("method", ["p2r", "pitfree"])
def test_a_run_resumed_with_more_tiles_keeps_the_done_ones_and_makes_the_others(tmp_path, method):
    """Two sample tiles, then all four into the same folder: the first two are kept (their edge limit, rounded
    from the tiles' spacing, is the same for two tiles and four), the two others made."""
    import shutil

    sample = sorted((Path(__file__).resolve().parents[1] / "sample_tiles").glob("*.la[sz]"))
    (tmp_path / "two").mkdir()
    for p in sample[:2]:
        shutil.copy(p, tmp_path / "two" / p.name)
    first = chm_from_tiles(tmp_path / "two", tmp_path / "out", ChmSettings(method=method))
    assert first["counts"]["ok"] == 2
    again = chm_from_tiles(sample[0].parent, tmp_path / "out", ChmSettings(method=method))
    assert (again["counts"]["ok"], again["counts"]["skipped"], again["counts"]["failed"]) == (2, 2, 0)
