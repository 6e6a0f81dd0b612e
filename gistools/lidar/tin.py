"""Delaunay TIN of points, evaluated by linear interpolation at grid cell centres.

Two engines give the same Delaunay triangulation (up to the choice between equally valid
triangles of cocircular points): gistools' compiled kernel (``csrc/tin.c``: the sweep-hull
algorithm of Delaunator with exact integer predicates, plus a rasteriser; 2.3x faster than
Triangle and the numpy evaluation on a 2 M point tile, docs/performance.md), built when the package
is installed with a C compiler; Shewchuk's Triangle (``triangle`` on PyPI, optional: it has no build for
Python 3.14) with a numpy evaluation; and scipy's Qhull (always there) with the same numpy evaluation.
Every function takes ``engine`` ("kernel", "triangle" or "qhull"); None is ``DEFAULT_ENGINE``: the
kernel when it is built, else Triangle when installed, else Qhull, unless the environment variable
``GISTOOLS_TIN`` names one (read once, when gistools is imported). Either way the evaluation costs in
proportion to the cells, not to points x cells.
"""

from __future__ import annotations

import os

import numpy as np

try:
    import triangle as _triangle
except ImportError:  # optional (no wheel or build for Python 3.14): scipy's Qhull then
    _triangle = None

from .. import kernel
from ..grid import Grid

__all__ = ["delaunay_triangles", "merge_repeats", "tin_at_points", "tin_to_grid", "tin_to_grid_exact", "tin_engine", "ENGINES", "DEFAULT_ENGINE"]


_QUANTUM_STEPS = 2**30  # the kernel's integer coordinates span at most this many steps (its exact predicates allow 2^30)


ENGINES = ("kernel", "triangle", "qhull")


def _default_engine() -> str:
    asked = os.environ.get("GISTOOLS_TIN", "").lower()
    available = [e for e, ok in zip(ENGINES, (kernel.loaded(), _triangle is not None, True)) if ok]
    return asked if asked in available else available[0]


DEFAULT_ENGINE = _default_engine()


def tin_engine(engine: str | None = None) -> str:
    """The engine a TIN uses: ``engine`` checked ("kernel": gistools' compiled Delaunay, "triangle": Shewchuk's
    Triangle, "qhull": scipy's), or ``DEFAULT_ENGINE`` when None."""
    if engine is None:
        return DEFAULT_ENGINE
    if engine not in ENGINES:
        raise ValueError(f"TIN engine {engine!r} is not one of {', '.join(ENGINES)}")
    if engine == "kernel" and not kernel.loaded():
        raise RuntimeError("the compiled TIN kernel is not built (reinstall gistools with a C compiler)")
    if engine == "triangle" and _triangle is None:
        raise RuntimeError("the triangle package is not installed (pip install triangle), use engine='qhull'")
    return engine


_BATCH = 1_000_000  # triangles per evaluation batch (bounds temporary memory)


def merge_repeats(x: np.ndarray, y: np.ndarray, z: np.ndarray, tris: np.ndarray, how: str = "mean") -> np.ndarray:
    """z with each repeated (x, y) given the mean z (``how="min"``: the lowest) of its repeats, on the copy the TIN
    uses.

    A TIN cannot hold two heights at one position (overlapping flight lines give such
    repeats). Triangle and Qhull keep the first of a repeated position and leave the others out
    of every triangle, so the unreferenced vertices are exactly the repeats.
    """
    used = np.zeros(len(x), bool)
    used[tris.ravel()] = True
    if used.all():
        return z
    cand = np.nonzero(np.isin(x, x[~used]))[0]
    order = cand[np.lexsort((y[cand], x[cand]))]
    xs, ys = x[order], y[order]
    new = np.ones(len(order), bool)
    new[1:] = (xs[1:] != xs[:-1]) | (ys[1:] != ys[:-1])
    group = np.cumsum(new) - 1
    if how == "min":
        merged = np.full(group[-1] + 1, np.inf)
        np.minimum.at(merged, group, z[order])
    else:
        merged = np.bincount(group, weights=z[order]) / np.bincount(group)
    z = z.copy()
    z[order] = merged[group]
    return z


