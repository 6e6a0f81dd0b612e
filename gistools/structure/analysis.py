"""Structure reconstruction, steps S0-S5 of the spec (reading: gistools.io.text.read_cloud): transform, check, voxel orders and parameters, levels,
clusters, chain / sown.

Parameters (metres): ``h`` the largest height step between consecutive levels, ``d`` the planimetric
distance that joins points into one cluster, ``t`` the planimetric tolerance of matching and of the
chain / sown split. The dissertation prints estimates 7.969 / 17.678 / 4.000 and adopts 8 / 15 / 4
without giving its rule; gistools estimates h and d by the spec's rule H2 (the voxel order whose size
first reaches the level gap / the in-level spacing) and takes t = 4 m unless given.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError

__all__ = ["transform_points", "check_points", "voxel_orders", "estimate_parameters", "split_levels", "cluster_level",
           "Cluster", "classify_cluster", "Parameters"]


def transform_points(xyz: np.ndarray, *, columns: str = "123", scales=(1.0, 1.0, 1.0),
                     rotations=(0.0, 0.0, 0.0)) -> np.ndarray:
    """x, y, z of input columns (S0): ``columns`` says which input column is x, y, z ("123" = as given, "213"
    swaps x and y); ``scales``: signed factors per axis; ``rotations``: degrees about x, y, z, applied after
    permuting and scaling."""
    order = [int(c) - 1 for c in str(columns)]
    if sorted(order) != [0, 1, 2]:
        raise InputError(f"column order {columns!r} is not a permutation of 123", hint="e.g. 123, or 213 to swap x and y")
    xyz = xyz[:, order] * np.asarray(scales, np.float64)
    if any(rotations):
        from scipy.spatial.transform import Rotation

        xyz = Rotation.from_euler("xyz", rotations, degrees=True).apply(xyz)
    return xyz


def level_spacing(xyz: np.ndarray, level: np.ndarray) -> float:
    """Median nearest-neighbour distance in plan between points of the same level (inf with none)."""
    nn = []
    for lev in np.unique(level):
        p = xyz[level == lev, :2]
        if len(p) > 1:
            dd, _ = cKDTree(p).query(p, 2)
            nn.append(dd[:, 1])
    return float(np.median(np.concatenate(nn))) if nn else np.inf


def check_points(points: pd.DataFrame, *, eps: float = 1e-6, near: float = 0.01, eps_z: float = 0.1,
                 isolated_distance: float | None = None):
    """(kept points, log) of S1: exact duplicates (same x, y, z) keep the lowest id; a reused id at another
    position is renumbered (max + 1, ...); points within ``near`` of another in plan on the same level
    are merged (the lowest id kept); a point with no other point (any level) within ``isolated_distance``
    (default 3 x the median in-level spacing) is flagged ``outlier`` and left out.
    """
    pts = points.sort_values("id", kind="stable").reset_index(drop=True)
    log = []
    key = np.round(pts[["x", "y", "z"]].to_numpy() / eps).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    dup = np.ones(len(pts), bool)
    dup[first] = False
    for i in np.flatnonzero(dup):
        log.append((int(pts.at[i, "id"]), None, "duplicate"))
    pts = pts[~dup].reset_index(drop=True)
    reused = pts["id"].duplicated(keep="first").to_numpy()
    next_id = int(pts["id"].max()) + 1
    for i in np.flatnonzero(reused):
        log.append((int(pts.at[i, "id"]), next_id, "renumbered"))
        pts.at[i, "id"] = next_id
        next_id += 1
    level = split_levels(pts["z"].to_numpy(), eps_z)
    xy = pts[["x", "y"]].to_numpy()
    drop = np.zeros(len(pts), bool)
    for lev in np.unique(level):
        idx = np.flatnonzero(level == lev)
        if len(idx) < 2:
            continue
        pairs = cKDTree(xy[idx]).query_pairs(near, output_type="ndarray")
        for a, b in pairs:
            i, j = idx[a], idx[b]
            if drop[i] or drop[j]:
                continue
            k = j if pts.at[j, "id"] > pts.at[i, "id"] else i
            drop[k] = True
            log.append((int(pts.at[k, "id"]), None, "near_duplicate"))
    pts, level = pts[~drop].reset_index(drop=True), level[~drop]
    xyz = pts[["x", "y", "z"]].to_numpy()
    if isolated_distance is None:  # 3 x the median in-level spacing
        isolated_distance = 3 * level_spacing(xyz, level)
    counts = np.asarray([len(nb) for nb in cKDTree(xyz).query_ball_point(xyz, isolated_distance)])
    flagged = counts <= 1  # nobody else within the distance, on any level
    for i in np.flatnonzero(flagged):
        log.append((int(pts.at[i, "id"]), None, "outlier"))
    return pts[~flagged].reset_index(drop=True), pd.DataFrame(log, columns=["id", "new_id", "change"])


def voxel_orders(xyz: np.ndarray, max_order: int = 12) -> tuple[dict, int, np.ndarray]:
    """({order: number of points first alone in their voxel at that order}, k_opt, order of each point) (S2).

    Order k divides the bounding box into 2^k x 2^k x 2^k boxes (anisotropic); a point's order is the
    smallest k at which it is alone in its voxel; k_opt the first order where every point is alone.
    """
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    size = np.where(hi > lo, hi - lo, 1.0)
    order_of = np.zeros(len(xyz), np.int64)
    done = np.zeros(len(xyz), bool)
    counts = {}
    k_opt = max_order
    for k in range(0, max_order + 1):
        n = 2 ** k
        idx = np.minimum(np.floor((xyz - lo) / (size / n)).astype(np.int64), n - 1)
        key = idx[:, 0] + n * idx[:, 1] + n * n * idx[:, 2]
        _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
        alone = (cnt[inv.ravel()] == 1) & ~done
        order_of[alone] = k
        done |= alone
        if k > 0 or alone.any():
            counts[k] = int(alone.sum())
        if done.all():
            k_opt = k
            break
    return counts, k_opt, order_of


@dataclass(frozen=True)
class Parameters:
    h: float
    d: float
    t: float
    k_opt: int
    voxel_counts: dict = field(default_factory=dict)
    estimated: dict = field(default_factory=dict)


def estimate_parameters(points: pd.DataFrame, *, h=None, d=None, t=None, eps_z: float = 0.1) -> Parameters:
    """h, d (rule H2 of the spec) and t (4 m) unless given. H2: k_z = the largest k with dz / 2^k >= the median
    gap between levels, h = dz / 2^k_z; k_xy = the largest k with diag_xy / 2^k >= the median in-level
    nearest-neighbour distance, d = diag_xy / 2^k_xy."""
    xyz = points[["x", "y", "z"]].to_numpy(np.float64)
    counts, k_opt, _ = voxel_orders(xyz)
    span = xyz.max(axis=0) - xyz.min(axis=0)
    level = split_levels(xyz[:, 2], eps_z)
    zs = np.array([xyz[level == lev, 2].mean() for lev in np.unique(level)])
    gap = float(np.median(np.diff(np.sort(zs)))) if len(zs) > 1 else float(span[2] or 1.0)
    s_xy = level_spacing(xyz, level)
    s_xy = s_xy if np.isfinite(s_xy) else 1.0
    diag = float(np.hypot(span[0], span[1]))
    kz = max(k for k in range(0, 40) if span[2] / 2 ** k >= gap) if span[2] >= gap else 0
    kxy = max(k for k in range(0, 40) if diag / 2 ** k >= s_xy) if diag >= s_xy else 0
    est = {"h": span[2] / 2 ** kz, "d": diag / 2 ** kxy, "t": 4.0, "level_gap": gap, "spacing": s_xy}
    return Parameters(h=float(h if h is not None else est["h"]), d=float(d if d is not None else est["d"]),
                      t=float(t if t is not None else est["t"]), k_opt=k_opt, voxel_counts=counts, estimated=est)


def split_levels(z: np.ndarray, eps_z: float = 0.1) -> np.ndarray:
    """Level index of each height: sorted heights split where the gap exceeds ``eps_z`` (S3)."""
    z = np.asarray(z, np.float64)
    order = np.argsort(z, kind="stable")
    breaks = np.concatenate([[0], np.cumsum(np.diff(z[order]) > eps_z)])
    level = np.empty(len(z), np.int64)
    level[order] = breaks
    return level


@dataclass
class Cluster:
    """Points of one level joined by planimetric distance <= d (S4); kind "sown" or "chain" (S5)."""

    index: int
    level: int
    z: float
    ids: np.ndarray
    xy: np.ndarray
    kind: str = ""


def cluster_level(xy: np.ndarray, d: float) -> np.ndarray:
    """Connected components of the points closer than ``d`` in plan (single linkage)."""
    n = len(xy)
    if n == 1:
        return np.zeros(1, np.int64)
    pairs = cKDTree(xy).query_pairs(d, output_type="ndarray")
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    return labels


def classify_cluster(xy: np.ndarray, footprint, spacing: float, t: float) -> str:
    """"chain" (every point within t of the footprint's outline) or "sown" (a plate of points), the spec's S5
    rule: with points off the outline it is a sown whether or not the share / count tests decide it, as
    "non-classified" clusters become sowns in the dissertation; so ``spacing`` does not change the answer."""
    if footprint is None or footprint.is_empty:
        return "chain"
    on_outline = shapely.distance(footprint.boundary, shapely.points(xy)) <= t
    return "chain" if on_outline.all() else "sown"
