"""The generated buildings F1-F4 of the structure spec (section 1), with their analytic answers.

Chain levels: perimeter points every 10 m from a vertex; sown levels: every 10 m lattice point the
footprint covers (boundary included). Variants: exact, ``jitter`` (x, y noise N(0, 0.3 m)),
``shuffle`` (rows and ids permuted), ``corrupt`` (5 exact duplicates under new ids, 3 id collisions,
4 points 0.005 m from another, 5 far outliers). Coordinates in metres, a local frame.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import shapely
import shapely.affinity

__all__ = ["building", "VOLUMES", "EULER", "BUILDINGS"]

S0 = shapely.box(0, 0, 200, 200)
P = shapely.Polygon([(0, 0), (200, 0), (200, 100), (100, 100), (100, 200), (0, 200)])
B = shapely.Polygon([(0, 20), (200, 20), (200, 100), (100, 100), (100, 170), (0, 170)])
T1 = shapely.box(20, 20, 60, 60)
T2 = shapely.box(140, 20, 180, 60)
F1 = shapely.box(0, 0, 60, 40)
F3 = shapely.Polygon(S0.exterior.coords, [shapely.box(60, 60, 140, 140).exterior.coords[::-1]])
VOLUMES = {"F1": 72_000.0, "F2": 900_000.0, "F3": 1_008_000.0, "F4": 3_352_000.0}
EULER = {"F1": 2, "F2": 2, "F3": 0, "F4": 0}
BUILDINGS = tuple(VOLUMES)


def perimeter_points(ring_coords, step: float = 10.0) -> np.ndarray:
    """Points every ``step`` along a closed ring, starting at its first vertex."""
    ring = shapely.LineString(ring_coords)
    n = int(round(ring.length / step))
    return shapely.get_coordinates(shapely.line_interpolate_point(ring, np.arange(n) * step))


def lattice_points(polygon, step: float = 10.0) -> np.ndarray:
    """Every ``step`` lattice point the polygon covers (its boundary included)."""
    x0, y0, x1, y1 = polygon.bounds
    xs, ys = np.meshgrid(np.arange(np.floor(x0 / step) * step, x1 + 1e-9, step),
                         np.arange(np.floor(y0 / step) * step, y1 + 1e-9, step))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    keep = shapely.intersects_xy(polygon.buffer(1e-9), pts[:, 0], pts[:, 1])
    return pts[keep]


def _chain(polygon, step: float = 10.0) -> np.ndarray:
    parts = [perimeter_points(polygon.exterior.coords, step)]
    parts += [perimeter_points(r.coords, step) for r in polygon.interiors]
    return np.vstack(parts)


def _levels(name: str, step: float = 10.0):
    """[(z, xy points)] of a building; ``step`` is the point spacing along outlines and on plates."""
    out = []

    def lattice(poly):
        return lattice_points(poly, step)

    def chain(poly):
        return _chain(poly, step)

    if name in ("F1", "F2", "F3"):
        foot = {"F1": F1, "F2": P, "F3": F3}[name]
        for z in range(0, 31, 5):
            out.append((float(z), lattice(foot) if z in (0, 30) else chain(foot)))
        return out
    for z in (-20, -15, -10, -5):
        out.append((float(z), chain(S0)))
    out.append((0.0, lattice(S0)))
    for z in range(5, 41, 5):
        out.append((float(z), chain(P)))
    out.append((45.0, lattice(P)))
    for z in range(50, 201, 5):
        shift = 0.5 * (z - 50) / 5
        out.append((float(z), np.vstack([chain(shapely.affinity.translate(t, 0, shift)) for t in (T1, T2)])))
    out.append((205.0, lattice(B)))
    for z in range(210, 231, 5):
        out.append((float(z), chain(B)))
    out.append((235.0, lattice(B)))
    return out


def building(name: str = "F4", *, jitter: float = 0.0, shuffle: bool = False, corrupt: bool = False, seed: int = 1,
             step: float = 10.0):
    """(points id, x, y, z; log of the planted corruptions: id, change) of building F1-F4."""
    if name not in BUILDINGS:
        raise ValueError(f"building {name!r} is not one of {', '.join(BUILDINGS)}")
    rng = np.random.default_rng(seed)
    rows = [np.column_stack([xy, np.full(len(xy), z)]) for z, xy in _levels(name, step)]
    xyz = np.vstack(rows)
    if jitter:
        xyz[:, :2] += rng.normal(0, jitter, (len(xyz), 2))
    ids = np.arange(1, len(xyz) + 1)
    pts = pd.DataFrame({"id": ids, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})
    planted = []
    if corrupt:
        n = len(pts)
        dup = pts.iloc[rng.choice(n, 5, replace=False)].copy()
        dup["id"] = n + 1 + np.arange(5)
        planted += [(int(i), "duplicate") for i in dup["id"]]
        coll = pts.iloc[rng.choice(n, 3, replace=False)].copy()
        coll["id"] = pts["id"].iloc[rng.choice(n, 3, replace=False)].to_numpy()
        coll["x"] += 1.0  # another position under an existing id
        coll["y"] += 1.0
        planted += [(int(i), "renumbered") for i in coll["id"]]
        near = pts.iloc[rng.choice(n, 4, replace=False)].copy()
        near["id"] = n + 100 + np.arange(4)
        near["x"] += 0.005
        planted += [(int(i), "near_duplicate") for i in near["id"]]
        far = pd.DataFrame({"id": n + 200 + np.arange(5), "x": rng.uniform(1000, 2000, 5), "y": rng.uniform(1000, 2000, 5),
                            "z": pts["z"].iloc[rng.choice(n, 5)].to_numpy()})
        planted += [(int(i), "outlier") for i in far["id"]]
        pts = pd.concat([pts, dup, coll, near, far], ignore_index=True)
    if shuffle:
        order = rng.permutation(len(pts))
        pts = pts.iloc[order].reset_index(drop=True)
        new_ids = rng.permutation(len(pts)) + 1
        mapping = dict(zip(pts["id"], new_ids)) if not corrupt else None
        if mapping is not None:
            pts["id"] = pts["id"].map(mapping)
    return pts, pd.DataFrame(planted, columns=["id", "change"])
