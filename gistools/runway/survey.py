"""Survey points of a runway: checks, the centre line and the local frame (steps 1-3; reading: gistools.io.survey).

Points have ``id, type, x, y, z``: type 1 a centre-line light, 2 any other point. The
dissertation gives no numeric outlier rule; gistools' (design spec step 1), every threshold
a parameter: exact duplicates (same x, y, z, another id) keep the first; a reused id at
another position is renumbered; lights: perpendicular residual r to the total-least-squares
line, robust z = 0.6745 (r - median r) / MAD, removed while |r| > ``max_offset``, or |z| > ``z_max`` and
|r| > ``min_offset`` (the worst first, the line refitted: a light closer to the line than ``min_offset`` is never
an anomaly, however precise the rest of the survey); light heights: residual to the running median of
height along the chainage (window 5), same robust rule (with ``max_height_step``); other
points: height against the median of their k = 8 nearest neighbours, same robust rule with
``max_height_jump``. Lengths in CRS units (metres for the ICAO template).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import shapely
from scipy.ndimage import median_filter
from scipy.spatial import cKDTree

from ..errors import InputError
from ..parameters import option

__all__ = ["SurveyChecks", "check_survey", "Frame", "fit_frame", "estimate_spacing"]


@dataclass(frozen=True)
class SurveyChecks:
    """Thresholds of the survey checks (CRS units): see the module text."""

    z_max: float = 3.5
    max_offset: float = 1.0
    min_offset: float = 0.1
    max_height_step: float = 0.5
    max_height_jump: float = 1.0
    k: int = 8


def _robust_z(r: np.ndarray) -> np.ndarray:
    med = np.median(r)
    mad = np.median(np.abs(r - med))
    if mad == 0:
        mad = np.mean(np.abs(r - med)) / 0.7979 or 1.0
    return 0.6745 * (r - med) / mad


def _tls_line(x, y):
    """(centroid, unit direction) of the total-least-squares line."""
    c = np.array([x.mean(), y.mean()])
    _, _, vt = np.linalg.svd(np.column_stack([x - c[0], y - c[1]]), full_matrices=False)
    return c, vt[0]


def check_survey(points: pd.DataFrame, checks: SurveyChecks | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(kept points, log): the log lists every removed or renumbered point: id, new_id, type, reason, residual, x, y, z."""
    s = checks or SurveyChecks()
    pts = points.reset_index(drop=True).copy()
    log = []
    # exact duplicates: same x, y, z (and type) under another id
    key = pts[["type", "x", "y", "z"]].round(6)
    dup = key.duplicated(keep="first").to_numpy()
    for i in np.flatnonzero(dup):
        log.append((int(pts.at[i, "id"]), None, int(pts.at[i, "type"]), "duplicate", 0.0))
    pts = pts[~dup].reset_index(drop=True)
    # reused ids at other positions: renumbered
    reused = pts["id"].duplicated(keep="first").to_numpy()
    next_id = int(pts["id"].max()) + 1
    for i in np.flatnonzero(reused):
        log.append((int(pts.at[i, "id"]), next_id, int(pts.at[i, "type"]), "renumbered", 0.0))
        pts.at[i, "id"] = next_id
        next_id += 1
    keep = np.ones(len(pts), bool)
    lights = np.flatnonzero(pts["type"].to_numpy() == 1)
    x, y, z = (pts[c].to_numpy(np.float64) for c in ("x", "y", "z"))
    cx, cy = x[lights].mean(), y[lights].mean()
    active = lights.copy()
    while len(active) > 2:  # lateral anomalies of the lights, worst first, line refitted each time
        c, u = _tls_line(x[active] - cx, y[active] - cy)
        r = (x[active] - cx - c[0]) * u[1] - (y[active] - cy - c[1]) * u[0]
        zr = _robust_z(r)
        k = int(np.argmax(np.abs(zr)))
        if abs(r[k]) <= s.max_offset and (abs(zr[k]) <= s.z_max or abs(r[k]) <= s.min_offset):
            break
        log.append((int(pts.at[active[k], "id"]), None, 1, "light_off_axis", float(r[k])))
        keep[active[k]] = False
        active = np.delete(active, k)
    # light heights against the running median along the axis
    c, u = _tls_line(x[active] - cx, y[active] - cy)
    t = (x[active] - cx) * u[0] + (y[active] - cy) * u[1]
    order = np.argsort(t)
    while len(order) > 4:
        zs = z[active[order]]
        r = zs - median_filter(zs, size=5, mode="nearest")
        zr = _robust_z(r)
        k = int(np.argmax(np.abs(zr)))
        if abs(zr[k]) <= s.z_max or abs(r[k]) <= s.max_height_step:
            break
        log.append((int(pts.at[active[order[k]], "id"]), None, 1, "light_height", float(r[k])))
        keep[active[order[k]]] = False
        order = np.delete(order, k)
    # other points: height against the median of the k nearest others
    others = np.flatnonzero(pts["type"].to_numpy() == 2)
    if len(others) > s.k + 1:
        tree = cKDTree(np.column_stack([x[others] - cx, y[others] - cy]))
        _, nb = tree.query(np.column_stack([x[others] - cx, y[others] - cy]), s.k + 1)
        r = z[others] - np.median(z[others][nb[:, 1:]], axis=1)
        zr = _robust_z(r)
        bad = (np.abs(zr) > s.z_max) & (np.abs(r) > s.max_height_jump)
        for i in np.flatnonzero(bad):
            log.append((int(pts.at[others[i], "id"]), None, 2, "ground_height", float(r[i])))
            keep[others[i]] = False
    logdf = pd.DataFrame(log, columns=["id", "new_id", "type", "reason", "residual"])
    return pts[keep].reset_index(drop=True), logdf


