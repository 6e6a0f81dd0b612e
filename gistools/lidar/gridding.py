"""DSM, DEM and nDSM from points on one snapped grid.

Pure functions over numpy arrays and a :class:`~gistools.grid.Grid`. Heights
stay in the CRS's vertical unit; empty cells are NaN.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..grid import Grid, cell_centres, cell_index
from ..parameters import choices, option
from .accumulate import finish_surface, max_into
from .tin import tin_engine, tin_to_grid, tin_to_grid_exact

__all__ = [
    "DEM_METHODS",
    "cell_statistic",
    "dsm_from_points",
    "dem_from_ground_points",
    "tin_dem_with_halo",
    "ndsm_from",
    "fill_voids",
    "DEM_FILLS",
    "within_distance",
]

DEM_METHODS = choices("dem_method")  # declared in gistools.parameters.rasters


def cell_statistic(grid: Grid, x, y, z, statistic: str = "max") -> np.ndarray:
    """Per-cell ``max``, ``min``, ``mean`` or ``count`` of z; NaN (0 for count) where a cell has no point."""
    flat = cell_index(grid, x, y)
    inside = flat >= 0
    flat = flat[inside]
    z = np.asarray(z, np.float64)[inside]
    n = grid.width * grid.height
    if statistic == "count":
        return np.bincount(flat, minlength=n).reshape(grid.shape)
    if statistic == "mean":
        count = np.bincount(flat, minlength=n)
        total = np.bincount(flat, weights=z, minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / np.maximum(count, 1), np.nan).reshape(grid.shape)
    if statistic in ("max", "min"):
        fill = -np.inf if statistic == "max" else np.inf
        acc = np.full(n, fill)
        (np.maximum if statistic == "max" else np.minimum).at(acc, flat, z)
        acc[np.isinf(acc)] = np.nan
        return acc.reshape(grid.shape)
    raise InputError(f"statistic {statistic!r} is not one of max, min, mean, count")


def dsm_from_points(x, y, z, grid: Grid) -> np.ndarray:
    """DSM: the highest z of the points in each cell; NaN where a cell holds none.

    Give the first returns of the classes the surface shows. The same accumulation as a streamed tile's, on all the
    points at once.

    Parameters
    ----------
    x, y : array_like
        Point coordinates, in CRS units.
    z : array_like
        Point heights, in the vertical unit (returned unchanged).
    grid : Grid
        The grid (see `gistools.snapped_grid`).

    Returns
    -------
    numpy.ndarray
        float64 DSM of ``grid.shape``, NaN = no point.

    Examples
    --------
    >>> from gistools import snapped_grid
    >>> g = snapped_grid((0.0, 0.0, 9.0, 9.0), 5.0)
    >>> dsm_from_points([1.0, 2.0, 7.0], [8.0, 9.0, 2.0], [10.0, 12.5, 3.0], g).tolist()
    [[12.5, nan], [nan, 3.0]]
    """
    flat = cell_index(grid, x, y)
    inside = flat >= 0
    dsm = np.full(grid.width * grid.height, -np.inf)
    max_into(dsm, flat[inside], np.asarray(z, np.float64)[inside])
    return finish_surface(dsm).reshape(grid.shape)


def within_distance(grid: Grid, x, y, max_distance: float) -> np.ndarray:
    """Boolean grid: the cell centre lies within ``max_distance`` (CRS units) of a point.

    Exact. A cell with a point in the square of k cells around it, k x cell diagonal + half a diagonal within
    ``max_distance``, is near (a maximum filter: most cells of a tile). Around the others (gaps: water, dense
    canopy), a Euclidean distance transform over the cells holding points (the grid padded by ``max_distance``,
    so points beyond the edges count) decides every cell except those within half a cell diagonal of the limit,
    which a k-d tree of the nearby points settles.
    """
    from scipy import ndimage  # here: a command that needs none (metrics) starts 0.04 s sooner

    cs = grid.cell_size
    reach = int(np.ceil(max_distance / cs)) + 1
    padded = grid.grown(reach)
    flat = cell_index(padded, x, y)
    occupied = np.zeros(padded.width * padded.height, bool)
    occupied[flat[flat >= 0]] = True
    occupied = occupied.reshape(padded.shape)
    if not occupied.any():
        return np.zeros(grid.shape, bool)
    half_diag = cs * np.sqrt(0.5)
    k = int(np.floor((max_distance * (1 - 1e-9) - half_diag) / (cs * np.sqrt(2))))
    if k >= 1:
        result = ndimage.maximum_filter(occupied.view(np.uint8), size=2 * k + 1, mode="constant").view(bool)
    else:
        result = occupied & (half_diag <= max_distance * (1 - 1e-9))
    inner = (slice(reach, -reach), slice(reach, -reach))
    rest = np.zeros(padded.shape, bool)
    rest[inner] = ~result[inner]
    if not rest.any():
        return result[inner]
    # the window of the cells left, with every cell within reach (+ 2 for the k-d tree's candidates) of them
    rows, cols = np.nonzero(rest)
    m = reach + 2
    r0, r1 = max(rows.min() - m, 0), min(rows.max() + m + 1, padded.height)
    c0, c1 = max(cols.min() - m, 0), min(cols.max() + m + 1, padded.width)
    win = (slice(r0, r1), slice(c0, c1))
    dist = ndimage.distance_transform_edt(~occupied[win]) * cs
    left = rest[win]
    decided = left & (dist + half_diag <= max_distance)
    unsure = left & (np.abs(dist - max_distance) <= half_diag) & ~decided
    result[win] |= decided
    if unsure.any():
        pick = flat >= 0
        fr, fc = np.divmod(flat[pick], padded.width)
        pick[pick] = (fr >= r0) & (fr < r1) & (fc >= c0) & (fc < c1)
        from scipy.spatial import cKDTree  # here: scipy.spatial costs a worker 0.1 s to import, and few tiles need it

        tree = cKDTree(np.column_stack([np.asarray(x)[pick], np.asarray(y)[pick]]))
        ur, uc = np.nonzero(unsure)
        xs, ys = cell_centres(padded)
        d, _ = tree.query(np.column_stack([xs[uc + c0], ys[ur + r0]]), distance_upper_bound=max_distance * (1 + 1e-12))
        result[ur + r0, uc + c0] = d <= max_distance
    return result[inner]


def _idw(grid: Grid, x, y, z, max_distance: float, k: int = 8, power: float = 2.0) -> np.ndarray:
    from scipy.spatial import cKDTree

    xs, ys = cell_centres(grid)
    cx, cy = np.meshgrid(xs, ys)
    tree = cKDTree(np.column_stack([x, y]))
    k = min(k, len(x))
    d, i = tree.query(np.column_stack([cx.ravel(), cy.ravel()]), k=k, distance_upper_bound=max_distance)
    d = d.reshape(-1, k)
    i = i.reshape(-1, k)
    valid = np.isfinite(d)
    zz = np.where(valid, np.asarray(z, np.float64)[np.minimum(i, len(x) - 1)], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(valid, 1.0 / np.maximum(d, 1e-12) ** power, 0.0)
        out = (w * zz).sum(axis=1) / w.sum(axis=1)
    exact = valid[:, 0] & (d[:, 0] < 1e-12)
    out[exact] = zz[exact, 0]
    out[~valid[:, 0]] = np.nan
    return out.reshape(grid.shape)


def dem_from_ground_points(
    x,
    y,
    z,
    grid: Grid,
    *,
    method: str = "tin",
    max_distance: float | None = None,
    max_edge: float | None = None,
    water: np.ndarray | None = None,
    engine: str | None = None,
) -> np.ndarray:
    """DEM of ground points on ``grid``; NaN = nodata.

    Give ground points from a buffer around the grid (neighbouring tiles) so that edge cells equal those of one
    mosaic-wide computation.

    Parameters
    ----------
    x, y : array_like
        Ground point coordinates, in CRS units.
    z : array_like
        Ground heights, in the vertical unit (returned unchanged).
    grid : Grid
        The grid (see `gistools.snapped_grid`).
    method : str
        ``"tin"`` (Delaunay, linear, evaluated at cell centres; fills cells without ground points under vegetation),
        ``"max"`` (highest point per cell, gaps stay NaN), ``"min"``, ``"mean"``, or ``"idw"`` (the 8 nearest within
        ``max_distance``, power 2).
    max_distance : float, optional
        CRS units (tin, idw): cells whose centre is farther from every ground point stay NaN. None: no limit.
    max_edge : float, optional
        CRS units (tin): triangles with a longer edge are left out. None: 2 x ``max_distance``.
    water : numpy.ndarray, optional
        Boolean grid of ``grid.shape``; its True cells (water) stay NaN.
    engine : str, optional
        TIN engine: ``"kernel"``, ``"triangle"`` or ``"qhull"``; None: the fastest one installed.

    Returns
    -------
    numpy.ndarray
        float64 DEM of ``grid.shape``, in the vertical unit.

    Raises
    ------
    InputError
        ``method`` is not one of the above.

    Examples
    --------
    >>> from gistools import snapped_grid
    >>> g = snapped_grid((0.0, 0.0, 9.0, 9.0), 5.0)
    >>> dem_from_ground_points([0.0, 10.0, 0.0, 10.0], [0.0, 0.0, 10.0, 10.0], [0.0, 10.0, 0.0, 10.0], g).tolist()
    [[2.5, 7.5], [2.5, 7.5]]
    """
    if method not in DEM_METHODS:
        raise InputError(f"DEM method {method!r} is not one of {', '.join(DEM_METHODS)}", hint=f"Use {option('dem_method', 'tin')}")
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    z = np.asarray(z, np.float64)
    if len(x) == 0:
        dem = np.full(grid.shape, np.nan)
    elif method in ("max", "min", "mean"):
        dem = cell_statistic(grid, x, y, z, method)
    elif method == "idw":
        dem = _idw(grid, x, y, z, max_distance if max_distance else np.inf)
    else:
        if max_edge is None and max_distance is not None:
            max_edge = 2 * max_distance
        dem = tin_to_grid(x, y, z, grid, max_edge=max_edge, engine=engine)
    if method in ("tin", "idw") and len(x):
        dem[~_kept_cells(grid, x, y, max_distance, water)] = np.nan
    elif water is not None:
        dem[water] = np.nan
    return dem


def _kept_cells(grid: Grid, x, y, max_distance: float | None, water: np.ndarray | None) -> np.ndarray:
    """Cells an interpolated DEM keeps: centre within ``max_distance`` of a ground point (None: any), not water."""
    kept = within_distance(grid, x, y, max_distance) if max_distance is not None else np.ones(grid.shape, bool)
    if water is not None:
        kept &= ~water
    return kept


def _windows(todo: np.ndarray, gap: int = 2, limit: int = 64) -> list[tuple[slice, slice]]:
    """Row / column windows around clusters of the True cells of ``todo`` (cells closer than ``gap`` joined)."""
    from scipy import ndimage

    labels, count = ndimage.label(ndimage.binary_dilation(todo, np.ones((3, 3), bool), iterations=gap))
    boxes = [b for b in ndimage.find_objects(labels) if b is not None]
    if len(boxes) > limit:
        return _windows(todo, gap * 4, limit)
    return boxes


def tin_dem_with_halo(x, y, z, grid: Grid, *, halo: float, max_distance: float, water: np.ndarray | None = None,
                      inner_halo: float | None = None, engine: str | None = None) -> np.ndarray:
    """TIN DEM of ground points given with a halo around ``grid`` (neighbouring tiles): the values of
    ``dem_from_ground_points(..., method="tin")`` on all of them, computed on fewer points.

    ``halo`` (CRS units): how far beyond the grid the points reach (at least 2 x ``max_distance``, the
    longest triangle edge kept). The TIN is first built on the points within ``inner_halo`` of the grid
    (default: 10 point spacings, at least 2 cells); a cell whose triangle has its circumcircle inside that
    area (or beyond it only on sides where no point lies farther out) has the value (or nodata) the TIN of
    all the points gives. The few others (gaps near the edges) are computed again from the points around
    them, in growing halos until their triangles are known to be Delaunay for all the points, or from the
    full ``halo`` around them (as a tile's TIN of its buffered points gives them).
    ``water``: cells that stay nodata. ``engine``: the TIN engine (lidar.tin; None = the default; the
    "triangle" engine finds no exact cell, so it triangulates all the points at once).
    """
    engine = tin_engine(engine)
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    cs = grid.cell_size
    w, s, e, n = grid.bounds
    max_edge = 2 * max_distance
    dem = np.full(grid.shape, np.nan)
    if len(x) == 0:
        return dem
    needed = _kept_cells(grid, x, y, max_distance, water)
    if inner_halo is None:
        in_grid = np.count_nonzero((x >= w) & (x <= e) & (y >= s) & (y <= n))
        spacing = np.sqrt((e - w) * (n - s) / max(in_grid, 1))
        inner_halo = float(np.clip(10 * spacing, 2 * cs, halo))
    if engine != "kernel" or inner_halo >= halo:
        tin_to_grid(x, y, z, grid, dem, max_edge=max_edge, engine=engine)
        dem[~needed] = np.nan
        return dem
    extent = (x.min(), y.min(), x.max(), y.max())
    box = _open_box((w - inner_halo, s - inner_halo, e + inner_halo, n + inner_halo), extent)
    sel = (x >= w - inner_halo) & (x <= e + inner_halo) & (y >= s - inner_halo) & (y <= n + inner_halo)
    dem, exact = tin_to_grid_exact(x[sel], y[sel], z[sel], grid, box, max_edge=max_edge, engine=engine)
    # centres outside the points' bounding box are outside every TIN of them (the edge of a block of tiles)
    xs, ys = cell_centres(grid)
    exact |= ((xs < extent[0]) | (xs > extent[2]))[None, :] | ((ys < extent[1]) | (ys > extent[3]))[:, None]
    todo = needed & ~exact
    if not todo.any():
        dem[~needed] = np.nan
        return dem
    # windows around the cells left, and the points within the halo of a window (read again when a halo grows past it)
    windows = _windows(todo)
    reach = int(np.ceil(halo / cs)) + 1
    padded = grid.grown(reach)
    near = np.zeros(padded.shape, bool)
    for rows, cols in windows:
        near[rows.start:rows.stop + 2 * reach, cols.start:cols.stop + 2 * reach] = True
    flat = cell_index(padded, x, y)
    cand = np.flatnonzero((flat >= 0) & near.reshape(-1)[np.maximum(flat, 0)])
    cx, cy, cz = x[cand], y[cand], z[cand]
    for rows, cols in windows:
        sub = grid.part(cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start)
        sw, ss, se, sn = sub.bounds
        left = todo[rows, cols].copy()
        h = min(2 * inner_halo, halo)
        while left.any():
            pick = (cx >= sw - h) & (cx <= se + h) & (cy >= ss - h) & (cy <= sn + h)
            wbox = _open_box((sw - h, ss - h, se + h, sn + h), extent)
            part, ex = tin_to_grid_exact(cx[pick], cy[pick], cz[pick], sub, wbox, max_edge=max_edge, engine=engine)
            if h >= halo or (wbox[0] < -1e299 and wbox[1] < -1e299 and wbox[2] > 1e299 and wbox[3] > 1e299):
                done = left  # the full halo (or every point) around them: what one TIN of the tile's points gives
            else:
                done = left & ex
            dem[rows, cols][done] = part[done]
            left &= ~done
            h = min(2 * h, halo)
    dem[~needed] = np.nan
    return dem


def _open_box(box, extent) -> list[float]:
    """``box`` with each side that no point lies beyond (``extent``: the points' west, south, east, north)
    moved to infinity: it bounds no circumcircle."""
    w, s, e, n = box
    big = 1e300
    return [w if extent[0] < w else -big, s if extent[1] < s else -big, e if extent[2] > e else big,
            n if extent[3] > n else big]


DEM_FILLS = choices("dem_fill")


def fill_voids(dem: np.ndarray, grid: Grid, x, y, z, *, method: str, keep: np.ndarray | None = None,
               engine: str | None = None) -> int:
    """In place: the DEM's empty cells (except those of ``keep``, e.g. water) from the ground points (x, y, z):
    ``tin``, a TIN of them with no edge limit (cells outside their hull stay empty), or ``idw``, the 8 nearest by
    inverse distance squared; returns how many cells were filled."""
    void = np.isnan(dem)
    if keep is not None:
        void &= ~keep
    if method == "none" or not void.any() or len(x) < 3:
        return 0
    if method == "tin":
        filled = tin_to_grid(x, y, z, grid, engine=engine)
    else:
        filled = _idw(grid, x, y, z, np.inf)
    take = void & np.isfinite(filled)
    dem[take] = filled[take]
    return int(np.count_nonzero(take))


def ndsm_from(dsm: np.ndarray, dem: np.ndarray) -> np.ndarray:
    """nDSM = DSM - DEM where both are valid, NaN elsewhere: heights above ground.

    Computed on the float32 values that the DSM and DEM rasters store, so it equals the nDSM of the rasters.

    Parameters
    ----------
    dsm : numpy.ndarray
        Surface heights, in the vertical unit.
    dem : numpy.ndarray
        Ground heights of the same shape, in the same unit.

    Returns
    -------
    numpy.ndarray
        float32 heights above ground, in the vertical unit.

    Examples
    --------
    >>> import numpy as np
    >>> ndsm_from(np.array([[12.5, np.nan]]), np.array([[10.0, 9.0]])).tolist()
    [[2.5, nan]]
    """
    dsm32 = np.asarray(dsm, np.float32)
    dem32 = np.asarray(dem, np.float32)
    return np.where(np.isfinite(dsm32) & np.isfinite(dem32), dsm32 - dem32, np.float32(np.nan))
