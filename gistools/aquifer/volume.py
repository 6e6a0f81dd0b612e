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

__all__ = ["thickness_at", "overlay_volume", "common_footprint", "planes"]


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


def _integral(surface: Surface, w, origin) -> tuple[float, float]:
    """(integral of z over W, area of W covered) for one TIN: whole triangles inside W by their vertex mean,
    the few that cross W's boundary clipped."""
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
    return total, covered


def overlay_volume(upper: Surface, lower: Surface, within=None) -> dict:
    """Exact volume between two TINs inside ``within`` (clipped to where both surfaces are; default: all of it).

    Returns {"volume", "volume_positive", "volume_negative" (<= 0), "area"} in CRS units. The net volume is
    the difference of the two surfaces' exact integrals over W; the negative part comes from the overlay of
    the triangle pairs where the upper surface can be below the lower one (bounded by their vertex values).
    """
    origin = upper.centre
    footprint = common_footprint(upper, lower)
    region = footprint if within is None else footprint.intersection(within)
    if region.is_empty or region.area <= 0:
        return {"volume": 0.0, "volume_positive": 0.0, "volume_negative": 0.0, "area": 0.0,
                "thickness_min": float("nan"), "thickness_max": float("nan")}
    w = shapely.affinity.translate(region, -origin[0], -origin[1])
    shapely.prepare(w)
    iu_total, area = _integral(upper, w, origin)
    il_total, _ = _integral(lower, w, origin)
    volume = iu_total - il_total
    # negative part: overlay only the pairs whose thickness plane may go below 0 on their intersection
    pu, pl = _triangle_polygons(upper, origin), _triangle_polygons(lower, origin)
    iu = np.flatnonzero(shapely.intersects(w, pu))
    il = np.flatnonzero(shapely.intersects(w, pl))
    a_idx, b_idx = shapely.STRtree(pl[il]).query(pu[iu])
    ia, ib = iu[a_idx], il[b_idx]
    cu, cl = planes(upper, origin), planes(lower, origin)
    d = cu[ia] - cl[ib]
    ux, uy = upper.x - origin[0], upper.y - origin[1]
    lx, ly = lower.x - origin[0], lower.y - origin[1]
    ta, tb = upper.triangles[ia], lower.triangles[ib]
    on_a = d[:, None, 0] * ux[ta] + d[:, None, 1] * uy[ta] + d[:, None, 2]
    on_b = d[:, None, 0] * lx[tb] + d[:, None, 1] * ly[tb] + d[:, None, 2]
    lower_bound = np.maximum(on_a.min(axis=1), on_b.min(axis=1))  # min of a linear function on ta n tb
    upper_bound = np.minimum(on_a.max(axis=1), on_b.max(axis=1))
    t_min, t_max = _extremes(upper, lower, w, origin, pu[ia], pl[ib], d, lower_bound, upper_bound)
    cand = lower_bound < 0
    negative = 0.0
    if cand.any():
        pieces = shapely.intersection(pu[ia[cand]], pl[ib[cand]])
        dn = -d[cand]
        nonempty = ~shapely.is_empty(pieces)
        pieces, dn = pieces[nonempty], dn[nonempty]
        inside = shapely.covers(w, pieces)
        if not inside.all():
            pieces[~inside] = shapely.intersection(pieces[~inside], w)
        keep = shapely.area(pieces) > 0
        pieces, dn = pieces[keep], dn[keep]
        if len(pieces):
            half = _halfplane(shapely.bounds(pieces), dn[:, 0], dn[:, 1], dn[:, 2])  # where thickness <= 0
            neg = shapely.intersection(pieces, half)
            na = shapely.area(neg)
            ok = na > 0
            if ok.any():
                c = shapely.get_coordinates(shapely.centroid(neg[ok]))
                negative = -float(np.sum(na[ok] * (dn[ok, 0] * c[:, 0] + dn[ok, 1] * c[:, 1] + dn[ok, 2])))
    return {"volume": volume, "volume_positive": volume - negative, "volume_negative": negative, "area": area,
            "thickness_min": t_min, "thickness_max": t_max}


def _extremes(upper, lower, w, origin, pa, pb, d, lower_bound, upper_bound) -> tuple[float, float]:
    """Exact min and max thickness in W: a piecewise linear function's extremes lie on the overlay's vertices.

    Values at the TIN vertices inside W bound them; only the triangle pairs whose bounds pass those
    values are overlaid (shapely) and evaluated at their pieces' vertices.
    """
    from .surface import height_at

    xs = np.concatenate([upper.x, lower.x])
    ys = np.concatenate([upper.y, lower.y])
    inside_w = shapely.contains_xy(w, xs - origin[0], ys - origin[1])
    zu, a = height_at(upper, xs[inside_w], ys[inside_w])
    zl, b = height_at(lower, xs[inside_w], ys[inside_w])
    t = (zu - zl)[a & b]
    lo = float(t.min()) if t.size else np.inf
    hi = float(t.max()) if t.size else -np.inf
    cand = (lower_bound < lo) | (upper_bound > hi)
    if cand.any():
        pieces = shapely.intersection(shapely.intersection(pa[cand], pb[cand]), w)
        xy, idx = shapely.get_coordinates(pieces, return_index=True)
        if len(xy):
            dc = d[cand][idx]
            tv = dc[:, 0] * xy[:, 0] + dc[:, 1] * xy[:, 1] + dc[:, 2]
            lo, hi = min(lo, float(tv.min())), max(hi, float(tv.max()))
    return (lo if np.isfinite(lo) else float("nan")), (hi if np.isfinite(hi) else float("nan"))
