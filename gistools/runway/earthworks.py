"""Strip areas, cross sections, the area diagram and the Brueckner (mass-haul) curve (steps 8-10), pure functions.

Sign convention: d = ground - design; d > 0 is cut (ground to dig), d < 0 fill. Areas in m^2,
volumes in m^3 (CRS units squared / cubed).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..parameters import option

__all__ = ["heron", "heron_kahan", "strip_areas", "dissertation_strip_areas", "section_areas", "compensate",
           "station_volumes", "brueckner", "balance_points", "overhaul"]


def heron(a, b, c):
    """Triangle area from its sides, the classic formula sqrt(p (p-a)(p-b)(p-c)) (loses precision on needles)."""
    a, b, c = (np.asarray(v, np.float64) for v in (a, b, c))
    p = (a + b + c) / 2
    return np.sqrt(np.maximum(p * (p - a) * (p - b) * (p - c), 0.0))


def heron_kahan(a, b, c):
    """Triangle area from its sides, Kahan's stable form: sides sorted a >= b >= c,
    A = sqrt((a + (b + c)) (c - (a - b)) (c + (a - b)) (a + (b - c))) / 4; NaN when they form no triangle.

    >>> float(heron_kahan(3, 4, 5)), float(heron_kahan(1e8, 1e8, 1e-3))
    (6.0, 50000.0)
    """
    s = np.sort(np.stack(np.broadcast_arrays(*(np.asarray(v, np.float64) for v in (a, b, c)))), axis=0)[::-1]
    a, b, c = s
    q = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    with np.errstate(invalid="ignore"):
        return np.where(c - (a - b) < 0, np.nan, np.sqrt(np.maximum(q, 0.0)) / 4)


def strip_areas(d0, d1, width) -> tuple[np.ndarray, np.ndarray]:
    """(cut, fill) areas (both >= 0) of strips of ``width`` between offsets with ground - design = d0, d1,
    exact for a straight ground and design line: split where the ground crosses the design.

    >>> strip_areas(1.0, -1.0, 10.0)
    (array(2.5), array(2.5))
    """
    d0, d1, w = (np.asarray(v, np.float64) for v in (d0, d1, width))
    pos0, pos1 = np.maximum(d0, 0), np.maximum(d1, 0)
    neg0, neg1 = np.maximum(-d0, 0), np.maximum(-d1, 0)
    same = (d0 >= 0) == (d1 >= 0)
    total = np.abs(d0) + np.abs(d1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cut = np.where(same, w * (pos0 + pos1) / 2, w * (pos0 + pos1) ** 2 / (2 * np.where(total > 0, total, 1)))
        fill = np.where(same, w * (neg0 + neg1) / 2, w * (neg0 + neg1) ** 2 / (2 * np.where(total > 0, total, 1)))
    return cut, fill


def dissertation_strip_areas(y0, y1, g0, g1, z0, z1, *, stable: bool = True) -> np.ndarray:
    """The dissertation's unsigned strip area: the quad (y0, design) (y1, design) (y1, ground) (y0, ground) in its
    section plane, Delaunay-split into two triangles whose Heron areas are summed (its convex hull when the
    ground crosses the design: too large, and never negative). ``stable``: Kahan's Heron."""
    f = heron_kahan if stable else heron
    p = np.stack([np.stack([y0, z0], -1), np.stack([y1, z1], -1), np.stack([y1, g1], -1), np.stack([y0, g0], -1)], axis=-2)
    from scipy.spatial import ConvexHull

    out = np.zeros(p.shape[:-2])
    flat = p.reshape(-1, 4, 2)
    res = np.zeros(len(flat))
    for i, q in enumerate(flat):
        try:
            hull = q[ConvexHull(q).vertices]
        except Exception:  # degenerate quad (zero area)
            continue
        for k in range(1, len(hull) - 1):
            a = np.linalg.norm(hull[k] - hull[0])
            b = np.linalg.norm(hull[k + 1] - hull[k])
            c = np.linalg.norm(hull[0] - hull[k + 1])
            res[i] += float(np.nan_to_num(f(a, b, c)))
    return res.reshape(out.shape)


