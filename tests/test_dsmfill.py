"""DSM pinholes on a sparse tile (about one first return per cell, a third of the cells empty): --dsm-fill tin,
nearest and subcircle fill them, never above the highest returns around them (a per-cell maximum computed here with numpy),
count them, leave the other cells, and give the same mosaic from two tiles as from one."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest
import rasterio

from gistools.errors import InputError
from gistools.io.points import write_tile
from gistools.products.rasters import RasterSettings, rasters_from_tiles

CS = 1.0  # m
X0, Y0, SIZE = 300_000.0, 4_100_000.0, 120.0


def sparse_points(seed=2):
    rng = np.random.default_rng(seed)
    n = int(SIZE * SIZE * 1.1)  # 1.1 first returns per 1 m cell: e^-1.1 = 33 % of the cells empty
    x, y = rng.uniform(0, SIZE, n), rng.uniform(0, SIZE, n)
    ground = 50 + 0.05 * x
    canopy = 8 * np.exp(-((x - 60) ** 2 + (y - 60) ** 2) / 800) + rng.uniform(0, 1.5, n)
    z = np.round(ground + canopy, 3)
    cls = np.where(canopy > 2, 5, 2).astype(np.uint8)
    return {"x": np.round(x + X0, 3), "y": np.round(y + Y0, 3), "z": z, "classification": cls,
            "return_number": np.ones(n, np.uint8), "number_of_returns": np.ones(n, np.uint8)}


@pytest.fixture(scope="module")
def tiles(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sparse")
    pts = sparse_points()
    crs = pyproj.CRS.from_epsg(32617)
    write_tile(folder / "one" / "sparse.las", pts, crs, scale=0.001)
    west = pts["x"] < X0 + SIZE / 2
    for name, m in (("w", west), ("e", ~west)):
        write_tile(folder / "two" / f"{name}.las", {k: v[m] for k, v in pts.items()}, crs, scale=0.001)
    return folder, pts


def dsm_of(folder, out, fill):
    report = rasters_from_tiles(folder, out, RasterSettings(cell_size="1m", dsm_fill=fill, products=("dsm",)))
    with rasterio.open(out / "dsm.vrt") as src:
        return src.read(1, masked=True).filled(np.nan).astype(float), src.transform, report


def reference_dsm(pts, transform, shape):
    """The highest return of each cell (numpy), on the raster's lattice (a point's cell: floor(x / cs), floor(y / cs)
    on the global lattice, README "Command line")."""
    col = (np.floor(pts["x"] / CS) - round(transform.c / CS)).astype(int)
    row = (round(transform.f / CS) - 1 - np.floor(pts["y"] / CS)).astype(int)
    ref = np.full(shape, -np.inf)
    ok = (row >= 0) & (row < shape[0]) & (col >= 0) & (col < shape[1])
    np.maximum.at(ref, (row[ok], col[ok]), np.float32(pts["z"][ok]))
    ref[np.isinf(ref)] = np.nan
    return ref


def window_extremes(a, r):
    from scipy import ndimage

    hi = ndimage.maximum_filter(np.where(np.isnan(a), -np.inf, a), size=2 * r + 1, mode="constant", cval=-np.inf)
    lo = ndimage.minimum_filter(np.where(np.isnan(a), np.inf, a), size=2 * r + 1, mode="constant", cval=np.inf)
    return lo, hi


@pytest.mark.parametrize("fill, reach", [("tin", 4), ("nearest", 4), ("subcircle", 1)])
def test_pinholes_are_filled_never_above_the_returns_around_them(tiles, tmp_path, fill, reach):
    folder, pts = tiles
    plain, transform, _ = dsm_of(folder / "one", tmp_path / "none", "none")
    ref = reference_dsm(pts, transform, plain.shape)
    np.testing.assert_allclose(plain, ref, atol=1e-4, equal_nan=True)  # the plain DSM is the per-cell maximum
    empty = np.isnan(plain)
    assert 0.25 < empty.mean() < 0.40
    got, _, report = dsm_of(folder / "one", tmp_path / fill, fill)
    filled = empty & np.isfinite(got)
    inner = np.zeros_like(empty)
    inner[3:-3, 3:-3] = True  # the block's outer edge has no returns beyond it
    assert filled[inner].sum() >= 0.9 * empty[inner].sum()  # the rest: holes wider than the 3-cell edge limit
    assert report["tiles"][0]["dsm_filled_cells"] == filled.sum()
    lo, hi = window_extremes(ref, reach)  # the returns a filled cell may come from lie within `reach` cells
    assert np.all(got[filled] <= hi[filled] + 1e-4)
    if fill in ("tin", "nearest"):
        assert np.all(got[filled] >= lo[filled] - 1e-4)  # a weighted mean of returns around it, or one of them
        np.testing.assert_array_equal(got[~empty], plain[~empty])  # only the holes change
    else:
        assert np.all(got[~empty] >= plain[~empty] - 1e-6)  # the subcircles widen the crowns, as lidR's


@pytest.mark.parametrize("fill", ["tin", "nearest", "subcircle"])
def test_two_tiles_fill_as_one(tiles, tmp_path, fill):
    folder, _ = tiles
    one, t1, _ = dsm_of(folder / "one", tmp_path / "one", fill)
    two, t2, report = dsm_of(folder / "two", tmp_path / "two", fill)
    assert report["counts"]["ok"] == 2 and t1 == t2
    np.testing.assert_array_equal(two, one)


def test_bad_fill_options_are_refused(tmp_path):
    with pytest.raises(InputError, match="dsm_fill"):
        rasters_from_tiles(tmp_path, tmp_path / "o", RasterSettings(dsm_fill="kriging"))
    with pytest.raises(InputError, match="subcircle"):
        rasters_from_tiles(tmp_path, tmp_path / "o", RasterSettings(dsm_fill="subcircle", subcircle="0m"))
    assert not (tmp_path / "o").exists()
