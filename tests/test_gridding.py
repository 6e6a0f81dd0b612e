"""Pure gridding functions against independent scipy oracles on synthetic points."""

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import cKDTree
from scipy.stats import binned_statistic_2d

from gistools.grid import cell_centres, snapped_grid
from gistools.lidar import dem_from_ground_points, dsm_from_points, ndsm_from, tin_to_grid, within_distance


@pytest.fixture
def cloud():
    rng = np.random.default_rng(7)
    x = rng.uniform(1000, 1400, 30000)
    y = rng.uniform(5000, 5300, 30000)
    z = 10 + 0.02 * x - 0.01 * y + np.sin(x / 20) + rng.normal(0, 0.1, x.size)
    return x, y, z


def test_dsm_is_the_max_per_cell(cloud):
    x, y, z = cloud
    g = snapped_grid((x.min(), y.min(), x.max(), y.max()), 5.0)
    dsm = dsm_from_points(x, y, z, g)
    w, s, e, n = g.bounds
    ref, _, _, _ = binned_statistic_2d(y, x, z, "max", bins=[np.linspace(s, n, g.height + 1), np.linspace(w, e, g.width + 1)])
    ref = ref[::-1]  # rows run north to south
    assert np.array_equal(np.isnan(dsm), np.isnan(ref))
    assert np.nanmax(np.abs(dsm - ref)) == 0.0


@pytest.mark.parametrize("chunks", [1, 3])
def test_top_class_is_the_class_of_the_highest_point_bare_on_ties(chunks):
    """max_with_class (compiled and numpy forms) against a point-by-point reference written here: per cell the highest
    z, and the class of the point giving it; on a tie within a call the last bare (ground 2, water 9) point, else the
    last point; on a tie with an earlier call's top, the call's class only when bare. Many ties (z in whole feet)."""
    from gistools.lidar.accumulate import _max_with_class_kernel, _max_with_class_numpy, max_with_class

    if _max_with_class_kernel() is None:
        pytest.fail("the compiled kernel is not built (pip install -e . with a C compiler)")
    rng = np.random.default_rng(11)
    n, m = 400, 2400
    cell = rng.integers(0, n, m)
    z = rng.integers(0, 4, m).astype(float)
    cls = rng.choice(np.array([1, 2, 3, 5, 6, 9], np.uint8), m)
    dsm_ref, top_ref = np.full(n, -np.inf), np.full(n, 255, np.uint8)
    dsm_c, top_c, dsm_np, top_np = dsm_ref.copy(), top_ref.copy(), dsm_ref.copy(), top_ref.copy()
    bare = {2, 9}
    for part in np.array_split(np.arange(m), chunks):
        best, win = {}, {}
        for i in part:  # the call's own maxima and winners
            c = cell[i]
            if c not in best or z[i] > best[c]:
                best[c], win[c] = z[i], cls[i]
            elif z[i] == best[c] and (cls[i] in bare or win[c] not in bare):
                win[c] = cls[i]
        for c in best:  # merged into what the earlier calls left
            if best[c] > dsm_ref[c] or (best[c] == dsm_ref[c] and win[c] in bare):
                top_ref[c] = win[c]
            dsm_ref[c] = max(dsm_ref[c], best[c])
        max_with_class(dsm_c, top_c, cell[part], z[part], cls[part])
        _max_with_class_numpy(dsm_np, top_np, cell[part], z[part], cls[part])
    for dsm, top in ((dsm_c, top_c), (dsm_np, top_np)):
        assert np.array_equal(dsm, dsm_ref) and np.array_equal(top, top_ref)


def test_points_at_cell_centres_give_z_exactly():
    g = snapped_grid((0, 0, 49.9, 49.9), 5.0)
    xs, ys = cell_centres(g)
    cx, cy = np.meshgrid(xs, ys)
    z = cx * 0.5 + cy
    assert np.array_equal(dsm_from_points(cx.ravel(), cy.ravel(), z.ravel(), g), z)


def test_tin_matches_scipy_linear_interpolation(cloud):
    x, y, z = cloud
    g = snapped_grid((1050, 5050, 1350, 5250), 2.0)
    dem = tin_to_grid(x, y, z, g)
    xs, ys = cell_centres(g)
    cx, cy = np.meshgrid(xs, ys)
    ref = LinearNDInterpolator(np.column_stack([x, y]), z)(cx, cy)
    assert np.isfinite(dem).all()
    assert np.max(np.abs(dem - ref)) < 1e-6


