"""DSM cells without a first return (pinholes), filled from their neighbourhood.

``tin``: a TIN of each cell's highest first return, at its own position, and of the returns at the corners of
their convex hull (``hull_points``), evaluated at the empty cells' centres (lidR ``p2r(na.fill = tin())``): every
empty cell inside the hull of the returns is filled, pinholes, roofs without returns and water alike, with a
weighted mean of three returns, so never above the highest of them. ``subcircle``: lidR's
``p2r(subcircle = r)``: every first return also counts at 8 points on a circle of radius r around it, so a return
reaches the cells within r (the crowns widen by r as in lidR). ``nearest``: the empty cell takes the height of the
nearest cell's highest return (by its position) within ``max_distance``: a Voronoi fill, which keeps the share of
vegetated cells of a patch where ``tin`` would raise it (between a shrub return and a ground return a TIN gives
heights above the ground floor). Pure functions over numpy arrays and grids.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid, cell_index
from .accumulate import max_into
from ..parameters import choices

__all__ = ["DSM_FILLS", "SUBCIRCLE", "max_with_position", "subcircle_into", "hull_points", "fill_from_tin",
           "fill_from_nearest"]

DSM_FILLS = choices("dsm_fill")  # declared in gistools.parameters.rasters
SUBCIRCLE = np.array([(np.cos(a), np.sin(a)) for a in np.arange(8) * np.pi / 4])  # lidR's 8 points of the circle


def max_with_position(dsm, px, py, cell, z, x, y) -> None:
    """In place: the per-cell maximum of z into the flat ``dsm`` (start from -inf) and the (x, y) of the point that
    gives it into ``px``, ``py`` (the first such point of a chunk, an earlier chunk's on ties)."""
    n = len(dsm)
    cm = np.full(n, -np.inf)
    np.maximum.at(cm, cell, z)
    top = np.flatnonzero(z == cm[cell])
    tc = cell[top]
    first = np.ones(len(top), bool)
    order = np.argsort(tc, kind="stable")
    tc_sorted = tc[order]
    first[order[1:]] = tc_sorted[1:] != tc_sorted[:-1]
    take = first & (cm[tc] > dsm[tc])
    px[tc[take]] = x[top[take]]
    py[tc[take]] = y[top[take]]
    np.maximum(dsm, cm, out=dsm)


def subcircle_into(dsm, grid: Grid, x, y, z, radius: float) -> None:
    """In place: each point's z at its position and at the 8 points of a circle of ``radius`` around it, as the
    per-cell maximum into the flat ``dsm`` of ``grid`` (points outside the grid left out)."""
    for dx, dy in ((0.0, 0.0), *(radius * SUBCIRCLE)):
        c = cell_index(grid, x + dx, y + dy)
        inside = c >= 0
        max_into(dsm, c[inside], z[inside])


def hull_points(x, y) -> np.ndarray:
    """Indices of the points (x, y) at the corners of their convex hull (all of them where Qhull finds no polygon:
    fewer than 3 points, or on one line). The points strictly inside the polygon of the extremes in 8 directions
    are left out first (Akl and Toussaint 1978), so a chunk of a million points costs a few vector passes and a
    Qhull of the few near its outline."""
    from scipy.spatial import ConvexHull, QhullError

    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if len(x) < 3:
        return np.arange(len(x))
    u, v = x - x.min(), y - y.min()  # lengths from a corner: the cross products below keep their digits
    corners = np.unique([f(a) for a in (u, v, u + v, u - v) for f in (np.argmin, np.argmax)])
    candidates = np.arange(len(x))
    if len(corners) >= 3:  # hull points themselves, so in convex order by their angle around their mean
        corners = corners[np.argsort(np.arctan2(v[corners] - v[corners].mean(), u[corners] - u[corners].mean()))]
        inside, side, part = np.ones(len(x), bool), np.empty(len(x)), np.empty(len(x))
        for a, b in zip(corners, np.roll(corners, -1)):  # left of every edge a -> b: du * v - dv * u > its value at a
            du, dv = u[b] - u[a], v[b] - v[a]
            np.multiply(v, du, out=side)
            side -= np.multiply(u, dv, out=part)
            inside &= side > du * v[a] - dv * u[a]
        candidates = np.flatnonzero(~inside)
    try:
        return candidates[ConvexHull(np.column_stack([u[candidates], v[candidates]])).vertices]
    except (QhullError, ValueError):
        return candidates


def fill_from_tin(dsm: np.ndarray, grid: Grid, px, py, pz, *, max_edge: float | None = None,
                  engine: str | None = None) -> int:
    """In place: the empty (NaN) cells of ``dsm`` on ``grid`` from the TIN of the points (px, py, pz) (the highest
    returns of the cells around, their positions, and the corners of the returns' hull), triangles longer than
    ``max_edge`` dropped (None: every cell inside the points' convex hull is filled); returns how many cells were
    filled."""
    from .tin import tin_to_grid

    empty = np.isnan(dsm)
    ok = np.isfinite(pz)
    if not empty.any() or np.count_nonzero(ok) < 3:
        return 0
    surface = tin_to_grid(px[ok], py[ok], pz[ok], grid, max_edge=max_edge, engine=engine)
    take = empty & np.isfinite(surface)
    dsm[take] = surface[take]
    return int(np.count_nonzero(take))


def fill_from_nearest(dsm: np.ndarray, grid: Grid, px, py, pz, *, max_distance: float) -> int:
    """In place: each empty (NaN) cell of ``dsm`` takes the height of the nearest of the points (px, py, pz) within
    ``max_distance`` of its centre; returns how many cells were filled."""
    from scipy.spatial import cKDTree

    from ..grid import cell_centres

    empty = np.isnan(dsm)
    ok = np.isfinite(pz)
    if not empty.any() or not ok.any():
        return 0
    xs, ys = cell_centres(grid)
    rows, cols = np.nonzero(empty)
    dist, idx = cKDTree(np.column_stack([px[ok], py[ok]])).query(np.column_stack([xs[cols], ys[rows]]),
                                                                distance_upper_bound=max_distance)
    hit = np.isfinite(dist)
    dsm[rows[hit], cols[hit]] = pz[ok][idx[hit]]
    return int(np.count_nonzero(hit))
