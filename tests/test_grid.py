import numpy as np
import pytest
from affine import Affine

from gistools.grid import Grid, affine_apply, cell_centres, cell_index, snapped_grid


def test_snapped_grid_edges_are_multiples_of_the_cell_size():
    g = snapped_grid((430000.39, 1811000.44, 430999.65, 1811999.62), 5.0)
    assert g.bounds == (430000.0, 1811000.0, 431000.0, 1812000.0)
    assert g.shape == (200, 200)
    g2 = snapped_grid((12.3, 7.9, 13.1, 8.2), 0.5)
    assert g2.bounds == (12.0, 7.5, 13.5, 8.5)


def test_point_on_an_edge_goes_to_the_cell_east_and_north():
    g = snapped_grid((0.0, 0.0, 10.0, 10.0), 5.0)
    # max edge 10.0 makes a third column/row: half-open cells [10, 15)
    assert g.shape == (3, 3)
    flat = cell_index(g, np.array([0.0, 5.0, 9.999, 10.0]), np.array([0.0, 0.0, 0.0, 0.0]))
    rows, cols = np.divmod(flat, g.width)
    assert cols.tolist() == [0, 1, 1, 2]
    assert rows.tolist() == [2, 2, 2, 2]


def test_cell_index_is_the_same_whatever_grid_holds_the_point():
    a = snapped_grid((0, 0, 100, 100), 2.5)
    b = snapped_grid((50, 50, 300, 300), 2.5)
    x, y = np.array([60.1, 77.7]), np.array([55.0, 99.99])
    fa, fb = cell_index(a, x, y), cell_index(b, x, y)
    ra, ca = np.divmod(fa, a.width)
    rb, cb = np.divmod(fb, b.width)
    xa, ya = cell_centres(a)
    xb, yb = cell_centres(b)
    assert np.allclose(xa[ca], xb[cb]) and np.allclose(ya[ra], yb[rb])


def test_outside_points_get_minus_one():
    g = snapped_grid((0, 0, 10, 10), 5.0)
    assert cell_index(g, np.array([-0.1, 20.0]), np.array([1.0, 1.0])).tolist() == [-1, -1]


def test_compiled_cell_index_equals_the_numpy_form_and_floor_division():
    """The kernel's one-pass cell_index against its numpy form and against integer-lattice floor division written
    here, on state-plane coordinates: points on every edge, on the lattice, outside, NaN and infinite."""
    from gistools import kernel
    from gistools.grid import _cell_index_numpy

    if kernel.function("gt_cell_index") is None:
        pytest.fail("the compiled kernel is not built (pip install -e . with a C compiler)")
    rng = np.random.default_rng(3)
    for cs in (5.0, 1.0, 0.5, 3.0):
        g = snapped_grid((430000.0, 1810000.0, 430000.0 + 997 * cs, 1810000.0 + 1003 * cs), cs)
        w, s, e, n = g.bounds
        x = rng.uniform(w - 20 * cs, e + 20 * cs, 200_000)
        y = rng.uniform(s - 20 * cs, n + 20 * cs, 200_000)
        x[:100], y[100:200], x[200:300], y[300:400] = w, n, e, s
        x[400:2000] = np.round(x[400:2000] / cs) * cs
        x[2000], y[2001], x[2002] = np.nan, np.inf, -np.inf
        flat = cell_index(g, x, y)
        with np.errstate(invalid="ignore"):
            assert np.array_equal(flat, _cell_index_numpy(g, x, y))
        # points on a 0.01 lattice (LAS coordinates): integer floor division gives the cell
        ix, iy = np.round(x[2003:] * 100).astype(np.int64), np.round(y[2003:] * 100).astype(np.int64)
        c100 = int(round(cs * 100))
        col = ix // c100 - int(round(w * 100)) // c100
        row = int(round(n * 100)) // c100 - 1 - iy // c100
        inside = (col >= 0) & (col < g.width) & (row >= 0) & (row < g.height)
        expect = np.where(inside, row * g.width + col, -1)
        assert np.array_equal(cell_index(g, ix / 100, iy / 100), expect)


