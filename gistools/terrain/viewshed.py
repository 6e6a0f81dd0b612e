"""Lines of sight over a surface's cells, as GDAL's gdal_viewshed (Wang, Robinson and White 2000, its default
"edge" mode): each cell's horizon height is interpolated from the two cells next to it on the observer's side, in
one sweep outward from the observer, a whole ring of a wedge at once; arrays in, arrays out (``gistools viewshed``
reads the surface and writes the rasters: gistools.products.viewshed)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..progress import ProgressCallback, report

__all__ = ["viewshed_array"]

_LOW = -1e12  # a nodata cell hides nothing (gdal_viewshed reads it as its nodata value, far below any surface)


def _line(z_near, eye, k):
    """gdal_viewshed's CalcHeightLine: the height at distance k on the line from the eye through z_near at k - 1."""
    return (z_near - eye) / (k - 1) + z_near


def _sweep(v, h, obs_row, eye, target, *, strict: bool, visible):
    """Sweep one wedge of view ``v`` (the main axis 1 outward from the observer at (obs_row, 0), the cross axis 0).

    ``v``: horizon heights, updated in place (a cell's own height, raised to the horizon it lies under); ``h``: the
    surface heights (curvature applied); ``visible``: the output, set in place. ``strict``: the wedge holds the
    cells with |cross| < main (north, south); else |cross| <= main (east, west, with the diagonals).
    """
    rows, cols = v.shape
    for k in range(1, cols):
        reach = k - 1 if strict else k
        lo, hi = max(obs_row - reach, 0), min(obs_row + reach, rows - 1)
        if lo > hi:
            continue
        idx = np.arange(lo, hi + 1)
        m = idx - obs_row
        a = np.abs(m)
        hk = h[lo:hi + 1, k]
        if k == 1:
            z = np.full(idx.shape, v[obs_row, 0])  # gdal_viewshed: the observer cell's own height
            if not strict:  # east and west: the two cells beside the observer are seen, their height kept
                beside = m == 0
                visible[lo:hi + 1, k] = np.where(beside, True, hk + target >= z)
                v[lo:hi + 1, k] = np.where(beside, hk, np.maximum(hk, z))
                continue
        else:
            s = np.sign(m)
            za = v[idx - s, k - 1]  # the cell one step nearer on the diagonal side
            zb = v[np.clip(idx, 0, rows - 1), k - 1]  # the cell one step nearer on the main axis
            with np.errstate(invalid="ignore"):
                z = ((za - eye) * a + (zb - eye) * (k - a)) / (k - 1) + eye
            z = np.where(a == 0, _line(zb, eye, k), z)
            z = np.where(a == k, _line(za, eye, k), z)
        visible[lo:hi + 1, k] = hk + target >= z
        v[lo:hi + 1, k] = np.maximum(hk, z)


def viewshed_array(z: np.ndarray, row: int, col: int, *, observer_height: float, target_height: float = 0.0,
                   curvature: float = 0.0, cell=(1.0, 1.0), max_distance: float = 0.0,
                   progress: ProgressCallback | None = None) -> np.ndarray:
    """Visibility (bool) of every cell of surface ``z`` (NaN = nodata, hides nothing) from an eye ``observer_height``
    above cell (``row``, ``col``), as gdal_viewshed's default mode.

    ``target_height``: a cell is seen when a point this high above it is. ``curvature``: the lowering per squared
    horizontal distance (coefficient / the ellipsoid's diameter, in z's unit per squared horizontal unit); ``cell``:
    (width, height) of a cell in horizontal units, for the distances; ``max_distance`` (> 0): cells farther from the
    observer's cell are not seen (gdal_viewshed -md); ``progress``: told after each of the four wedges (and may
    cancel). Heights in z's unit.
    """
    z = np.asarray(z, dtype=np.float64)
    rows, cols = z.shape
    if not (0 <= row < rows and 0 <= col < cols):
        raise InputError("the observer is outside the surface raster", hint="Give a position inside the raster")
    if not np.isfinite(z[row, col]):
        raise InputError("the observer stands on a cell without a height (nodata)", hint="Move the observer onto data")
    h = np.where(np.isfinite(z), z, _LOW)
    r2 = None
    if curvature or max_distance:
        dy = (np.arange(rows) - row)[:, None] * cell[1]
        dx = (np.arange(cols) - col)[None, :] * cell[0]
        r2 = dx * dx + dy * dy
    if curvature:
        h = h - curvature * r2
        h[row, col] = z[row, col]
    eye = z[row, col] + observer_height
    v = h.copy()
    visible = np.zeros(z.shape, bool)
    visible[row, col] = True
    # east and west (with the diagonals) first: north and south read the diagonal cells
    views = [(v[:, col:], h[:, col:], visible[:, col:], row, False),
             (v[:, col::-1], h[:, col::-1], visible[:, col::-1], row, False),
             (v[row::-1, :].T, h[row::-1, :].T, visible[row::-1, :].T, col, True),
             (v[row:, :].T, h[row:, :].T, visible[row:, :].T, col, True)]
    for i, (vv, hh, vis, obs, strict) in enumerate(views):
        _sweep(vv, hh, obs, eye, target_height, strict=strict, visible=vis)
        report(progress, (i + 1) / len(views), "viewshed: sweeping")
    if max_distance:
        visible &= r2 <= max_distance * max_distance
    return visible
