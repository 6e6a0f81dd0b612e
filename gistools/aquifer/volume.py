"""Thickness and volume of the unit between two surfaces (S9).

Thickness T = z_upper - z_lower, defined where both surfaces are; negative where they
cross, reported as it is. The volume inside a polygon W is exact for TINs: the triangles of
both surfaces and W are overlaid (shapely), T is linear on every piece, so the piece's
volume is its area times T at its centroid; pieces where T changes sign are split along
T = 0, which gives the positive and negative parts exactly. Units: CRS units (m -> m^3).
"""

from __future__ import annotations

import numpy as np
import shapely
import shapely.affinity

from .surface import Surface, height_at

__all__ = ["tin_integral", "thickness_at", "overlay_volume", "common_footprint", "planes"]


def thickness_at(upper: Surface, lower: Surface, qx, qy, method: str = "tin", *, clip_negative: bool = False, **kw):
    """Thickness at points; NaN where a TIN surface does not reach (method "tin")."""
    zu, _ = height_at(upper, qx, qy, method, **kw)
    zl, _ = height_at(lower, qx, qy, method, **kw)
    t = zu - zl
    return np.maximum(t, 0.0) if clip_negative else t


def common_footprint(*surfaces: Surface):
    """Where all the surfaces are: the intersection of their outlines."""
    out = surfaces[0].outline()
    for s in surfaces[1:]:
        out = out.intersection(s.outline())
    return out


def planes(surface: Surface, origin) -> np.ndarray:
    """Coefficients (a, b, c) of z = a (x - ox) + b (y - oy) + c for every triangle."""
    ox, oy = origin
    t = surface.triangles
    x, y, z = surface.x - ox, surface.y - oy, surface.z
    x0, y0, z0 = x[t[:, 0]], y[t[:, 0]], z[t[:, 0]]
    ux, uy, uz = x[t[:, 1]] - x0, y[t[:, 1]] - y0, z[t[:, 1]] - z0
    vx, vy, vz = x[t[:, 2]] - x0, y[t[:, 2]] - y0, z[t[:, 2]] - z0
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    a, b = -nx / nz, -ny / nz
    c = z0 - a * x0 - b * y0
    return np.column_stack([a, b, c])


def _triangle_polygons(surface: Surface, origin) -> np.ndarray:
    cache = surface.__dict__.setdefault("_polygons", {})
    key = (float(origin[0]), float(origin[1]), len(surface.triangles))
    if key not in cache:
        cache.clear()
        cache[key] = _make_triangle_polygons(surface, origin)
    return cache[key]


def _make_triangle_polygons(surface: Surface, origin) -> np.ndarray:
    ox, oy = origin
    t = surface.triangles
    coords = np.stack([np.column_stack([surface.x[t[:, i]] - ox, surface.y[t[:, i]] - oy]) for i in (0, 1, 2, 0)], axis=1)
    return shapely.polygons(coords)


def _halfplane(bounds, a, b, c):
    """The part of each box (minx, miny, maxx, maxy) where a x + b y + c >= 0, as polygons (Sutherland-Hodgman)."""
    out = []
    for (x0, y0, x1, y1), ai, bi, ci in zip(bounds, a, b, c):
        pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        f = [ai * px + bi * py + ci for px, py in pts]
        poly = []
        for k in range(4):
            p, q = pts[k], pts[(k + 1) % 4]
            fp, fq = f[k], f[(k + 1) % 4]
            if fp >= 0:
                poly.append(p)
            if (fp >= 0) != (fq >= 0):
                s = fp / (fp - fq)
                poly.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
        out.append(shapely.Polygon(poly) if len(poly) >= 3 else shapely.Polygon())
    return np.asarray(out, dtype=object)


def _integral(surface: Surface, w, origin):
    """(integral of z over W, area of W covered, triangle inside W flags, triangle polygons) for one TIN:
    whole triangles inside W by their vertex mean, the few that cross W's boundary clipped."""
    polys = _triangle_polygons(surface, origin)
    t = surface.triangles
    inside = shapely.contains(w, polys)
    touch = ~inside & shapely.intersects(w, polys)
    x, y = surface.x - origin[0], surface.y - origin[1]
    area = 0.5 * np.abs((x[t[:, 1]] - x[t[:, 0]]) * (y[t[:, 2]] - y[t[:, 0]])
                        - (y[t[:, 1]] - y[t[:, 0]]) * (x[t[:, 2]] - x[t[:, 0]]))
    zmean = surface.z[t].mean(axis=1)
    total = float(np.sum(area[inside] * zmean[inside]))
    covered = float(np.sum(area[inside]))
    if touch.any():
        parts = shapely.intersection(polys[touch], w)
        pa = shapely.area(parts)
        ok = pa > 0
        if ok.any():
            c = shapely.get_coordinates(shapely.centroid(parts[ok]))
            coef = planes(surface, origin)[touch][ok]
            total += float(np.sum(pa[ok] * (coef[:, 0] * c[:, 0] + coef[:, 1] * c[:, 1] + coef[:, 2])))
            covered += float(np.sum(pa[ok]))
    return total, covered, inside, polys


