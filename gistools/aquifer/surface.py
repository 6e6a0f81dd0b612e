"""One layer's surface: a Delaunay TIN of its points, its boundary ring, heights and densified points (S4, S5, S7, S8).

Coordinates are centred (the layer's own centroid subtracted) before triangulation, as
Qhull wants for large projected coordinates (Gauss-Boaga eastings are 1.5e6 m). Triangles
are stored counter-clockwise seen from above. Lengths and heights are in CRS units.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from scipy.spatial import Delaunay, cKDTree

from ..errors import InputError

__all__ = ["Surface", "build_surface", "boundary_rings", "mask_outside", "height_at", "densify", "unique_edges",
           "HEIGHT_METHODS"]

HEIGHT_METHODS = ("tin", "knn", "idw")


@dataclass
class Surface:
    """A TIN: points (ids, x, y, z), CCW triangles (index triples), the Delaunay locator and a kept-triangle mask."""

    name: str
    ids: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    triangles: np.ndarray
    centre: tuple[float, float]
    delaunay: Delaunay = field(repr=False)
    kept: np.ndarray = field(repr=False)  # per Delaunay simplex: still part of the surface (after masking)

    @property
    def xyz(self) -> np.ndarray:
        return np.column_stack([self.x, self.y, self.z])

    @cached_property
    def rings(self) -> list[np.ndarray]:
        """Boundary rings (vertex indices, CCW), the outer one first."""
        return boundary_rings(self.triangles, self.x, self.y)

    def ring(self) -> np.ndarray:
        """Vertex indices of the outer boundary ring, CCW, first vertex not repeated."""
        return self.rings[0]

    @cached_property
    def _outline(self):
        if len(self.rings) == 1:
            r = self.rings[0]
            return shapely.Polygon(np.column_stack([self.x[r], self.y[r]]))
        # masked: the union of the triangles (valid whatever the rings look like: holes, pinched vertices)
        t = self.triangles
        coords = np.stack([np.column_stack([self.x[t[:, i]], self.y[t[:, i]]]) for i in (0, 1, 2, 0)], axis=1)
        return shapely.coverage_union_all(shapely.polygons(coords))

    def outline(self):
        """The boundary as a polygon (outer ring, and holes where masking opened them)."""
        return self._outline


def _ccw(x, y, tris) -> np.ndarray:
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    cross = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
    out = tris.copy()
    flip = cross < 0
    out[flip, 1], out[flip, 2] = tris[flip, 2], tris[flip, 1]
    return out


def build_surface(name: str, ids, x, y, z) -> Surface:
    """Delaunay TIN of one layer's points (centred first). Needs 3 points not on one line, no repeated xy."""
    ids, x, y, z = (np.asarray(a) for a in (ids, x, y, z))
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    if x.size < 3:
        raise InputError(f"layer {name}: {x.size} point(s); a surface needs at least 3",
                         hint="Check the layer names and the outlier flags")
    cx, cy = float(np.mean(x)), float(np.mean(y))
    xy = np.column_stack([x - cx, y - cy])
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    if (np.diff(xy[order], axis=0) == 0).all(axis=1).any():
        raise InputError(f"layer {name}: repeated x, y positions", hint="Flag duplicates first (aquifer outliers)")
    sv = np.linalg.svd(xy, compute_uv=False) if len(xy) >= 3 else np.zeros(2)
    if len(xy) < 3 or sv[1] <= 1e-7 * max(sv[0], 1e-12):  # on one line up to rounding: slivers of no area
        raise InputError(f"layer {name}: the points do not span an area ({len(xy)} points, all on one line)",
                         hint="A surface needs points that are not all on one line")
    try:
        tri = Delaunay(xy)
    except Exception as err:  # QhullError: all points on a line
        raise InputError(f"layer {name}: the points do not span an area ({str(err).splitlines()[0]})",
                         hint="A surface needs points that are not all on one line") from None
    triangles = _ccw(xy[:, 0], xy[:, 1], tri.simplices.astype(np.int64))
    return Surface(name, ids, x, y, z, triangles, (cx, cy), tri, np.ones(len(tri.simplices), bool))


