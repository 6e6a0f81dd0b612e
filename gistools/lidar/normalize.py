"""Heights above ground of points, from a TIN of the ground points (PDAL ``filters.hag_delaunay``, lidR
``normalize_height(tin())``), and ASPRS vegetation classes from those heights.

Pure functions over numpy arrays; heights stay in the points' vertical unit.
"""

from __future__ import annotations

import numpy as np

from .tin import tin_at_points, tin_engine

__all__ = ["ground_height_at", "height_above_ground", "vegetation_classes", "LOW_VEGETATION", "MEDIUM_VEGETATION",
           "HIGH_VEGETATION", "ROAD_SURFACE", "WATER", "UNCLASSIFIED"]

UNCLASSIFIED = (0, 1)
LOW_VEGETATION, MEDIUM_VEGETATION, HIGH_VEGETATION = 3, 4, 5
ROAD_SURFACE, WATER = 11, 9


def ground_height_at(gx, gy, gz, x, y, *, vertex=None, k: int = 10, power: float = 2.0,
                     engine: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(ground elevation at each (x, y), True where it came from the TIN).

    Inside the ground points' convex hull: linear interpolation on their Delaunay triangulation (repeated positions
    at their lowest z). Outside it (the edge of a block, a lake wider than the buffer): inverse-distance weighting
    of the ``k`` nearest ground points (lidR ``tin()`` does the same with its ``knnidw``, k = 10, p = 2). NaN when
    there is no ground point. ``vertex``: for each (x, y), the index of the ground point at that position, or -1
    (the TIN's value at its own vertex is that vertex's z, so those points are not searched for). ``engine``: the
    TIN's (lidar.tin)."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    gx, gy, gz = (np.asarray(a, np.float64) for a in (gx, gy, gz))
    ground = np.full(len(x), np.nan)
    inside = np.zeros(len(x), bool)
    if len(gx) == 0 or len(x) == 0:
        return ground, inside
    # with the kernel, a query at a TIN vertex takes the vertex's z (its repeats' lowest) without a search
    ground = tin_at_points(gx, gy, gz, x, y, vertex=vertex if tin_engine(engine) == "kernel" else None, engine=engine)
    inside = np.isfinite(ground)
    rest = ~inside
    if rest.any():
        kk = min(k, len(gx))
        from scipy.spatial import cKDTree  # here: scipy.spatial costs 0.05 s to import, and few tiles need it

        dist, idx = cKDTree(np.column_stack([gx, gy])).query(np.column_stack([x[rest], y[rest]]), k=kk)
        dist, idx = dist.reshape(-1, kk), idx.reshape(-1, kk)
        with np.errstate(divide="ignore"):
            wts = 1.0 / np.maximum(dist, 1e-12) ** power
        ground[rest] = (wts * gz[idx]).sum(axis=1) / wts.sum(axis=1)
    return ground, inside


def height_above_ground(x, y, z, gx, gy, gz, **kw) -> tuple[np.ndarray, np.ndarray]:
    """(z minus the ground elevation under each point, True where the ground came from the TIN); see
    ``ground_height_at``."""
    ground, inside = ground_height_at(gx, gy, gz, x, y, **kw)
    return np.asarray(z, np.float64) - ground, inside


def vegetation_classes(classification, hag, thresholds, *, floor: float, road=None, water=None) -> np.ndarray:
    """ASPRS classes with vegetation set from heights above ground (``hag``, the thresholds' unit).

    Points of classes 0 / 1 above ``floor``: low vegetation (3) up to T1, medium (4) up to T3, high (5) above
    (``thresholds`` = the height bands' T1, T2, T3: B1 is low, B2 and B3 the shrubs are medium, above B3 high).
    ``road`` / ``water``: boolean masks of the points inside the road / water polygons; there, points of classes
    0, 1, 2 at most ``floor`` above the ground become road surface (11) / water (9). Other classes are kept."""
    t1, _t2, t3 = thresholds
    cls = np.asarray(classification, np.uint8).copy()
    h = np.asarray(hag, np.float64)
    open_ = np.isin(cls, UNCLASSIFIED) & np.isfinite(h)
    cls[open_ & (h > floor) & (h <= t1)] = LOW_VEGETATION
    cls[open_ & (h > t1) & (h <= t3)] = MEDIUM_VEGETATION
    cls[open_ & (h > t3)] = HIGH_VEGETATION
    surface = np.isin(classification, (0, 1, 2)) & np.isfinite(h) & (h <= floor)
    if road is not None:
        cls[surface & road] = ROAD_SURFACE
    if water is not None:
        cls[surface & water] = WATER
    return cls