def test_window_in_overlap():
    a = snapped_grid((0, 0, 99, 99), 10.0)  # 10 x 10
    b = snapped_grid((90, 50, 150, 120), 10.0)
    rs, cs, ro, co = a.window_in(b)
    assert (rs.stop - rs.start, cs.stop - cs.start) == (5, 1)
    assert (ro.stop - ro.start, co.stop - co.start) == (5, 1)
    assert a.window_in(snapped_grid((200, 200, 300, 300), 10.0)) is None
    g = Grid(Affine(10, 0, 0, 0, -10, 100), 10, 10)
    with pytest.raises(ValueError):
        g.window_in(snapped_grid((0, 0, 10, 10), 5.0))


@pytest.mark.parametrize("dtype,nodata", [("float32", -9999.0), ("uint8", 255)])
def test_read_window_equals_a_boundless_read(tmp_path, dtype, nodata):
    """read_window reads the part inside the raster and fills the rest: the cells of rasterio's boundless read, for
    windows inside, across every edge and wholly outside, with and without a halo, from a GeoTIFF and a VRT."""
    import rasterio
    from rasterio.windows import Window, from_bounds

    from gistools.io.blocks import read_window
    from gistools.io.raster import write_raster, write_vrt

    rng = np.random.default_rng(4)
    g = snapped_grid((1000.0, 2000.0, 1300.0, 2200.0), 2.0)
    data = rng.uniform(0, 100, g.shape).astype(dtype)
    data[rng.uniform(size=g.shape) < 0.1] = nodata
    tif = write_raster(tmp_path / "a.tif", data, g, dtype=dtype, nodata=nodata)
    vrt = write_vrt(tmp_path / "a.vrt", [tif])
    base_grid = snapped_grid((1100.0, 2050.0, 1500.0, 2300.0), 2.0)
    base_path = write_raster(tmp_path / "base.tif", np.zeros(base_grid.shape), base_grid)
    with rasterio.open(base_path) as base:
        for path in (tif, vrt):
            with rasterio.open(path) as src:
                for win in (Window(0, 0, 40, 30), Window(-10, -10, 60, 50), Window(180, 120, 40, 30), Window(190, 5, 30, 20)):
                    for halo, fill in ((0, None), (5, 0)):
                        ours = read_window(src, base, win, halo=halo, fill=fill)
                        west, north = affine_apply(base.transform, (win.col_off - halo, win.row_off - halo))
                        east, south = west + (win.width + 2 * halo) * 2.0, north - (win.height + 2 * halo) * 2.0
                        w = from_bounds(west, south, east, north, src.transform).round_offsets().round_lengths()
                        ref = src.read(1, window=w, boundless=True, fill_value=nodata if fill is None else fill, masked=False)
                        if dtype == "float32":
                            ref = ref.astype(np.float64)
                            ref[ref == nodata] = np.nan
                        assert np.array_equal(ours, ref, equal_nan=True)


def test_grid_transforms_warn_on_no_affine_version_and_agree_with_rasterio():
    """affine 3 deprecates ``*`` for products (a PendingDeprecationWarning, later an error); the grids are made and
    applied without it, and their cell centres are rasterio's (rasterio.transform.xy)."""
    import warnings

    from rasterio.transform import xy

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grid = snapped_grid((500003.2, 4100001.7, 500051.0, 4100040.3), 2.0)
        grown = grid.grown(3)
        part = grid.part(5, 4, 6, 7)
        x, y = affine_apply(grid.transform, (np.array([0.5, 7.5]), np.array([0.5, 9.5])))
    assert grown.bounds == (grid.bounds[0] - 6, grid.bounds[1] - 6, grid.bounds[2] + 6, grid.bounds[3] + 6)
    assert part.bounds == (grid.bounds[0] + 10, grid.bounds[3] - 8 - 14, grid.bounds[0] + 22, grid.bounds[3] - 8)
    want = xy(grid.transform, [0, 9], [0, 7])
    np.testing.assert_allclose(x, want[0])
    np.testing.assert_allclose(y, want[1])
