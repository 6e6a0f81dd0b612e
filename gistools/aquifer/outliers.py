"""Outliers of layer contacts (S1-S2), flagged with their rule and residual, never silently dropped.

The dissertation lists its outliers but gives no rule or threshold; these are gistools' own,
documented in the design spec (section 1, S1-S2), every threshold a parameter:

* ``dup``: points of one layer within ``xy_tol`` of each other. One is kept per group, the one
  with the smallest leave-one-out residual against its neighbours at other positions; same
  position and same height keeps the first. (A repeated id at another position is renamed,
  flag ``renamed_id``, and the point kept.)
* ``outside_cloud``: nearest-neighbour distance > ``f_nn`` x the layer's median one, and
  outside the convex hull of the other layers' points.
* ``wrong_layer``: residual r = z - (least-squares plane of the k nearest other points at the
  point); sigma = 1.4826 MAD(r), threshold = max(``abs_thr``, ``c`` sigma); while the largest
  |r| passes it, that point is flagged and the residuals around it recomputed.
* ``order_violation``: a kept point above the upper layer's TIN or below the lower layer's by
  more than ``order_tol``. Reported only: real data contain such crossings.

Lengths are in the CRS unit (heights too).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = ["OutlierSettings", "plane_residuals", "find_outliers", "order_violations", "FLAGS"]

FLAGS = ("dup", "renamed_id", "outside_cloud", "wrong_layer", "order_violation")


@dataclass(frozen=True)
class OutlierSettings:
    """Thresholds of the outlier rules (CRS units): see the module text."""

    xy_tol: float = 0.5
    k: int = 12
    abs_thr: float = 8.0
    c: float = 5.0
    f_nn: float = 5.0
    order_tol: float = 1.0
    max_iterations: int | None = None  # wrong_layer: at most this many (default: a quarter of the layer)


def plane_residuals(x, y, z, neighbours: np.ndarray) -> np.ndarray:
    """z_i minus the least-squares plane through the points ``neighbours[i]``, evaluated at (x_i, y_i)."""
    return _plane_at_zero(x[neighbours] - x[:, None], y[neighbours] - y[:, None], z[neighbours], z)


class _Neighbours:
    """The k nearest active points of each point, kept current as points are deactivated."""

    def __init__(self, x, y, k, active):
        self.x, self.y, self.k = x, y, k
        self.active = active
        n = len(x)
        self.kq = min(n - 1, k + 6)
        self.tree = cKDTree(np.column_stack([x, y]))
        _, nb = self.tree.query(np.column_stack([x, y]), self.kq + 1)
        nb = nb.reshape(n, self.kq + 1)
        self.cand = np.where(nb == np.arange(n)[:, None], -1, nb)  # never the point itself
        self.sel = np.full((n, k), -1, np.int64)

    def select(self, rows: np.ndarray) -> np.ndarray:
        cand = self.cand[rows]
        ok = (cand >= 0) & self.active[np.maximum(cand, 0)]
        order = np.argsort(~ok, axis=1, kind="stable")[:, : self.k]
        sel = np.take_along_axis(cand, order, axis=1)
        short = ~np.take_along_axis(ok, order, axis=1).all(axis=1)
        if short.any():  # too many neighbours gone: ask the active points directly
            act = np.flatnonzero(self.active)
            tree = cKDTree(np.column_stack([self.x[act], self.y[act]]))
            for r in np.flatnonzero(short):
                i = rows[r]
                _, j = tree.query([self.x[i], self.y[i]], min(self.k + 1, len(act)))
                j = act[np.atleast_1d(j)]
                j = j[j != i][: self.k]
                sel[r, : len(j)] = j
                sel[r, len(j):] = j[-1] if len(j) else i
        self.sel[rows] = sel
        return sel


def _wrong_layer(x, y, z, active, s: OutlierSettings):
    """Indices and residuals of the points flagged wrong_layer, in the order they were found."""
    n_active = int(active.sum())
    if n_active <= s.k + 1:
        return [], np.full(len(x), np.nan)
    nbs = _Neighbours(x, y, min(s.k, n_active - 1), active)
    rows = np.flatnonzero(active)
    r = np.full(len(x), np.nan)
    r[rows] = _res(x, y, z, rows, nbs)
    flagged = []
    limit = s.max_iterations if s.max_iterations is not None else max(1, n_active // 4)
    while len(flagged) < limit:
        ra = r[active]
        sigma = 1.4826 * np.median(np.abs(ra - np.median(ra)))
        thr = max(s.abs_thr, s.c * sigma)
        worst = int(np.flatnonzero(active)[np.argmax(np.abs(ra))])
        if abs(r[worst]) <= thr:
            break
        flagged.append((worst, float(r[worst])))
        active[worst] = False
        affected = np.flatnonzero(active & np.any(nbs.sel == worst, axis=1))
        if affected.size:
            r[affected] = _res(x, y, z, affected, nbs)
    final = r.copy()
    return flagged, final


def _res(x, y, z, rows, nbs: _Neighbours) -> np.ndarray:
    sel = nbs.select(rows)
    dx = x[sel] - x[rows, None]
    dy = y[sel] - y[rows, None]
    return _plane_at_zero(dx, dy, z[sel], z[rows])


def _plane_at_zero(dx, dy, zz, z0) -> np.ndarray:
    s = np.hypot(dx, dy).mean(axis=1, keepdims=True)
    s[s == 0] = 1.0
    dx, dy = dx / s, dy / s
    A = np.stack([dx, dy, np.ones_like(dx)], axis=2)
    ata = np.einsum("nki,nkj->nij", A, A)
    atz = np.einsum("nki,nk->ni", A, zz)
    coef = np.einsum("nij,nj->ni", np.linalg.pinv(ata), atz)
    return z0 - coef[:, 2]


def _duplicates(x, y, z, ids, s: OutlierSettings):
    """(flagged (index, residual) list) of same-position groups, keeping the best member of each."""
    tree = cKDTree(np.column_stack([x, y]))
    pairs = tree.query_pairs(s.xy_tol, output_type="ndarray")
    if len(pairs) == 0:
        return []
    n = len(x)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    sizes = np.bincount(label)
    grouped = np.flatnonzero(sizes[label] > 1)
    active = np.ones(n, bool)
    active[grouped] = False  # neighbours for the residuals: points at other positions
    others = np.flatnonzero(active)
    k = min(s.k, len(others))
    flagged = []
    r = np.zeros(n)
    if k >= 3:
        _, j = cKDTree(np.column_stack([x[others], y[others]])).query(np.column_stack([x[grouped], y[grouped]]), k)
        sel = others[np.asarray(j).reshape(len(grouped), k)]
        r[grouped] = _plane_at_zero(x[sel] - x[grouped, None], y[sel] - y[grouped, None], z[sel], z[grouped])
    for lab in np.unique(label[grouped]):
        members = np.flatnonzero(label == lab)
        keep = members[np.argmin(np.abs(r[members]))]
        flagged += [(int(m), float(r[m])) for m in members if m != keep]
    return flagged


def find_outliers(points: pd.DataFrame, layers, settings: OutlierSettings | None = None):
    """(kept points, flags): flags has id, layer, flag, residual, x, y, z, kept (False = removed from the surface).

    The rules run in order over every layer: repeated ids renamed, duplicates, points outside the cloud, points
    of the wrong layer (each rule sees what the ones before it kept)."""
    s = settings or OutlierSettings()
    rows = []
    keep = np.ones(len(points), bool)
    pts = points.reset_index(drop=True).copy()
    for layer in layers:
        rows += _rename_repeated_ids(pts, layer)
    for rule in (_flag_duplicates, _flag_outside_cloud, _flag_wrong_layer):
        for layer in layers:
            found = rule(pts, layer, keep, s)
            for _, _, _, _, row, _ in found:
                keep[row] = False
            rows += found
    flags = pd.DataFrame(rows, columns=["id", "layer", "flag", "residual", "row", "kept"])
    for c in ("x", "y", "z"):
        flags[c] = pts[c].to_numpy()[flags["row"].to_numpy(np.int64)] if len(flags) else []
    if "line" in pts.columns and len(flags):
        flags["line"] = pts["line"].to_numpy()[flags["row"].to_numpy(np.int64)]
    flags = flags.drop(columns="row")
    return pts[keep].reset_index(drop=True), flags


def _rename_repeated_ids(pts: pd.DataFrame, layer) -> list:
    """Repeated ids at other positions in a layer get new ids (in place); they are kept."""
    rows = []
    sub = pts.index[pts["layer"] == layer]
    dup_ids = pts.loc[sub, "id"].duplicated(keep="first")
    if dup_ids.any():
        next_id = int(pts["id"].max()) + 1
        for i in sub[dup_ids.to_numpy()]:
            rows.append((int(pts.at[i, "id"]), layer, "renamed_id", np.nan, i, True))
            pts.at[i, "id"] = next_id
            next_id += 1
    return rows


def _flag_duplicates(pts: pd.DataFrame, layer, keep, s: OutlierSettings) -> list:
    sub = np.flatnonzero((pts["layer"] == layer).to_numpy())
    x, y, z = (pts[c].to_numpy(np.float64)[sub] for c in ("x", "y", "z"))
    ids = pts["id"].to_numpy()[sub]
    return [(int(ids[i]), layer, "dup", r, sub[i], False) for i, r in _duplicates(x, y, z, ids, s)]


def _flag_outside_cloud(pts: pd.DataFrame, layer, keep, s: OutlierSettings) -> list:
    """Points far from their layer's others (NN distance > f_nn x the median) and outside the other layers' hull."""
    sub = np.flatnonzero((pts["layer"] == layer).to_numpy() & keep)
    other = np.flatnonzero((pts["layer"] != layer).to_numpy() & keep)
    if len(sub) <= 2 or len(other) <= 2:
        return []
    x, y = pts["x"].to_numpy(np.float64), pts["y"].to_numpy(np.float64)
    d, _ = cKDTree(np.column_stack([x[sub], y[sub]])).query(np.column_stack([x[sub], y[sub]]), 2)
    far = d[:, 1] > s.f_nn * np.median(d[:, 1])
    if not far.any():
        return []
    hull = shapely.convex_hull(shapely.multipoints(np.column_stack([x[other], y[other]])))
    if hull.area <= 0:  # the other layers do not span an area: no hull to be outside of
        return []
    outside = ~shapely.intersects_xy(hull, x[sub][far], y[sub][far])
    return [(int(pts.at[i, "id"]), layer, "outside_cloud", float(d_nn), i, False)
            for i, d_nn in zip(sub[far][outside], d[far, 1][outside])]


def _flag_wrong_layer(pts: pd.DataFrame, layer, keep, s: OutlierSettings) -> list:
    sub = np.flatnonzero((pts["layer"] == layer).to_numpy() & keep)
    x, y, z = (pts[c].to_numpy(np.float64)[sub] for c in ("x", "y", "z"))
    x, y = x - x.mean(), y - y.mean()
    flagged, _ = _wrong_layer(x, y, z, np.ones(len(sub), bool), s)
    return [(int(pts.at[sub[i], "id"]), layer, "wrong_layer", r, sub[i], False) for i, r in flagged]


def order_violations(points: pd.DataFrame, surfaces: dict, layers, tol: float = 1.0) -> pd.DataFrame:
    """Kept points above their upper neighbour's TIN or below their lower neighbour's by more than ``tol``."""
    from .surface import height_at

    rows = []
    for k, layer in enumerate(layers):
        sub = points[points["layer"] == layer]
        x, y, z = sub["x"].to_numpy(), sub["y"].to_numpy(), sub["z"].to_numpy()
        for other, sign, name in ((layers[k - 1] if k > 0 else None, 1, "above"),
                                  (layers[k + 1] if k + 1 < len(layers) else None, -1, "below")):
            if other is None:
                continue
            zo, inside = height_at(surfaces[other], x, y)
            excess = sign * (z - zo)
            bad = inside & (excess > tol)
            for i in np.flatnonzero(bad):
                rows.append((int(sub["id"].iloc[i]), layer, "order_violation", float(excess[i]), x[i], y[i], z[i], True,
                             f"{name} {other} by {excess[i]:.3f}"))
    return pd.DataFrame(rows, columns=["id", "layer", "flag", "residual", "x", "y", "z", "kept", "note"])