def delaunay_triangles(x: np.ndarray, y: np.ndarray, *, engine: str | None = None) -> np.ndarray:
    """Delaunay triangles (m, 3) int32 vertex indices of distinct 2-D points.

    Coordinates are centred before triangulation to keep precision on large
    projected coordinates. Fewer than 3 points, or collinear points, give no triangles.
    """
    if len(x) < 3:
        return np.empty((0, 3), np.int32)
    engine = tin_engine(engine)
    if engine == "kernel":
        return _kernel_triangles(np.asarray(x, np.float64), np.asarray(y, np.float64))
    pts = np.column_stack([x - x.mean(), y - y.mean()])
    if engine == "qhull":
        return _qhull_triangles(pts)
    try:
        result = _triangle.triangulate({"vertices": pts}, "QNBP")  # quiet; return triangles only
    except Exception:  # Triangle rejects degenerate (e.g. collinear) input
        return np.empty((0, 3), np.int32)
    return result.get("triangles", np.empty((0, 3), np.int32)).astype(np.int32, copy=False)


def _qhull_triangles(pts: np.ndarray) -> np.ndarray:
    """Delaunay triangles by scipy's Qhull ("Qbb Qc Qz Q12", its defaults for 2-D: repeats are left out as
    coplanar points); none for degenerate input."""
    from scipy.spatial import Delaunay, QhullError

    try:
        return Delaunay(pts).simplices.astype(np.int32, copy=False)
    except (QhullError, ValueError):
        return np.empty((0, 3), np.int32)


def _lattice_step(x: np.ndarray, y: np.ndarray, x0: float, y0: float, extent: float) -> float | None:
    """The largest decimal step (1 ... 1e-4 CRS units) on which a sample of the points lies, or None.

    LAS coordinates are integers times the header scale (0.01 ft, 0.001 m): on that lattice the
    kernel's integer coordinates are the file's own, so the triangulation is exact for them.
    """
    pick = np.linspace(0, len(x) - 1, min(len(x), 2000)).astype(np.int64)
    sx, sy = x[pick] - x0, y[pick] - y0
    for step in (1.0, 0.1, 0.01, 0.001, 0.0001):
        if extent / step > _QUANTUM_STEPS:
            return None
        rx, ry = sx / step, sy / step
        if np.abs(rx - np.rint(rx)).max() < 1e-3 and np.abs(ry - np.rint(ry)).max() < 1e-3:
            return step
    return None


def _to_integers(v: np.ndarray, v0: float, scale: float) -> tuple[np.ndarray, float]:
    """(rint((v - v0) * scale) as int64, the largest distance of (v - v0) * scale to an integer)."""
    out = np.empty(len(v), np.int64)
    worst = kernel.function("gt_quantise")(len(v), np.ascontiguousarray(v, np.float64), v0, scale, out)
    return out, worst


