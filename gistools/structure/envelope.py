"""Structure reconstruction, steps S6-S8: closed loops, matching between levels, bands and the watertight envelope.

Loops (S6): a chain's loop is the cycle of its Delaunay edges no longer than 1.25 x the median
nearest-neighbour distance (each point used once, each side once); a sown's footprint is the union
of the faces those edges close (``shapely.polygonize``), holes kept. Loops of one level nest even-odd
(a loop inside another is a hole: a courtyard stays a hole). Matching (S7): clusters of consecutive
levels (height step <= h) pair when their loops come within t (chain - chain) or a chain's loop meets
a sown's footprint grown by t (sown - chain). Bands: a strip of n_a + n_b triangles between the two
loops of a pair (the chain's loop projected to the sown's height for sown - chain pairs). Envelope
(S8): at every level the region where bands arrive from below (D) and leave upwards (U); D - U is
roof (normals up), U - D floor (normals down), each triangulated by constrained Delaunay on the loop
vertices only, so the bands and the horizontal faces close into one consistently wound surface.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import Delaunay, cKDTree

from ..mesh import wall
from ..errors import InputError

__all__ = ["chain_loops", "sown_footprint", "level_region", "match_clusters", "band", "envelope", "winding_number", "catmull_rom_loop"]


def _short_edges(xy: np.ndarray, factor: float = 1.25):
    if len(xy) < 3:
        raise InputError(f"a cluster of {len(xy)} point(s) makes no loop", hint="Check the distance parameter d")
    tri = Delaunay(xy - xy.mean(axis=0))
    e = np.concatenate([tri.simplices[:, [0, 1]], tri.simplices[:, [1, 2]], tri.simplices[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    d_nn, _ = cKDTree(xy).query(xy, 2)
    limit = factor * float(np.median(d_nn[:, 1]))
    length = np.hypot(*(xy[e[:, 0]] - xy[e[:, 1]]).T)
    return e[length <= limit + 1e-9]


def _insertion_loop(xy: np.ndarray) -> np.ndarray | None:
    """One simple loop through all points by cheapest insertion into their convex hull (outlines digitised by
    their corners, whose sides differ in length); None when no simple loop comes out."""
    from scipy.spatial import ConvexHull

    try:
        ring = list(ConvexHull(xy).vertices)
    except Exception:
        return None
    rest = [i for i in range(len(xy)) if i not in set(ring)]
    while rest:
        best = None
        for p in rest:
            for k in range(len(ring)):
                a, b = ring[k], ring[(k + 1) % len(ring)]
                cost = (np.hypot(*(xy[a] - xy[p])) + np.hypot(*(xy[p] - xy[b])) - np.hypot(*(xy[a] - xy[b])))
                if best is None or cost < best[0]:
                    trial = ring[: k + 1] + [p] + ring[k + 1:]
                    if shapely.LinearRing(xy[trial]).is_simple:
                        best = (cost, p, trial)
        if best is None:
            return None
        ring = best[2]
        rest.remove(best[1])
    return np.asarray(ring)


def chain_loops(xy: np.ndarray) -> list[np.ndarray]:
    """Closed loops (vertex indices, counter-clockwise) through every point of a chain cluster: the cycle of
    its short Delaunay edges, or, when those do not form one (an outline digitised by its corners), the
    cheapest-insertion loop."""
    e = _short_edges(xy)
    deg = np.bincount(e.ravel(), minlength=len(xy))
    if (deg != 2).any():
        ring = _insertion_loop(xy) if len(xy) <= 500 else None
        if ring is not None:
            x, y = xy[ring, 0], xy[ring, 1]
            if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
                ring = ring[::-1]
            return [ring]
        bad = int(np.flatnonzero(deg != 2)[0])
        raise InputError(f"chain point {bad} at ({xy[bad, 0]:.2f}, {xy[bad, 1]:.2f}) has {deg[bad]} loop sides, not 2",
                         hint="The points of a chain must follow one closed outline at a regular spacing; adjust d or t")
    nbrs = [[] for _ in range(len(xy))]
    for a, b in e:
        nbrs[a].append(int(b))
        nbrs[b].append(int(a))
    seen = np.zeros(len(xy), bool)
    loops = []
    for start in range(len(xy)):
        if seen[start]:
            continue
        loop, prev, cur = [start], -1, start
        seen[start] = True
        while True:
            nxt = nbrs[cur][0] if nbrs[cur][0] != prev else nbrs[cur][1]
            if nxt == start:
                break
            loop.append(nxt)
            seen[nxt] = True
            prev, cur = cur, nxt
        ring = np.asarray(loop)
        x, y = xy[ring, 0], xy[ring, 1]
        if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
            ring = ring[::-1]
        loops.append(ring)
    return loops


def sown_footprint(xy: np.ndarray):
    """The area a sown plate covers: the faces its short Delaunay edges close, unioned (holes kept)."""
    e = _short_edges(xy)
    lines = shapely.linestrings(np.stack([xy[e[:, 0]], xy[e[:, 1]]], axis=1))
    faces = shapely.get_parts(shapely.polygonize(lines))
    d_nn, _ = cKDTree(xy).query(xy, 2)
    s = float(np.median(d_nn[:, 1]))
    faces = faces[shapely.area(faces) <= 2 * s * s + 1e-9]
    return shapely.union_all(faces) if len(faces) else shapely.Polygon()


def level_region(rings: list[np.ndarray]):
    """Even-odd region of closed rings ((n, 2) arrays): a ring inside another is a hole."""
    region = shapely.Polygon()
    for r in rings:
        region = shapely.symmetric_difference(region, shapely.Polygon(r))
    return region


def match_clusters(lower, upper, t: float) -> bool:
    """Whether two clusters of consecutive levels are joined (see the module text)."""
    if lower.kind == "chain" and upper.kind == "chain":
        return any(shapely.distance(shapely.LinearRing(a), shapely.LinearRing(b)) <= t
                   for a in lower.rings for b in upper.rings)
    return bool(shapely.intersects(lower.footprint.buffer(t), upper.footprint))


def band(lower_ring: np.ndarray, upper_ring: np.ndarray) -> np.ndarray:
    """Triangles (n, 3, 3) of the strip between a lower and an upper closed loop (both oriented like their region)."""
    w = wall(upper_ring, lower_ring)
    pts = np.vstack([upper_ring, lower_ring])
    return pts[w]


def _insert_vertices(region, vertices: np.ndarray, tol: float = 1e-7):
    """``region`` with every loop vertex that lies on its boundary inserted (no T-junctions with the bands)."""
    tree = cKDTree(vertices)

    def ring(coords):
        coords = np.asarray(coords)
        out = []
        for p, q in zip(coords[:-1], coords[1:]):
            out.append(p)
            seg = q - p
            L = float(np.hypot(*seg))
            if L == 0:
                continue
            mid = (p + q) / 2
            cand = vertices[tree.query_ball_point(mid, L / 2 + tol)]
            if len(cand):
                lam = ((cand - p) @ seg) / (L * L)
                dist = np.abs((cand[:, 0] - p[0]) * seg[1] - (cand[:, 1] - p[1]) * seg[0]) / L
                on = (lam > 1e-9) & (lam < 1 - 1e-9) & (dist <= tol)
                for k in np.argsort(lam[on]):
                    out.append(cand[on][k])
        out.append(coords[-1])
        return np.asarray(out)

    polys = []
    for poly in shapely.get_parts(region):
        if poly.geom_type != "Polygon" or poly.area <= 1e-9:
            continue
        polys.append(shapely.Polygon(ring(poly.exterior.coords), [ring(r.coords) for r in poly.interiors]))
    return polys


def _flat_triangles(region, vertices: np.ndarray, z: float, up: bool) -> list[np.ndarray]:
    out = []
    for poly in _insert_vertices(region, vertices):
        tris = shapely.get_parts(shapely.constrained_delaunay_triangles(poly))
        for tri in tris:
            c = np.asarray(tri.exterior.coords)[:3]
            area2 = (c[1, 0] - c[0, 0]) * (c[2, 1] - c[0, 1]) - (c[1, 1] - c[0, 1]) * (c[2, 0] - c[0, 0])
            if abs(area2) < 1e-12:
                continue
            if (area2 > 0) != up:
                c = c[::-1]
            out.append(np.column_stack([c, np.full(3, z)]))
    return out


def _snap(ring: np.ndarray, points: np.ndarray, t: float) -> np.ndarray:
    """A loop projected onto a sown: each vertex moved to the sown's nearest point within ``t`` (kept otherwise),
    so loops projected from above and below meet on shared points."""
    d, j = cKDTree(points).query(ring)
    out = ring.copy()
    near = d <= t
    out[near] = points[j[near]]
    return out


def envelope(levels: list, pairs: list, t: float = 4.0) -> np.ndarray:
    """All triangles (m, 3, 3) of the closed surface: bands of the matched pairs and the roofs / floors.

    ``levels``: per level (z, clusters), each cluster with ``rings`` ((n, 2) arrays, oriented like their
    region), ``kind`` and ``footprint``; ``pairs``: (lower level index, lower cluster, upper level index,
    upper cluster) of the matched clusters.
    """
    arriving = {i: [] for i in range(len(levels))}
    leaving = {i: [] for i in range(len(levels))}
    triangles = []
    for li, lc, ui, uc in pairs:
        zl, zu = levels[li][0], levels[ui][0]
        for rl, ru in _paired_rings(lc, uc, zl, zu, t):
            triangles.append(band(np.column_stack([rl, np.full(len(rl), zl)]), np.column_stack([ru, np.full(len(ru), zu)])))
            leaving[li].append(rl)
            arriving[ui].append(ru)
    for i, (z, _) in enumerate(levels):
        triangles += _roof_and_floor(arriving[i], leaving[i], z)
    return np.concatenate(triangles) if triangles else np.zeros((0, 3, 3))


def _paired_rings(lc, uc, zl: float, zu: float, t: float) -> list:
    """(lower ring, upper ring) of each band between two matched clusters."""
    if lc.kind == "chain" and uc.kind == "chain":
        if len(lc.rings) != len(uc.rings):
            raise InputError(f"clusters at {zl} and {zu} have {len(lc.rings)} and {len(uc.rings)} loops",
                             hint="Loops of matched chains must correspond one to one")
        return list(zip(lc.rings, uc.rings))
    if lc.kind == "chain":  # chain below a sown: its loop projected up, snapped to the sown's points within t
        return [(r, _snap(r, uc.xy, t)) for r in lc.rings]
    return [(_snap(r, lc.xy, t), r) for r in uc.rings]  # a sown below a chain: the chain's loop projected down


def _roof_and_floor(arriving: list, leaving: list, z: float) -> list:
    """Flat triangles of a level: roofs where bands arrive and none leave, floors where they leave and none arrive."""
    if not arriving and not leaving:
        return []
    d, u = level_region(arriving), level_region(leaving)
    verts = np.vstack(arriving + leaving)
    out = []
    for region, up in ((shapely.difference(d, u), True), (shapely.difference(u, d), False)):
        if not region.is_empty and region.area > 1e-9:
            flat = _flat_triangles(region, verts, z, up)
            if flat:
                out.append(np.stack(flat))
    return out


def winding_number(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number of points about a closed triangle mesh (1 inside, 0 outside, for outward
    normals): the solid angles of the triangles seen from each point (van Oosterom and Strackee), summed."""
    pts = np.atleast_2d(np.asarray(points, np.float64))
    out = np.zeros(len(pts))
    for k, p in enumerate(pts):
        a, b, c = (vertices[faces[:, i]] - p for i in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la + \
            np.einsum("ij,ij->i", c, a) * lb
        out[k] = np.sum(2 * np.arctan2(num, den)) / (4 * np.pi)
    return out


def catmull_rom_loop(ring: np.ndarray, *, eps: float = 1e-12):
    """The dissertation's piecewise Catmull-Rom loop (ch. 2.4.2) of a closed loop (n, 2), loop_mode 1.

    Through every vertex P_i runs the line parallel to P_i+1 - P_i-1; the new points are the intersections
    of consecutive lines (quadratic Bezier control points between P_i and P_i+1). Returns (points (n, 2),
    with NaN where two consecutive lines are parallel: a straight side, "no intersection"; lines: one row
    per vertex (kind "y" for y = a x + b, "x" for x = c y + d), slope, intercept).
    """
    r = np.asarray(ring, np.float64)
    n = len(r)
    d = np.roll(r, -1, axis=0) - np.roll(r, 1, axis=0)  # direction of the line through P_i
    lines = []
    for (px, py), (dx, dy) in zip(r, d):
        if abs(dx) >= abs(dy):
            a = dy / dx
            lines.append(("y", a, py - a * px))
        else:
            c = dx / dy
            lines.append(("x", c, px - c * py))
    pts = np.full((n, 2), np.nan)
    for i in range(n):
        j = (i + 1) % n
        p, u = r[i], d[i]
        q, v = r[j], d[j]
        den = u[0] * v[1] - u[1] * v[0]
        if abs(den) <= eps * max(np.hypot(*u) * np.hypot(*v), 1.0):
            continue  # parallel lines: no intersection, the side stays straight
        s_ = ((q[0] - p[0]) * v[1] - (q[1] - p[1]) * v[0]) / den
        pts[i] = p + s_ * u
    return pts, lines
