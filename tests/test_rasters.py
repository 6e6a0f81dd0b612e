"""The rasters task on the sample block and on the real files of ../shared/data, against independent oracles."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from scipy.interpolate import LinearNDInterpolator
from scipy.stats import binned_statistic_2d

from conftest import read_las_independently, tin_oracle
from gistools import RasterSettings, rasters_from_tiles
from gistools.grid import Grid, cell_centres
from gistools.io.raster import read_raster
from gistools.lidar import within_distance
from gistools.synthetic import ground_z
from gistools.units import US_SURVEY_FOOT


def mosaic(out, product):
    return read_raster(out / f"{product}.vrt")


def first_return_max(grid: Grid, paths, classes=None):
    """Independent DSM: scipy binned max of first returns (all but noise 7/18 and withheld)."""
    x, y, z, cls, rn, withheld = read_las_independently(paths)
    keep = (rn <= 1) & ~withheld & (~np.isin(cls, [7, 18]) if classes is None else np.isin(cls, classes))
    w, s, e, n = grid.bounds
    ref, _, _, _ = binned_statistic_2d(
        y[keep], x[keep], z[keep], "max",
        bins=[np.linspace(s, n, grid.height + 1), np.linspace(w, e, grid.width + 1)],
    )
    return ref[::-1]


def test_sample_run_writes_all_products(sample_run, sample_tiles):
    out, summary = sample_run
    assert summary["counts"] == {"ok": 4, "failed": 0, "skipped": 0}
    assert summary["crs"].startswith("EPSG:2882")
    assert summary["cell_size"] == 5.0 and summary["horizontal_unit"] == "US survey foot"
    for product in ("dsm", "dem", "ndsm"):
        tifs = sorted((out / product).glob("*.tif"))
        assert [t.stem for t in tifs] == sorted(t.stem for t in sample_tiles)
        with rasterio.open(tifs[0]) as src:
            assert src.crs.to_epsg() == 2882
            assert src.dtypes[0] == "float32" and src.nodata == -9999.0
            assert src.res == (5.0, 5.0) and src.profile["compress"] == "deflate"
            assert src.units[0] == "ftUS"
            assert src.transform.c % 5.0 == 0 and src.transform.f % 5.0 == 0
        with rasterio.open(out / f"{product}.vrt") as vrt:
            assert vrt.shape == (400, 400) and vrt.bounds == (430000.0, 1810000.0, 432000.0, 1812000.0)
    tile = summary["tiles"][0]
    assert tile["points"] == sum(tile["points_by_class"].values()) > 60000
    assert set(tile["points_by_class"]) <= {1, 2, 9}
    assert not list(out.rglob("*.partial")) and not list(out.glob(".gistools-scratch-*"))


def test_sample_tiles_mosaic_without_gaps_or_overlaps(sample_run):
    out, _ = sample_run
    grids = []
    for tif in sorted((out / "dsm").glob("*.tif")):
        with rasterio.open(tif) as src:
            grids.append(src.bounds)
    area = sum((b.right - b.left) * (b.top - b.bottom) for b in grids)
    assert area == 2000.0 * 2000.0  # four 1000 ft tiles, no overlap, no gap


def test_dsm_equals_independent_max_of_first_returns_on_sample(sample_run, sample_tiles):
    out, _ = sample_run
    dsm, grid, _ = mosaic(out, "dsm")
    ref = first_return_max(grid, sample_tiles)
    assert np.array_equal(np.isnan(dsm), np.isnan(ref))
    assert np.nanmax(np.abs(dsm - ref)) < 1e-4  # float32 storage of values with 0.01 ft scale


def test_dsm_equals_independent_max_on_real_files(real_tile, tmp_path):
    rasters_from_tiles([real_tile], tmp_path, RasterSettings(cell_size="1m"))
    dsm, grid, _ = mosaic(tmp_path, "dsm")
    ref = first_return_max(grid, [real_tile])
    assert np.array_equal(np.isnan(dsm), np.isnan(ref))
    assert np.nanmax(np.abs(dsm - ref)) < 1e-3


def test_dem_tin_matches_scipy_on_sample(sample_run, sample_tiles):
    out, summary = sample_run
    dem, grid, _ = mosaic(out, "dem")
    ref, interior, nodata, decided = tin_oracle(grid, sample_tiles, summary["dem_max_distance"])
    assert np.array_equal(np.isnan(dem)[decided], nodata[decided])  # nodata by an independent rule
    both = interior & np.isfinite(dem)
    assert both.sum() > 0.9 * grid.width * grid.height * 0.9
    assert np.max(np.abs(dem[both] - ref[both])) < 0.001 / US_SURVEY_FOOT  # 1 mm


def test_dem_tin_matches_scipy_on_real_files(real_tile, tmp_path):
    summary = rasters_from_tiles([real_tile], tmp_path, RasterSettings(cell_size="1m"))
    dem, grid, _ = mosaic(tmp_path, "dem")
    ref, interior, nodata, decided = tin_oracle(grid, [real_tile], summary["dem_max_distance"])
    assert np.array_equal(np.isnan(dem)[decided], nodata[decided])  # nodata by an independent rule
    both = interior & np.isfinite(dem)
    assert both.sum() > 1000
    diff = np.abs(dem[both] - ref[both])
    mm = 0.001 / (summary["cell_size_m"] / summary["cell_size"])  # 1 mm in the file's vertical unit
    assert np.max(diff) < mm, f"max |TIN - scipy| = {np.max(diff):.6f} at {np.sum(diff >= mm)} cells"


def test_dem_error_against_the_true_ground_surface(sample_run, record_property):
    out, _ = sample_run
    dem, grid, _ = mosaic(out, "dem")
    xs, ys = cell_centres(grid)
    cx, cy = np.meshgrid(xs, ys)
    truth = ground_z(cx, cy, (430000.0, 1810000.0))
    ok = np.isfinite(dem)
    rmse = float(np.sqrt(np.mean((dem[ok] - truth[ok]) ** 2)))
    record_property("dem_rmse_ft", rmse)
    print(f"\nDEM (TIN) RMSE against the generator's true ground: {rmse:.4f} ft over {ok.sum()} cells")
    assert rmse < 0.2
    assert ok.mean() > 0.9  # water and far-from-ground cells only are nodata


def test_ndsm_is_dsm_minus_dem(sample_run):
    out, _ = sample_run
    dsm, _, _ = mosaic(out, "dsm")
    dem, _, _ = mosaic(out, "dem")
    ndsm, _, _ = mosaic(out, "ndsm")
    both = np.isfinite(dsm) & np.isfinite(dem)
    assert np.array_equal(np.isfinite(ndsm), both)
    assert np.allclose(ndsm[both], (dsm - dem)[both], atol=1e-4)


def test_dissertation_parity_options(sample_tiles, tmp_path):
    """--dem-method max --dsm-classes 1,2: DEM = max of ground per cell, DSM over classes 1 and 2 only."""
    s = rasters_from_tiles(sample_tiles, tmp_path, RasterSettings(dem_method="max", dsm_classes=(1, 2)))
    assert s["counts"]["ok"] == 4
    dsm, grid, _ = mosaic(tmp_path, "dsm")
    ref = first_return_max(grid, sample_tiles, classes=(1, 2))
    assert np.array_equal(np.isnan(dsm), np.isnan(ref)) and np.nanmax(np.abs(dsm - ref)) < 1e-4
    dem, _, _ = mosaic(tmp_path, "dem")
    x, y, z, cls, _, _ = read_las_independently(sample_tiles)
    g = cls == 2
    w, s_, e, n = grid.bounds
    ref, _, _, _ = binned_statistic_2d(y[g], x[g], z[g], "max", bins=[np.linspace(s_, n, grid.height + 1), np.linspace(w, e, grid.width + 1)])
    ref = ref[::-1]
    assert np.array_equal(np.isnan(dem), np.isnan(ref)) and np.nanmax(np.abs(dem - ref)) < 1e-4
    assert np.isnan(dem).mean() > 0.05  # the dissertation's gaps under vegetation


@pytest.mark.parametrize("chunk_size", [7_777])
def test_chunked_equals_whole(sample_tiles, tmp_path, chunk_size, sample_run):
    whole_out, _ = sample_run
    rasters_from_tiles(sample_tiles[:1] + sample_tiles[1:], tmp_path, RasterSettings(chunk_size=chunk_size))
    for product in ("dsm", "dem", "ndsm"):
        a, _, _ = mosaic(whole_out, product)
        b, _, _ = mosaic(tmp_path, product)
        assert np.array_equal(a, b, equal_nan=True)