@dataclass
class Frame:
    """The runway's local frame: chainage along the centre line from ``origin``, signed offset (left +)."""

    line: shapely.LineString  # the centre line through the lights, in CRS coordinates, from chainage 0
    chain: np.ndarray  # chainage of the lights (sorted)
    z_cl: np.ndarray  # light heights at those chainages
    bearing: float  # grid bearing of the axis, degrees clockwise from north (chainage direction)

    def _arrays(self):
        cache = self.__dict__.get("_cache")
        if cache is None:
            v = shapely.get_coordinates(self.line)
            seg = np.diff(v, axis=0)
            length = np.hypot(seg[:, 0], seg[:, 1])
            u = seg / length[:, None]
            start = np.concatenate([[0.0], np.cumsum(length)])
            axis = (v[-1] - v[0]) / np.linalg.norm(v[-1] - v[0])
            along = (v - v[0]) @ axis
            cache = self.__dict__["_cache"] = (v, u, length, start, axis, along)
        return cache

    def local(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(chainage, offset) of points; offsets positive to the left of the direction of increasing chainage.
        Beyond the ends the end segments are extended (chainage < 0 or > length)."""
        v, u, length, start, axis, along = self._arrays()
        p = np.column_stack([np.asarray(x, np.float64), np.asarray(y, np.float64)])
        m = len(u)
        t = (p - v[0]) @ axis
        guess = np.clip(np.searchsorted(along, t) - 1, 0, m - 1)
        best_d = np.full(len(p), np.inf)
        ch = np.zeros(len(p))
        off = np.zeros(len(p))
        for k in (-1, 0, 1):  # the segment under the point's axis position and its neighbours
            s_ = np.clip(guess + k, 0, m - 1)
            rel = p - v[s_]
            lam = np.einsum("ij,ij->i", rel, u[s_])
            lo = np.where(s_ == 0, -np.inf, 0.0)
            hi = np.where(s_ == m - 1, np.inf, length[s_])
            lam_c = np.clip(lam, lo, hi)
            foot = v[s_] + lam_c[:, None] * u[s_]
            d = np.hypot(p[:, 0] - foot[:, 0], p[:, 1] - foot[:, 1])
            better = d < best_d
            best_d[better] = d[better]
            ch[better] = start[s_][better] + lam_c[better]
            off[better] = (u[s_, 0] * rel[:, 1] - u[s_, 1] * rel[:, 0])[better]
        return ch, off

    def world(self, chain, offset) -> tuple[np.ndarray, np.ndarray]:
        """CRS (x, y) of local (chainage, offset)."""
        v, u, length, start, axis, along = self._arrays()
        ch = np.asarray(chain, np.float64)
        s_ = np.clip(np.searchsorted(start, ch, side="right") - 1, 0, len(u) - 1)
        foot = v[s_] + (ch - start[s_])[:, None] * u[s_]
        off = np.asarray(offset, np.float64)
        return foot[:, 0] - u[s_, 1] * off, foot[:, 1] + u[s_, 0] * off

    def z_centre(self, chain) -> np.ndarray:
        """Centre-line height at chainages: linear between lights, constant beyond the ends."""
        return np.interp(np.asarray(chain, np.float64), self.chain, self.z_cl)


def fit_frame(points: pd.DataFrame, *, origin: str = "low", profile_window: int = 1) -> Frame:
    """The centre line from the surviving lights (step 2): ordered by their projection on the principal axis,
    joined into a line. ``origin``: chainage 0 at the "low" end (the lower light height, the dissertation's
    reading), the "high" end, or "first" (the first light of the file). ``profile_window``: the centre-line
    height profile is the running mean of this many lights (odd; 1 = the lights' own heights, the
    dissertation's), which keeps the survey noise of single lights out of the design grade."""
    lights = points[points["type"] == 1]
    x, y, z = (lights[c].to_numpy(np.float64) for c in ("x", "y", "z"))
    cx, cy = x.mean(), y.mean()
    c, u = _tls_line(x - cx, y - cy)
    t = (x - cx) * u[0] + (y - cy) * u[1]
    order = np.argsort(t)
    x, y, z, t = x[order], y[order], z[order], t[order]
    if origin == "low":
        flip = z[-1] < z[0]
    elif origin == "high":
        flip = z[-1] > z[0]
    elif origin == "first":
        flip = order[0] != 0 and order[-1] == 0
    else:
        raise InputError(f"origin {origin!r} is not low, high or first")
    if flip:
        x, y, z = x[::-1], y[::-1], z[::-1]
    line = shapely.LineString(np.column_stack([x, y]))
    chain = shapely.line_locate_point(line, shapely.points(x, y))
    w = int(profile_window)
    if w < 1 or w % 2 == 0:
        raise InputError(f"profile window {w} must be an odd number >= 1", hint=f"e.g. {option('profile_window', 5)}")
    if w > 1 and len(z) >= 3:
        h = w // 2
        # symmetric windows, shrinking at the ends: a straight grade stays exactly straight
        zs = np.empty_like(z)
        for i in range(len(z)):
            k = min(h, i, len(z) - 1 - i)
            zs[i] = z[i - k:i + k + 1].mean()
        z = zs
    dx, dy = x[-1] - x[0], y[-1] - y[0]
    bearing = float(np.degrees(np.arctan2(dx, dy)) % 360)
    return Frame(line, chain, z, bearing)


def estimate_spacing(chain: np.ndarray, offset: np.ndarray) -> float:
    """The survey's point spacing s = sqrt(A / N) (step 3), A the area of the points' hull in the local frame."""
    hull = shapely.convex_hull(shapely.multipoints(np.column_stack([chain, offset])))
    return float(np.sqrt(hull.area / len(chain))) if len(chain) else float("nan")