def test_tin_of_a_plane_is_the_plane_and_outside_the_hull_is_nan():
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0, 100, 500), rng.uniform(0, 100, 500)
    z = 3.0 + 0.25 * x - 0.5 * y
    g = snapped_grid((-50, -50, 150, 150), 5.0)
    dem = tin_to_grid(x, y, z, g)
    xs, ys = cell_centres(g)
    cx, cy = np.meshgrid(xs, ys)
    ok = np.isfinite(dem)
    assert np.allclose(dem[ok], (3.0 + 0.25 * cx - 0.5 * cy)[ok], atol=1e-9)
    assert not ok[0, 0] and ok[g.height // 2, g.width // 2]


def test_repeated_xy_are_merged_by_mean():
    x = np.array([0.0, 10, 0, 10, 5, 5])
    y = np.array([0.0, 0, 10, 10, 5, 5])
    z = np.array([0.0, 0, 0, 0, 2, 4])
    g = snapped_grid((4.0, 4.0, 5.9, 5.9), 1.0)  # cell centre (4.5, 4.5) and (5.5, 5.5)
    dem = tin_to_grid(x, y, z, g)
    assert np.isfinite(dem).all() and dem.max() == pytest.approx(3.0 * 0.9)


def test_within_distance_is_exact(cloud):
    x, y, _ = cloud
    keep = (x - 1200) ** 2 + (y - 5150) ** 2 > 60**2  # a hole with no points
    x, y = x[keep], y[keep]
    g = snapped_grid((1000, 5000, 1400, 5300), 3.0)
    mask = within_distance(g, x, y, 12.0)
    xs, ys = cell_centres(g)
    cx, cy = np.meshgrid(xs, ys)
    d, _ = cKDTree(np.column_stack([x, y])).query(np.column_stack([cx.ravel(), cy.ravel()]))
    assert np.array_equal(mask.ravel(), d <= 12.0)
    assert (~mask).sum() > 100  # the hole is really there


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("cell,limit", [(1.0, 0.5), (3.3, 7.07), (5.0, 15.0), (5.0, 49.2)])
def test_within_distance_equals_nearest_point_search(seed, cell, limit):
    """Two holes far apart (one cut by the grid's edge), points beyond the edges, limits below and above a cell
    diagonal: every cell as a brute-force nearest-point search decides it."""
    rng = np.random.default_rng(seed)
    x, y = rng.random(20000) * 1000, rng.random(20000) * 1000
    keep = ((x - 300) ** 2 + (y - 350) ** 2 > (60 + 40 * seed) ** 2) & ((x - 880) ** 2 + (y - 700) ** 2 > 90**2)
    x, y = x[keep], y[keep]
    g = snapped_grid((100, 100, 900, 900), cell)
    mask = within_distance(g, x, y, limit)
    xs, ys = cell_centres(g)
    cx, cy = np.meshgrid(xs, ys)
    d, _ = cKDTree(np.column_stack([x, y])).query(np.column_stack([cx.ravel(), cy.ravel()]))
    assert np.array_equal(mask.ravel(), d <= limit)


@pytest.mark.parametrize("method", ["max", "min", "mean"])
def test_cell_methods(cloud, method):
    x, y, z = cloud
    g = snapped_grid((1000, 5000, 1399, 5299), 10.0)
    dem = dem_from_ground_points(x, y, z, g, method=method)
    w, s, e, n = g.bounds
    ref, _, _, _ = binned_statistic_2d(y, x, z, method, bins=[np.linspace(s, n, g.height + 1), np.linspace(w, e, g.width + 1)])
    assert np.allclose(dem, ref[::-1], equal_nan=True)


def test_idw_reproduces_a_constant_and_honours_max_distance():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, 100, 2000), rng.uniform(0, 100, 2000)
    g = snapped_grid((0, 0, 199, 99), 5.0)
    dem = dem_from_ground_points(x, y, np.full(x.size, 7.5), g, method="idw", max_distance=10.0)
    assert np.allclose(dem[np.isfinite(dem)], 7.5)
    assert np.isnan(dem[:, -5:]).all()  # more than 10 from every point


def test_tin_dem_leaves_water_and_far_cells_nodata(cloud):
    x, y, z = cloud
    keep = (x - 1200) ** 2 + (y - 5150) ** 2 > 60**2
    g = snapped_grid((1000, 5000, 1399, 5299), 5.0)
    water = np.zeros(g.shape, bool)
    water[:3, :3] = True
    dem = dem_from_ground_points(x[keep], y[keep], z[keep], g, max_distance=20.0, water=water)
    assert np.isnan(dem[:3, :3]).all()
    r, c = (5300 - 5150) // 5, (1200 - 1000) // 5
    assert np.isnan(dem[r, c])  # centre of the 60-unit hole, > 20 from ground
    assert np.isfinite(dem[r, c + 14])  # outside the hole
    assert np.isnan(dem[r, c + 10])  # inside the hole, 7.5 from ground, but its triangles span the 120-wide hole (edge > 2 x 20)


def test_ndsm_where_both_valid():
    dsm = np.array([[5.0, np.nan], [3.0, 2.0]])
    dem = np.array([[1.0, 1.0], [np.nan, 2.5]])
    out = ndsm_from(dsm, dem)
    assert out[0, 0] == 4.0 and np.isnan(out[0, 1]) and np.isnan(out[1, 0]) and out[1, 1] == -0.5


def test_unknown_method_is_refused():
    g = snapped_grid((0, 0, 10, 10), 5.0)
    with pytest.raises(ValueError, match="tin"):
        dem_from_ground_points([1.0], [1.0], [1.0], g, method="kriging")


@pytest.mark.parametrize("radius,cell", [(25.0, 5.0), (7.62, 1.0), (3.0, 5.0), (10.0, 2.5), (25.0 * 1200 / 3937, 1.5)])
def test_disk_count_equals_scipy_correlate_and_cover_is_exact(radius, cell):
    from scipy import ndimage

    from gistools.lidar.density import disk_count, disk_kernel, point_density

    rng = np.random.default_rng(4)
    mask = rng.uniform(size=(157, 203)) < 0.4
    kernel = disk_kernel(radius, cell)
    ref = ndimage.correlate(mask.astype(np.float64), kernel.astype(np.float64), mode="constant", cval=0.0)
    assert np.array_equal(disk_count(mask, kernel), np.rint(ref).astype(np.int32))
    count, density, cover = point_density(np.ones((40, 40), bool), cell, radius)
    k = kernel.shape[0] // 2
    inner = (slice(k, 40 - k), slice(k, 40 - k))  # cells whose whole disk is inside the mask
    assert np.all(cover[inner] == 1.0) and np.allclose(density[inner], kernel.sum() / (np.pi * radius**2))