def _edge_keys(edges: np.ndarray) -> np.ndarray:
    """One int64 per undirected edge (vertex indices below 2**31)."""
    lo, hi = np.minimum(edges[:, 0], edges[:, 1]), np.maximum(edges[:, 0], edges[:, 1])
    return (lo.astype(np.int64) << 32) | hi.astype(np.int64)


def unique_edges(triangles: np.ndarray) -> np.ndarray:
    """Undirected edges (i < j) of a triangle list, each once."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    keys = np.unique(_edge_keys(e))
    return np.column_stack([keys >> 32, keys & 0xFFFFFFFF])


def boundary_rings(triangles: np.ndarray, x=None, y=None) -> list[np.ndarray]:
    """Closed boundary rings (vertex indices, CCW outer first, then holes) from the sides used by one triangle.

    The dissertation's perimeter rule (S5): count the triangles on each side; sides used once
    are boundary sides, chained into rings. For an unmasked Delaunay TIN this is the convex hull.
    """
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    _, inverse, counts = np.unique(_edge_keys(directed), return_inverse=True, return_counts=True)
    boundary = directed[counts[inverse.ravel()] == 1]  # directed as in their (CCW) triangle: interior on the left
    nxt: dict[int, list[int]] = {}
    for a, b in boundary:
        nxt.setdefault(int(a), []).append(int(b))
    rings = []
    while nxt:
        start = min(nxt)
        ring = [start]
        cur = start
        while True:
            outs = nxt[cur]
            b = outs.pop()
            if not outs:
                del nxt[cur]
            if b == start:
                break
            ring.append(b)
            cur = b
        rings.append(np.asarray(ring, np.int64))
    if x is not None and len(rings) > 1:
        def area(r):
            cx, cy = x[r] - x[r].mean(), y[r] - y[r].mean()
            return abs(0.5 * float(np.sum(cx * np.roll(cy, -1) - np.roll(cx, -1) * cy)))

        rings.sort(key=area, reverse=True)
    return rings


def mask_outside(surface: Surface, polygon) -> Surface:
    """Remove triangles whose centroid or a side midpoint lies outside ``polygon`` (the dissertation's
    concave / hole rule, ch. 2): the surface then follows a concave outline or has holes."""
    shapely.prepare(polygon)
    t = surface.triangles
    x, y = surface.x, surface.y
    probes = [((x[t[:, 0]] + x[t[:, 1]] + x[t[:, 2]]) / 3, (y[t[:, 0]] + y[t[:, 1]] + y[t[:, 2]]) / 3)]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        probes.append(((x[t[:, i]] + x[t[:, j]]) / 2, (y[t[:, i]] + y[t[:, j]]) / 2))
    inside = np.ones(len(t), bool)
    for px, py in probes:
        inside &= shapely.contains_xy(polygon, px, py) | shapely.intersects_xy(polygon.boundary, px, py)
    if not inside.any():
        raise InputError(f"layer {surface.name}: no triangle inside the clipping polygon", hint="Check the polygon's CRS")
    # map kept triangles back to Delaunay simplices (same order as built)
    kept = surface.kept.copy()
    kept[np.flatnonzero(kept)[~inside]] = False
    return Surface(surface.name, surface.ids, surface.x, surface.y, surface.z, t[inside], surface.centre, surface.delaunay,
                   kept)


def _morton_order(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A Z-order (Morton) permutation of points: neighbours in the order are neighbours in space."""
    def spread(v):
        v = v.astype(np.uint64)
        for shift, mask in ((16, 0x0000FFFF0000FFFF), (8, 0x00FF00FF00FF00FF), (4, 0x0F0F0F0F0F0F0F0F),
                            (2, 0x3333333333333333), (1, 0x5555555555555555)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        return v

    def quantise(v):
        lo, hi = np.nanmin(v), np.nanmax(v)
        return np.nan_to_num((v - lo) / (hi - lo if hi > lo else 1.0) * 65535, nan=0).astype(np.uint64)

    return np.argsort(spread(quantise(x)) | (spread(quantise(y)) << np.uint64(1)), kind="stable")


def _locate(surface: Surface, qx, qy):
    """(simplex index, barycentric weights (n, 3)) of query points; simplex -1 outside the surface."""
    cx, cy = surface.centre
    q = np.column_stack([np.asarray(qx, np.float64) - cx, np.asarray(qy, np.float64) - cy])
    if len(q) > 1000:
        # Qhull's point location walks from the previous point's triangle: spatially sorted queries walk little
        order = _morton_order(q[:, 0], q[:, 1])
        s = np.empty(len(q), np.int64)
        s[order] = surface.delaunay.find_simplex(q[order])
    else:
        s = surface.delaunay.find_simplex(q)
    inside = s >= 0
    s = np.where(inside & surface.kept[np.maximum(s, 0)], s, -1)
    T = surface.delaunay.transform[np.maximum(s, 0)]
    b = np.einsum("nij,nj->ni", T[:, :2, :], q - T[:, 2, :])
    w = np.column_stack([b, 1 - b.sum(axis=1)])
    return s, w


def height_at(surface: Surface, qx, qy, method: str = "tin", *, k: int = 10, power: float = 2.0):
    """(z, inside) of the surface at query points (S8).

    ``tin``: linear on the triangle holding the point, NaN outside the boundary. ``knn``:
    unweighted mean of the k planimetrically nearest points (the dissertation's "average of
    the heights of the points closely located"). ``idw``: inverse-distance weights 1/d^power
    over k neighbours. ``inside`` says whether the point lies within the boundary
    (interpolation) or not (extrapolation, for knn / idw).
    """
    if method not in HEIGHT_METHODS:
        raise InputError(f"height method {method!r} is not one of {', '.join(HEIGHT_METHODS)}")
    qx, qy = np.atleast_1d(np.asarray(qx, np.float64)), np.atleast_1d(np.asarray(qy, np.float64))
    s, w = _locate(surface, qx, qy)
    inside = s >= 0
    if method == "tin":
        verts = surface.delaunay.simplices[np.maximum(s, 0)]
        z = np.einsum("ni,ni->n", w, surface.z[verts])
        return np.where(inside, z, np.nan), inside
    cx, cy = surface.centre
    tree = cKDTree(np.column_stack([surface.x - cx, surface.y - cy]))
    kk = min(k, surface.x.size)
    d, idx = tree.query(np.column_stack([qx - cx, qy - cy]), k=kk)
    d, idx = d.reshape(len(qx), kk), idx.reshape(len(qx), kk)
    zz = surface.z[idx]
    if method == "knn":
        return zz.mean(axis=1), inside
    with np.errstate(divide="ignore"):
        wts = 1.0 / np.maximum(d, 1e-12) ** power
    return (wts * zz).sum(axis=1) / wts.sum(axis=1), inside


def densify(surface: Surface, n_per_edge: int = 2, t=None) -> np.ndarray:
    """New points on every TIN edge (S7): P0 + t (P1 - P0) for t = 1/(n+1) ... n/(n+1), as (x, y, z) rows.

    The dissertation's printed counts (LS 5916, AU 5722, AD 4308, AQ 2092) are 2 per edge.
    """
    ts = np.asarray(t if t is not None else np.arange(1, n_per_edge + 1) / (n_per_edge + 1), np.float64)
    e = unique_edges(surface.triangles)
    p0, p1 = surface.xyz[e[:, 0]], surface.xyz[e[:, 1]]
    pts = p0[None, :, :] + ts[:, None, None] * (p1 - p0)[None, :, :]
    return pts.transpose(1, 0, 2).reshape(-1, 3)