def section_areas(offsets: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per station (rows of ``d``, ground - design at ``offsets`` sorted ascending): per-strip (cut, fill) and
    the station's total (cut, fill). NaN strips (no ground) count as 0."""
    y = np.asarray(offsets, np.float64)
    w = np.diff(y)
    cut, fill = strip_areas(d[:, :-1], d[:, 1:], w[None, :])
    cut, fill = np.nan_to_num(cut), np.nan_to_num(fill)
    return cut, fill, cut.sum(axis=1), fill.sum(axis=1)


def compensate(a_cut, a_fill, f_cut: float = 1.0, f_fill: float = 1.0) -> np.ndarray:
    """Net area after transverse compensation: f_cut A_cut - f_fill A_fill (f_cut: swell of the dug
    material, f_fill: its compaction in the fill; the dissertation's "overturned" diagram with factors 1)."""
    if f_cut <= 0 or f_fill <= 0:
        raise InputError(f"cut / fill factors {f_cut}, {f_fill} must be positive", hint=f"e.g. {option('f_cut', 1.2)} {option('f_fill', 1.0)}")
    return f_cut * np.asarray(a_cut, np.float64) - f_fill * np.asarray(a_fill, np.float64)


def station_volumes(x, area) -> tuple[np.ndarray, np.ndarray]:
    """(cut, fill) volumes (>= 0) between consecutive stations from net areas by the average end area;
    where the sign changes the zero is placed linearly (d_S = D A_i / (A_i - A_i+1)).

    >>> station_volumes([0, 20], [30, -10])
    (array([225.]), array([25.]))
    """
    x, a = np.asarray(x, np.float64), np.asarray(area, np.float64)
    D = np.diff(x)
    a0, a1 = a[:-1], a[1:]
    same = (a0 >= 0) == (a1 >= 0)
    cut = np.zeros(len(D))
    fill = np.zeros(len(D))
    both = same & (a0 >= 0)
    cut[both] = D[both] * (a0[both] + a1[both]) / 2
    negs = same & (a0 < 0)
    fill[negs] = -D[negs] * (a0[negs] + a1[negs]) / 2
    ch = ~same
    ds = D[ch] * a0[ch] / (a0[ch] - a1[ch])
    dr = D[ch] - ds
    pos_first = a0[ch] > 0
    cut[ch] = np.where(pos_first, a0[ch] * ds, a1[ch] * dr) / 2
    fill[ch] = -np.where(pos_first, a1[ch] * dr, a0[ch] * ds) / 2
    return cut, fill


def brueckner(x, area) -> np.ndarray:
    """The mass-haul (Brueckner) ordinate: B(x0) = 0, B(x_i+1) = B(x_i) + V_cut - V_fill (rising = cut)."""
    cut, fill = station_volumes(x, area)
    return np.concatenate([[0.0], np.cumsum(cut - fill)])


def balance_points(x, b, level: float = 0.0, *, tol: float = 1e-9) -> np.ndarray:
    """Chainages where B crosses (or touches) the balance line ``level`` (linear between stations)."""
    x, v = np.asarray(x, np.float64), np.asarray(b, np.float64) - level
    scale = max(float(np.max(np.abs(v))), 1.0) * tol
    v = np.where(np.abs(v) <= scale, 0.0, v)
    pts = list(x[v == 0])
    s0, s1 = v[:-1], v[1:]
    cross = (s0 * s1) < 0
    pts += list(x[:-1][cross] + (x[1:] - x[:-1])[cross] * s0[cross] / (s0[cross] - s1[cross]))
    return np.unique(np.round(np.asarray(pts, np.float64), 9))


def overhaul(x, b, free_haul: float) -> dict:
    """Haul moment (m^3 m: area between B and its balance line), mean haul distance and, with a free-haul
    distance, the overhaul: the moment of the hauls longer than ``free_haul`` beyond it (balance-point method,
    between consecutive balance points of B = 0)."""
    x, b = np.asarray(x, np.float64), np.asarray(b, np.float64)
    moment = float(np.sum(np.diff(x) * (np.abs(b[:-1]) + np.abs(b[1:])) / 2))
    total = float(np.sum(np.maximum(np.diff(b), 0)))
    extra = 0.0
    if free_haul and free_haul > 0:
        # per level v, haul length L(v) = chainage span where |B| >= v inside one balanced loop;
        # overhaul = integral over v of max(L(v) - free_haul, 0)
        levels = np.linspace(0, float(np.max(np.abs(b))) if len(b) else 0, 200)[1:]
        dv = levels[1] - levels[0] if len(levels) > 1 else 0.0
        for v in levels:
            above = np.abs(b) >= v
            # runs of consecutive stations above the level
            edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(int), [0]])))
            for s, e in zip(edges[::2], edges[1::2]):
                span = x[e - 1] - x[s]
                extra += max(span - free_haul, 0.0) * dv
    return {"haul_moment": moment, "mean_haul_distance": moment / total if total > 0 else 0.0, "overhaul": extra}