def clip_triangles(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Intersections of triangle pairs a[i] n b[i] ((n, 3, 2) each, counter-clockwise), vectorised
    Sutherland-Hodgman: (vertices (n, 9, 2), vertex counts (n,)); a convex polygon each, count < 3 if empty."""
    n = len(a)
    m = 9
    poly = np.zeros((n, m, 2))
    poly[:, :3] = a
    k = np.full(n, 3)
    rows = np.arange(n)
    for e in range(3):
        p, q = b[:, e], b[:, (e + 1) % 3]
        ex, ey = q[:, 0] - p[:, 0], q[:, 1] - p[:, 1]
        side = ex[:, None] * (poly[:, :, 1] - p[:, None, 1]) - ey[:, None] * (poly[:, :, 0] - p[:, None, 0])
        new = np.zeros_like(poly)
        nk = np.zeros(n, np.int64)
        for i in range(int(k.max()) if n else 0):
            valid = i < k
            j = np.where(i + 1 < k, i + 1, 0)
            s_cur, s_nxt = side[:, i], side[rows, j]
            cur, nxt = poly[:, i], poly[rows, j]
            emit = valid & (s_cur >= 0)
            new[rows[emit], nk[emit]] = cur[emit]
            nk += emit
            cross = valid & ((s_cur >= 0) != (s_nxt >= 0))
            if cross.any():
                t = s_cur[cross] / (s_cur[cross] - s_nxt[cross])
                new[rows[cross], nk[cross]] = cur[cross] + t[:, None] * (nxt[cross] - cur[cross])
                nk += cross
        poly, k = new, nk
    return poly, k


def _negative_part(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Integral of min(f, 0) over triangles v (m, 3, 2), f linear with values f (m, 3) at the vertices (exact)."""
    area = 0.5 * np.abs((v[:, 1, 0] - v[:, 0, 0]) * (v[:, 2, 1] - v[:, 0, 1])
                        - (v[:, 1, 1] - v[:, 0, 1]) * (v[:, 2, 0] - v[:, 0, 0]))
    d = np.sort(f, axis=1)
    d1, d2, d3 = d[:, 0], d[:, 1], d[:, 2]
    out = np.zeros(len(v))
    allneg = d3 <= 0
    out[allneg] = area[allneg] * (d1 + d2 + d3)[allneg] / 3
    one = (d1 < 0) & (d2 >= 0)
    out[one] = area[one] * d1[one] ** 3 / (3 * (d1[one] - d2[one]) * (d1[one] - d3[one]))
    two = (d2 < 0) & (d3 > 0)
    pos = area[two] * d3[two] ** 3 / (3 * (d3[two] - d1[two]) * (d3[two] - d2[two]))
    out[two] = area[two] * (d1 + d2 + d3)[two] / 3 - pos
    return out


def _fan(poly: np.ndarray, k: np.ndarray):
    """Fan triangles (m, 3, 2) of convex polygons and the index of their polygon."""
    tris, owner = [], []
    for j in range(1, int(k.max()) - 1 if len(k) else 0):
        ok = k > j + 1
        idx = np.flatnonzero(ok)
        tris.append(np.stack([poly[idx, 0], poly[idx, j], poly[idx, j + 1]], axis=1))
        owner.append(idx)
    if not tris:
        return np.zeros((0, 3, 2)), np.zeros(0, np.int64)
    return np.concatenate(tris), np.concatenate(owner)


def tin_integral(surface: Surface, within, *, origin=None) -> tuple[float, float]:
    """(exact integral of the TIN's z over ``within`` where the TIN is, the area of that part), CRS units."""
    origin = surface.centre if origin is None else origin
    w = shapely.affinity.translate(within, -origin[0], -origin[1])
    shapely.prepare(w)
    total, area, _, _ = _integral(surface, w, origin)
    return total, area


def overlay_volume(upper: Surface, lower: Surface, within=None, *, origin=None) -> dict:
    """Exact volume between two TINs inside ``within`` (clipped to where both surfaces are; default: all of it).

    Returns {"volume", "volume_positive", "volume_negative" (<= 0), "area", "thickness_min", "thickness_max"}
    in CRS units. The net volume is the difference of the two surfaces' exact integrals over W. The
    negative part and the extremes come from the overlay of the triangle pairs that can hold them
    (bounded by the thickness at their vertices): pairs inside W are clipped with numpy, pairs on W's
    edge with shapely. ``origin``: where coordinates are centred (default: the upper surface's centre;
    one origin for all units lets them share the triangle polygons).
    """
    origin = upper.centre if origin is None else origin
    footprint = common_footprint(upper, lower)
    region = footprint if within is None else footprint.intersection(within)
    if region.is_empty or region.area <= 0:
        return {"volume": 0.0, "volume_positive": 0.0, "volume_negative": 0.0, "area": 0.0,
                "thickness_min": float("nan"), "thickness_max": float("nan")}
    w = shapely.affinity.translate(region, -origin[0], -origin[1])
    shapely.prepare(w)
    iu_total, area, in_u, pu = _integral(upper, w, origin)
    il_total, _, in_l, pl = _integral(lower, w, origin)
    volume = iu_total - il_total
    near_u = np.flatnonzero(in_u | shapely.intersects(w, pu))
    near_l = np.flatnonzero(in_l | shapely.intersects(w, pl))
    a_idx, b_idx = shapely.STRtree(pl[near_l]).query(pu[near_u])
    ia, ib = near_u[a_idx], near_l[b_idx]
    cu, cl = planes(upper, origin), planes(lower, origin)
    d = cu[ia] - cl[ib]  # thickness = d0 x + d1 y + d2 on the pair's intersection
    ux, uy = upper.x - origin[0], upper.y - origin[1]
    lx, ly = lower.x - origin[0], lower.y - origin[1]
    ta, tb = upper.triangles[ia], lower.triangles[ib]
    on_a = d[:, None, 0] * ux[ta] + d[:, None, 1] * uy[ta] + d[:, None, 2]
    on_b = d[:, None, 0] * lx[tb] + d[:, None, 1] * ly[tb] + d[:, None, 2]
    lower_bound = np.maximum(on_a.min(axis=1), on_b.min(axis=1))  # a linear function's min on ta n tb
    upper_bound = np.minimum(on_a.max(axis=1), on_b.max(axis=1))
    lo, hi = _vertex_extremes(upper, lower, w, origin)
    want = (lower_bound < 0) | (lower_bound < lo) | (upper_bound > hi)
    inside = in_u[ia] & in_l[ib]
    negative = 0.0
    # pairs inside W: numpy
    sel = np.flatnonzero(want & inside)
    if sel.size:
        A = np.stack([ux[ta[sel]], uy[ta[sel]]], axis=2)
        B = np.stack([lx[tb[sel]], ly[tb[sel]]], axis=2)
        poly, k = clip_triangles(A, B)
        ds = d[sel]
        vals = ds[:, None, 0] * poly[:, :, 0] + ds[:, None, 1] * poly[:, :, 1] + ds[:, None, 2]
        valid = (np.arange(poly.shape[1])[None, :] < k[:, None]) & (k[:, None] >= 3)
        if valid.any():
            lo = min(lo, float(vals[valid].min()))
            hi = max(hi, float(vals[valid].max()))
        tris, owner = _fan(poly, k)
        if len(tris):
            do = ds[owner]
            f = do[:, None, 0] * tris[:, :, 0] + do[:, None, 1] * tris[:, :, 1] + do[:, None, 2]
            negative += float(_negative_part(tris, f).sum())
    # pairs on W's edge: shapely
    sel = np.flatnonzero(want & ~inside)
    if sel.size:
        pieces = shapely.intersection(shapely.intersection(pu[ia[sel]], pl[ib[sel]]), w)
        ds = d[sel]
        xy, idx = shapely.get_coordinates(pieces, return_index=True)
        if len(xy):
            tv = ds[idx, 0] * xy[:, 0] + ds[idx, 1] * xy[:, 1] + ds[idx, 2]
            lo, hi = min(lo, float(tv.min())), max(hi, float(tv.max()))
        keep = ~shapely.is_empty(pieces) & (shapely.area(pieces) > 0)
        pieces, dn = pieces[keep], -ds[keep]
        if len(pieces):
            half = _halfplane(shapely.bounds(pieces), dn[:, 0], dn[:, 1], dn[:, 2])  # where thickness <= 0
            neg = shapely.intersection(pieces, half)
            na = shapely.area(neg)
            ok = na > 0
            if ok.any():
                c = shapely.get_coordinates(shapely.centroid(neg[ok]))
                negative -= float(np.sum(na[ok] * (dn[ok, 0] * c[:, 0] + dn[ok, 1] * c[:, 1] + dn[ok, 2])))
    return {"volume": volume, "volume_positive": volume - negative, "volume_negative": negative, "area": area,
            "thickness_min": lo if np.isfinite(lo) else float("nan"), "thickness_max": hi if np.isfinite(hi) else float("nan")}


def _vertex_extremes(upper, lower, w, origin) -> tuple[float, float]:
    """Thickness range at the TIN vertices inside W: bounds the exact extremes (which lie on overlay vertices)."""
    from .surface import height_at

    xs = np.concatenate([upper.x, lower.x])
    ys = np.concatenate([upper.y, lower.y])
    inside_w = shapely.contains_xy(w, xs - origin[0], ys - origin[1])
    zu, a = height_at(upper, xs[inside_w], ys[inside_w])
    zl, b = height_at(lower, xs[inside_w], ys[inside_w])
    t = (zu - zl)[a & b]
    return (float(t.min()), float(t.max())) if t.size else (np.inf, -np.inf)