def _integer_coordinates(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The kernel's integer coordinates of the points (None when they are all at one position).

    Points on a decimal lattice (LAS files: integers times the header scale) keep their exact
    positions. Other coordinates are quantised to the power of two at or above extent / 2^30 (4e-6 ft
    on a 3000 ft tile), on absolute positions: points closer than that count as one (repeats), and ties
    between (nearly) cocircular points are broken on the quantised positions.
    """
    if len(x) >= 2**31 // 6:
        raise MemoryError(f"{len(x)} points are too many for one TIN; split the area")
    x0, y0 = float(x.min()), float(y.min())
    extent = max(float(x.max()) - x0, float(y.max()) - y0)
    if not np.isfinite(extent) or extent == 0:
        return None
    step = _lattice_step(x, y, x0, y0, extent)
    if step is not None:
        ix, ex = _to_integers(x, x0, 1.0 / step)
        iy, ey = _to_integers(y, y0, 1.0 / step)
        if max(ex, ey) < 1e-3:
            return ix, iy
    # a power-of-two quantum from the extent's order of magnitude, on absolute coordinates: the same point
    # gets the same integers in every point set of a similar extent (a tile with a wide or a thin halo)
    scale = 2.0 ** -(int(np.ceil(np.log2(extent))) - int(np.log2(_QUANTUM_STEPS)))
    return _to_integers(x, 0.0, scale)[0], _to_integers(y, 0.0, scale)[0]


def _kernel_triangles(x: np.ndarray, y: np.ndarray, count_repeats: bool = False):
    """Delaunay triangles from the compiled kernel (see _integer_coordinates); repeats are in none. With
    ``count_repeats``: (triangles, how many points repeat another's position)."""
    coords = _integer_coordinates(x, y)
    if coords is None:
        none = np.empty((0, 3), np.int32)
        return (none, 0) if count_repeats else none
    tris = np.empty(6 * len(x), np.int32)
    repeats = np.zeros(1, np.int64)
    m = kernel.function("gt_delaunay")(len(x), coords[0], coords[1], tris, repeats)
    if m < 0:
        raise MemoryError(f"not enough memory to triangulate {len(x)} points")
    tris = tris[: 3 * m].reshape(-1, 3)
    return (tris, int(repeats[0])) if count_repeats else tris


def tin_at_points(x, y, z, qx, qy, *, vertex=None, engine: str | None = None) -> np.ndarray:
    """Linear TIN interpolation of the points (x, y, z) at the points (qx, qy); NaN outside the TIN. Repeated
    (x, y) take their lowest z (a surface under the points, as a ground TIN must be). ``vertex``: per query, the
    index of the TIN point at its position, or -1: such a query takes that vertex's z without a search.

    With the compiled kernel: its Delaunay triangles and a bucket search (about 0.6 µs a query on a 2-core VM);
    otherwise scipy's Qhull and ``find_simplex`` (20 to 50 times slower on millions of points)."""
    x, y, z, qx, qy = (np.ascontiguousarray(a, np.float64) for a in (x, y, z, qx, qy))
    out = np.full(len(qx), np.nan)
    if len(x) < 3 or len(qx) == 0:
        return out
    x0, y0 = float(x.min()), float(y.min())  # local coordinates keep the digits of state-plane values
    if tin_engine(engine) == "kernel":
        tris, repeats = _kernel_triangles(x, y, count_repeats=True)
        if repeats:
            z = merge_repeats(x, y, z, tris, how="min")
        tris = np.ascontiguousarray(tris, np.int32)
        ask = np.ones(len(qx), bool) if vertex is None else np.asarray(vertex) < 0
        if not ask.all():
            out[~ask] = z[np.asarray(vertex)[~ask]]
        part = np.full(int(np.count_nonzero(ask)), np.nan)
        if kernel.function("gt_tin_at")(len(tris), tris, x - x0, y - y0, z, len(x), len(part), np.ascontiguousarray(qx[ask] - x0),
                             np.ascontiguousarray(qy[ask] - y0), part) < 0:
            raise MemoryError(f"not enough memory to locate {len(qx)} points in a TIN of {len(x)}")
        out[ask] = part
        return out
    from scipy.spatial import Delaunay, QhullError

    order = np.lexsort((z, y, x))  # Qhull keeps the first of repeated points: the lowest
    x, y, z = x[order], y[order], z[order]
    try:
        tri = Delaunay(np.column_stack([x - x0, y - y0]))
    except (QhullError, ValueError):  # every point on a line
        return out
    q = np.column_stack([qx - x0, qy - y0])
    simplex = tri.find_simplex(q)
    inside = simplex >= 0
    t = tri.transform[simplex[inside]]
    b = np.einsum("ijk,ik->ij", t[:, :2], q[inside] - t[:, 2])
    w = np.column_stack([b, 1 - b.sum(axis=1)])
    out[inside] = np.einsum("ij,ij->i", w, z[tri.simplices[simplex[inside]]])
    return out


def tin_to_grid_exact(x, y, z, grid: Grid, box, *, max_edge: float | None = None,
                      engine: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(tin_to_grid(...), exact): ``exact`` (bool, the grid's shape) marks the cells whose value (or nodata) any
    TIN of a point set that adds only points outside ``box`` would give too (their triangle's circumcircle
    lies inside ``box``).

    Give all the points inside ``box`` (west, south, east, north, CRS units). Only the compiled kernel
    finds exact cells: with the "triangle" or "qhull" engine none is marked.
    """
    out = np.full(grid.shape, np.nan)
    exact = np.zeros(grid.shape, np.uint8)
    if tin_engine(engine) != "kernel":
        return tin_to_grid(x, y, z, grid, out, max_edge=max_edge, engine=engine), exact.view(bool)
    tin_to_grid(x, y, z, grid, out, max_edge=max_edge, exact=exact, exact_box=box, engine="kernel")
    return out, exact.view(bool)


def tin_to_grid(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: Grid, out: np.ndarray | None = None, *, max_edge: float | None = None,
    exact: np.ndarray | None = None, exact_box=None, engine: str | None = None,
) -> np.ndarray:
    """Linear TIN interpolation of (x, y, z) at the cell centres of ``grid``.

    Cells outside the convex hull of the points are NaN, and so are cells in triangles with an edge longer than
    ``max_edge`` (the hull's long bridges over concave data edges and big gaps). Repeated (x, y) are merged (mean z).

    Parameters
    ----------
    x, y : numpy.ndarray
        Point coordinates, in CRS units.
    z : numpy.ndarray
        Point values, in any unit (returned unchanged).
    grid : Grid
        The grid (see `gistools.snapped_grid`).
    out : numpy.ndarray, optional
        C-contiguous float64 array of ``grid.shape``: only the cells the TIN covers are written into it. None: a new
        array of NaN.
    max_edge : float, optional
        Longest triangle edge kept, in CRS units. None: every triangle.
    exact : numpy.ndarray, optional
        uint8 array of ``grid.shape`` (kernel engine only): set to 1 at the cells whose value any larger point set
        adding points only outside ``exact_box`` would give too.
    exact_box : tuple of float, optional
        (west, south, east, north) in CRS units, with ``exact``.
    engine : str, optional
        ``"kernel"`` (gistools' compiled Delaunay), ``"triangle"`` (Shewchuk's Triangle) or ``"qhull"`` (scipy's);
        None: the kernel when built, else Triangle when installed, else Qhull.

    Returns
    -------
    numpy.ndarray
        float64 array of ``grid.shape`` (``out`` when given).

    Raises
    ------
    ValueError
        ``engine`` is unknown, or ``out`` is not a C-contiguous float64 array of the grid's shape.
    RuntimeError
        The engine asked for is not installed.

    Examples
    --------
    >>> from gistools import snapped_grid
    >>> g = snapped_grid((0.0, 0.0, 9.0, 9.0), 5.0)
    >>> tin_to_grid([0.0, 10.0, 0.0, 10.0], [0.0, 0.0, 10.0, 10.0], [0.0, 0.0, 10.0, 10.0], g).tolist()
    [[7.5, 7.5], [2.5, 2.5]]
    """
    if out is None:
        out = np.full(grid.shape, np.nan)
    x, y, z = (np.ascontiguousarray(a, np.float64) for a in (x, y, z))
    cs = grid.cell_size
    # Work in cell units relative to the grid's west/north edge: u = col + 0.5 at a centre, v = row + 0.5.
    u = (x / cs) - grid.col0
    v = grid.row_top - (y / cs)
    max_edge_cells = None if max_edge is None else max_edge / cs
    engine = tin_engine(engine)
    if engine == "kernel":
        if len(x) < 3 or (coords := _integer_coordinates(x, y)) is None:
            return out
        if out.dtype != np.float64 or not out.flags.c_contiguous or out.shape != grid.shape:
            raise ValueError("out must be a C-contiguous float64 array of the grid's shape")
        repeats = np.zeros(1, np.int64)
        box_cells = None
        if exact is not None:
            w, s, e, n = exact_box
            box_cells = np.array([w / cs - grid.col0, grid.row_top - n / cs, e / cs - grid.col0, grid.row_top - s / cs])
        m = kernel.function("gt_tin_grid")(len(x), coords[0], coords[1], u, v, z, grid.width, grid.height,
                                           -1.0 if max_edge_cells is None else max_edge_cells**2, out, repeats,
                                           box_cells, exact)
        if m < 0:
            raise MemoryError(f"not enough memory to triangulate {len(x)} points")
        return out
    tris = delaunay_triangles(x, y, engine=engine)
    if len(tris) == 0:
        return out
    z = merge_repeats(x, y, z, tris)
    flat_out = out.reshape(-1)
    # Per vertex, the first and last cell centre at or beyond it (int32): a triangle's range of
    # centres is the min / max of its vertices', so most triangles, which hold no centre when
    # points are dense, are dropped with integer work only.
    big = np.iinfo(np.int32).max // 2
    ulo, uhi = (np.clip(f(u - 0.5), -big, big).astype(np.int32) for f in (np.ceil, np.floor))
    vlo, vhi = (np.clip(f(v - 0.5), -big, big).astype(np.int32) for f in (np.ceil, np.floor))
    for start in range(0, len(tris), _BATCH):
        t = tris[start : start + _BATCH]
        i0, i1, i2 = (np.ascontiguousarray(t[:, k]) for k in range(3))
        c_lo = _min3(ulo[i0], ulo[i1], ulo[i2])
        c_hi = _max3(uhi[i0], uhi[i1], uhi[i2])
        hit = (c_hi >= np.maximum(c_lo, 0)) & (np.minimum(c_hi, grid.width - 1) >= c_lo)
        r_lo = _min3(vlo[i0], vlo[i1], vlo[i2])
        r_hi = _max3(vhi[i0], vhi[i1], vhi[i2])
        hit &= (r_hi >= np.maximum(r_lo, 0)) & (np.minimum(r_hi, grid.height - 1) >= r_lo)
        if not hit.any():
            continue
        i0, i1, i2 = i0[hit], i1[hit], i2[hit]
        _eval_batch(u[i0], u[i1], u[i2], v[i0], v[i1], v[i2], z[i0], z[i1], z[i2],
                    grid.width, grid.height, flat_out, max_edge_cells)
    return out


def _min3(a, b, c):
    return np.minimum(np.minimum(a, b), c)


def _max3(a, b, c):
    return np.maximum(np.maximum(a, b), c)


def _eval_batch(ax, bx, cx, ay, by, cy, za, zb, zc, width, height, flat_out, max_edge=None):
    """Evaluate triangles (vertices a, b, c in cell units) at the cell centres they cover."""
    if max_edge is not None:
        e2 = _max3((ax - bx) ** 2 + (ay - by) ** 2, (bx - cx) ** 2 + (by - cy) ** 2, (cx - ax) ** 2 + (cy - ay) ** 2)
        keep = e2 <= max_edge * max_edge
        if not keep.all():
            ax, bx, cx, ay, by, cy, za, zb, zc = (a[keep] for a in (ax, bx, cx, ay, by, cy, za, zb, zc))
    c_lo = np.maximum(np.ceil(_min3(ax, bx, cx) - 0.5), 0).astype(np.int64)
    c_hi = np.minimum(np.floor(_max3(ax, bx, cx) - 0.5), width - 1).astype(np.int64)
    r_lo = np.maximum(np.ceil(_min3(ay, by, cy) - 0.5), 0).astype(np.int64)
    r_hi = np.minimum(np.floor(_max3(ay, by, cy) - 0.5), height - 1).astype(np.int64)
    nc = c_hi - c_lo + 1
    nr = r_hi - r_lo + 1
    det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    keep = (nc > 0) & (nr > 0) & (det != 0)
    if not keep.any():
        return
    idx = np.nonzero(keep)[0]
    nc, nr = nc[idx], nr[idx]
    k = nc * nr
    total = int(k.sum())
    # one candidate per (triangle, covered cell centre)
    tri = np.repeat(idx, k)
    j = np.arange(total) - np.repeat(np.cumsum(k) - k, k)
    ncr = np.repeat(nc, k)
    col = c_lo[tri] + j % ncr
    row = r_lo[tri] + j // ncr
    inv = 1.0 / det[tri]
    px = col + 0.5 - cx[tri]
    py = row + 0.5 - cy[tri]
    w1 = ((by - cy)[tri] * px + (cx - bx)[tri] * py) * inv
    w2 = ((cy - ay)[tri] * px + (ax - cx)[tri] * py) * inv
    w3 = 1.0 - w1 - w2
    eps = -1e-9
    inside = (w1 >= eps) & (w2 >= eps) & (w3 >= eps)
    zi = w1 * za[tri] + w2 * zb[tri] + w3 * zc[tri]
    flat_out[(row * width + col)[inside]] = zi[inside]
