"""Class breaks against an independent implementation: Fisher-Jenks natural breaks of jenkspy."""

from __future__ import annotations

import jenkspy  # test extra: an independent Fisher-Jenks
import numpy as np
import pytest

from gistools.lidar.shrub import jenks_breaks, quantile_breaks


@pytest.mark.parametrize("seed", range(6))
def test_jenks_breaks_equal_jenkspy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 800))
    centres = np.sort(rng.uniform(0.05, 0.95, 3))
    v = np.concatenate([rng.normal(c, rng.uniform(0.01, 0.08), n) for c in centres]).clip(0.001, 1.0)
    v = np.round(v, 3)  # ties, as cover fractions of a disk have
    expect = jenkspy.jenks_breaks(v, n_classes=3)[1:3]
    assert jenks_breaks(v, sample=v.size) == pytest.approx(tuple(expect), abs=0)


def test_quantile_breaks_equal_numpys_equal_count_split():
    v = np.random.default_rng(3).uniform(0, 1, 3001)
    b1, b2 = quantile_breaks(v)
    assert np.mean(v <= b1) == pytest.approx(1 / 3, abs=1e-3) and np.mean(v <= b2) == pytest.approx(2 / 3, abs=1e-3)


@pytest.mark.parametrize("method", ["jenks", "quantile"])
def test_breaks_do_not_depend_on_tiles_or_blocks(tmp_path, method):
    """A 1200 x 1200 cover split into 3 x 3 tiles that share their edge rows and columns (as the chain writes them),
    and the VRT mosaic read in blocks of several sizes: the same sampled cells, the same breaks."""
    import pyproj

    from gistools.grid import snapped_grid
    from gistools.io.raster import read_raster, write_raster, write_vrt
    from gistools.lidar.shrub import breaks_from_sample, lattice_sample, sample_step
    from gistools.products.steps import class_breaks

    rng = np.random.default_rng(7)
    cs, n = 5.0, 1200
    yy, xx = np.mgrid[0:n, 0:n]
    cover = np.clip(0.5 + 0.3 * np.sin(xx / 37.0) * np.cos(yy / 53.0) + rng.normal(0, 0.1, (n, n)), 0, 1)
    cover[rng.uniform(size=cover.shape) < 0.3] = np.nan
    crs = pyproj.CRS(2882)
    tiles = []
    for i in range(3):
        for j in range(3):
            r0, r1 = max(0, i * 400 - 1), min(n, (i + 1) * 400 + 1)  # one shared row / column with each neighbour
            c0, c1 = max(0, j * 400 - 1), min(n, (j + 1) * 400 + 1)
            grid = snapped_grid((1000 + c0 * cs, 2000 + (n - r1) * cs, 1000 + c1 * cs - 1e-6, 2000 + (n - r0) * cs - 1e-6), cs, crs)
            tiles.append(write_raster(tmp_path / f"t{i}{j}.tif", cover[r0:r1, c0:c1], grid))
    step = sample_step(n * n)
    samples = [lattice_sample(a, g.col0, g.row_top, step) for a, g, _ in map(read_raster, tiles)]
    per_tile = breaks_from_sample([k for k, _ in samples], [v for _, v in samples], method)
    vrt = write_vrt(tmp_path / "cover.vrt", tiles)
    for block in (0, 100, 256, 777, 2048):
        assert class_breaks(vrt, method, block=block) == pytest.approx(per_tile, abs=0), block
