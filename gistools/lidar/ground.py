"""Ground points: the Simple Morphological Filter (SMRF; Pingel, Clarke & McBride 2013), as PDAL ``filters.smrf``.

Pure functions over coordinate arrays. Lengths are in CRS units (x, y) and the vertical unit (z); the
caller converts the metre defaults (``products.ground``). The steps, as in the paper and PDAL:

1. ZImin: the lowest point of each cell (on the absolute lattice of ``cell``: a tile with a buffer of its
   neighbours has the cells of the merged tiles), empty cells inpainted;
2. low outliers: the filter on the inverted surface (slope 5, window 1 cell);
3. objects: the progressive morphological filter, openings by a diamond of radius 1 ... window / cell, a cell is an
   object when the surface drops by more than slope x cell x radius at one step;
4. ZIpro: ZImin without objects and low cells, inpainted; a point is ground when it lies within
   ``threshold + scalar x slope of ZIpro`` of ZIpro (bilinear at the point); the adaptive method's ground reaches
   ``below`` (3) such thresholds under it: the surfaces drawn between the lowest returns of a sparsely sampled,
   rough floor pass above its hollows, and points far below the terrain are the noise step's.

The smrftin method (``smrftin_params``: 1.5 m cells, no mean-surface pass) adds two steps: the candidates measured
again against a TIN of the ground found (one step of Axelsson's densification), and ``raised_patches``: ground
patches standing above all around them (roofs, decks) removed.

Empty cells are filled by the mean of their filled 3 x 3 neighbours, grown ring by ring (deterministic,
so a tiled run equals a merged one; PDAL averages the 8 nearest filled cells, whose ties depend on
the extent), and, past ``FILL_RINGS`` rings, by the nearest filled cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from .. import kernel
from ..parameters import choices, default_for
from ..units import METRE, LinearUnit, length_to_crs_units

__all__ = ["SmrfParams", "smrftin_params", "adaptive_params", "for_data", "TIN_METHODS",
           "canopy_cell", "survey_returns", "survey_density",
           "CsfParams", "NoiseParams", "smrf_ground", "csf_ground", "classify_ground_and_noise", "fill_gaps",
           "progressive_filter", "min_surface", "raised_patches", "GROUND_METHODS", "ground_candidates", "plane_residuals",
           "noise_histogram", "noise_from_histogram", "for_noise", "survey_noise_histogram", "noise_stride",
           "NoiseBlocks", "too_few_in_blocks"]

FILL_RINGS = 32


def _metres(name: str) -> float:
    """The declared default of length parameter ``name`` (gistools.parameters.lidar) in metres."""
    return length_to_crs_units(default_for(name), LinearUnit("metre", METRE), name=name)


@dataclass(frozen=True)
class SmrfParams:
    """SMRF parameters in the data's units: ``cell``, ``window`` in CRS units; ``threshold``, ``scalar`` in the
    vertical unit; ``slope`` dimensionless (rise over run in true lengths); ``z_per_xy``: vertical units per CRS
    unit of the same length (1 when both are metres or both feet). The defaults are gistools ground's
    (gistools.parameters.lidar), for data in metres."""

    cell: float = _metres("cell")
    slope: float = default_for("slope")
    window: float = _metres("window")
    threshold: float = _metres("threshold")
    scalar: float = _metres("scalar")
    z_per_xy: float = 1.0
    refine: bool = True  # measure the points again against the mean of the ground found (see smrf_ground)
    tin: bool = False  # then against a TIN of the ground found (the smrftin method, see smrf_ground)
    step: float = 0.0  # smrftin: a height step above this (vertical units per cell) parts ground patches; 0: none
    patch: float = 0.0  # smrftin: raised ground patches narrower than this (CRS units) are removed; 0: none
    noise_band: tuple = ()  # smrftin: (precise, noisy) ground noise (vertical units) of the threshold scale; (): fixed
    tight: tuple = ()  # smrftin: (threshold, scalar, slope) for ground noise at or below noise_band[0]
    noise: float | None = None  # smrftin: the ground noise measured on the run's points (None: measure it here)
    canopy: tuple = ()  # adaptive under a canopy, data's units: cell, threshold, scalar, slope, the last returns per
    # square CRS unit at which the cell stays, the smallest cell (canopy_set); (): none
    multi: float | None = None  # adaptive: the survey's share of multi-return points (None: measure it on the points)
    density: float | None = None  # adaptive: the survey's last returns per square CRS unit (None: measure it)
    below: float = 1.0  # a candidate this many thresholds below the surface is still ground (1: SMRF's |dz|)


def smrftin_params(**lengths) -> SmrfParams:
    """The smrftin method's parameters (SMRF, then the TIN of its ground) with its declared defaults, for data in
    metres; ``lengths`` override them in the data's units (as SmrfParams' fields)."""
    base = dict(cell=_metres("smrftin_cell"), slope=default_for("smrftin_slope"), window=_metres("smrftin_window"),
                threshold=_metres("smrftin_threshold"), scalar=_metres("smrftin_scalar"), refine=False, tin=True,
                step=_metres("smrftin_step"), patch=_metres("smrftin_patch"), noise_band=NOISE_BAND_M,
                tight=TIGHT_M)
    base.update(lengths)
    return SmrfParams(**base)


def adaptive_params(**lengths) -> SmrfParams:
    """The adaptive method's parameters: smrftin's (``smrftin_params``, ``lengths`` override them) and the set it
    takes under a canopy (CANOPY_M, CANOPY_DENSITY_M2, CANOPY_MIN_CELL_M; in the data's units through ``canopy``)."""
    lengths.setdefault("canopy", (*CANOPY_M, CANOPY_DENSITY_M2, CANOPY_MIN_CELL_M))
    lengths.setdefault("below", BELOW_THRESHOLDS)
    return smrftin_params(**lengths)


NOISE_BAND_M = (0.025, 0.045)  # smrftin: ground noise (m) below which its thresholds are the tight set, above: its own
TIGHT_M = (0.05, 0.2, 0.1)  # smrftin on a precise survey: threshold (m), scalar (m), slope (smrf's)
CANOPY_M = (1.75, 0.05, 0.2, 0.1)  # adaptive under a canopy: cell (m), threshold (m), scalar (m), slope
BELOW_THRESHOLDS = 3.0  # adaptive: ground reaches this many thresholds below its surface (see smrf_ground)
CANOPY_SHARE = 0.10  # a survey records a canopy when at least this share of its points are of multi-return pulses
CANOPY_DENSITY_M2 = 3.2  # last returns per m2 up to which the canopy set keeps its 1.75 m cells (about 10 a cell) ...
CANOPY_MIN_CELL_M = 0.5  # ... beyond, cells as wide as hold as many, down to this
DENSITY_CELL_M = 25.0  # the survey's area for its density: the cells of this side (m) that hold a point
NOISE_SIGMAS = 4.0  # smrftin's threshold is at least this many times the ground noise
NOISE_BIN_M = 0.001  # the ground noise is measured in steps of 1 mm ...
NOISE_BINS = 1000  # ... up to 1 m (larger residuals count in one last bin)


def min_surface(x, y, z, cell: float):
    """(ZImin with NaN where empty, col0, row_top, flat cell of each point): the lowest z per cell of the
    lattice of multiples of ``cell`` covering the points; row 0 is the north."""
    col0 = math.floor(float(np.min(x)) / cell)
    row_top = math.floor(float(np.max(y)) / cell) + 1
    width = math.floor(float(np.max(x)) / cell) - col0 + 1
    height = row_top - math.floor(float(np.min(y)) / cell)
    col = np.floor(x / cell).astype(np.int64) - col0
    row = row_top - 1 - np.floor(y / cell).astype(np.int64)
    flat = row * width + col
    zmin = np.full(width * height, np.inf)
    if _CELL_MIN is not None:
        _CELL_MIN(len(flat), np.ascontiguousarray(flat, np.int64), np.ascontiguousarray(z, np.float64), zmin)
    else:
        np.minimum.at(zmin, flat, z)
    zmin[np.isinf(zmin)] = np.nan
    return zmin.reshape(height, width), col0, row_top, flat


def fill_gaps(surface: np.ndarray, rings: int = FILL_RINGS) -> np.ndarray:
    """NaN cells filled by the mean of their filled 3 x 3 neighbours, one ring at a time (each ring from the values
    before it); past ``rings`` rings (wide gaps: water, large buildings), by the nearest filled cell. Work goes
    to the cells on the front of each ring only."""
    z = np.ascontiguousarray(surface, np.float64).copy()
    empty = np.isnan(z)
    if not empty.any() or empty.all():
        return z
    if _FILL_FRONT is not None:  # ring by ring over each ring's front only
        cap = int(np.count_nonzero(empty))
        _FILL_FRONT(z, z.shape[0], z.shape[1], int(rings), cap, np.empty(2 * cap, np.int64), np.empty(z.size, np.uint8),
                    np.empty(cap))
    elif _FILL is not None:
        _FILL(z, np.empty_like(z), z.shape[0], z.shape[1], int(rings))
    else:
        z = _fill_rings_numpy(z, rings)
    empty = np.isnan(z)
    if empty.any():
        _, (ri, ci) = ndimage.distance_transform_edt(empty, return_indices=True)
        z[empty] = z[ri[empty], ci[empty]]
    return z


def _fill_rings_numpy(z: np.ndarray, rings: int) -> np.ndarray:
    """fill_gaps' rings without the compiled kernel (the same sums in the same order)."""
    h, w = z.shape
    wp = w + 2
    flat = np.full((h + 2) * wp, np.nan)
    flat.reshape(h + 2, wp)[1:-1, 1:-1] = z
    inside = np.zeros((h + 2, wp), bool)
    inside[1:-1, 1:-1] = True
    inside = inside.ravel()
    offsets = np.array([-wp - 1, -wp, -wp + 1, -1, 1, wp - 1, wp, wp + 1])
    filled = ~np.isnan(flat) & inside
    # the first front: empty cells next to a filled one
    front = np.flatnonzero(~filled & inside)
    for _ in range(rings):
        if front.size == 0:
            break
        vals = flat[front[:, None] + offsets]
        ok = ~np.isnan(vals)
        count = ok.sum(axis=1)
        new = count > 0
        if not new.any():
            break
        cells = front[new]
        total = np.zeros(len(cells))
        for j in range(8):  # in the kernel's order, one neighbour at a time: the same rounding
            total += np.where(ok[new, j], vals[new, j], 0.0)
        flat[cells] = total / count[new]
        near = np.unique((cells[:, None] + offsets).ravel())
        front = near[inside[near] & np.isnan(flat[near])]
    return flat.reshape(h + 2, wp)[1:-1, 1:-1].copy()


_CROSS = kernel.function("gt_cross_filter")
_FILL = kernel.function("gt_fill_rings")
_PROGRESSIVE = kernel.function("gt_progressive")
_CELL_MIN = kernel.function("gt_cell_min")
_FILL_FRONT = kernel.function("gt_fill_front")
_BILINEAR = kernel.function("gt_bilinear")
_SLOPE_THRESHOLD = kernel.function("gt_slope_threshold")
_CELL_MEAN = kernel.function("gt_cell_mean")


def cross_filter(a: np.ndarray, iterations: int, maximum: bool) -> np.ndarray:
    """``iterations`` grey dilations (``maximum``) or erosions by the 4-neighbour cross: the filter by a diamond of
    that radius. The compiled kernel when built (one pass a step), else numpy (the same values)."""
    a = np.ascontiguousarray(a, np.float64)
    if _CROSS is not None:
        out, work = np.empty_like(a), np.empty_like(a)
        _CROSS(a, out, work, a.shape[0], a.shape[1], 1 if maximum else 0, int(iterations))
        return out
    step = _dilate1 if maximum else _erode1
    for _ in range(iterations):
        a = step(a)
    return a


def _cross1(a: np.ndarray, op) -> np.ndarray:
    """``op`` (np.minimum: grey erosion, np.maximum: dilation) over the 4-neighbour cross (a diamond of radius 1);
    edges use the neighbours they have."""
    out = a.copy()
    op(out[1:], a[:-1], out=out[1:])
    op(out[:-1], a[1:], out=out[:-1])
    op(out[:, 1:], a[:, :-1], out=out[:, 1:])
    op(out[:, :-1], a[:, 1:], out=out[:, :-1])
    return out


def _erode1(a: np.ndarray) -> np.ndarray:
    return _cross1(a, np.minimum)


def _dilate1(a: np.ndarray) -> np.ndarray:
    return _cross1(a, np.maximum)


def progressive_filter(surface: np.ndarray, cell: float, slope_z: float, window: float) -> np.ndarray:
    """Object cells of the progressive morphological filter: openings by diamonds of radius 1 ... ceil(window /
    cell) cells; a cell is an object when the opened surface drops by more than ``slope_z`` x cell x radius
    (vertical units) from the previous one (PDAL's progressiveFilter)."""
    # from a radius of rows + cols the diamond covers the grid from every cell: every opening is the grid's minimum,
    # the same as the one before, and no cell changes; larger radii are not run (the same objects, bounded work)
    max_radius = min(int(math.ceil(window / cell)), surface.shape[0] + surface.shape[1])
    if _PROGRESSIVE is not None:
        z = np.ascontiguousarray(surface, np.float64)
        obj = np.zeros(z.shape, np.uint8)
        _PROGRESSIVE(z, obj, np.empty(4 * z.size), z.shape[0], z.shape[1], float(cell), float(slope_z), max_radius)
        return obj.view(bool)
    obj = np.zeros(surface.shape, bool)
    previous, erosion = surface, surface
    for radius in range(1, max_radius + 1):
        erosion = cross_filter(erosion, 1, maximum=False)  # erosion by the diamond of this radius
        opening = cross_filter(erosion, radius, maximum=True)
        obj |= (previous - opening) > slope_z * cell * radius
        previous = opening
    return obj


def _bilinear_at(shape, u: np.ndarray, v: np.ndarray):
    """Where fractional (col, row) positions (u = col + 0.5 at a cell centre) fall between cell centres, clamped:
    (flat index of the upper-left centre, the step to the next column, to the next row, the two fractions)."""
    h, w = shape
    fu = np.clip(u - 0.5, 0, w - 1)
    fv = np.clip(v - 0.5, 0, h - 1)
    c0 = np.minimum(fu.astype(np.int64), max(w - 2, 0))  # fu >= 0: the cast is the floor
    r0 = np.minimum(fv.astype(np.int64), max(h - 2, 0))
    tu, tv = fu - c0, fv - r0
    return r0 * w + c0, (1 if w > 1 else 0), (w if h > 1 else 0), tu, tv


def _bilinear(surface: np.ndarray, at) -> np.ndarray:
    """``surface`` at the positions of ``_bilinear_at``."""
    i, dc, dr, tu, tv = at
    f = surface.ravel()
    top = f[i] * (1 - tu) + f[i + dc] * tu
    bottom = f[i + dr] * (1 - tu) + f[i + dr + dc] * tu
    return top * (1 - tv) + bottom * tv


class _Points:
    """Surfaces of one lattice (col0, row_top, cell) sampled at the points: the compiled kernel when built, else
    numpy (the same operations in the same order)."""

    def __init__(self, x, y, cell: float, col0: int, row_top: int, shape):
        self.x, self.y, self.cell, self.col0, self.row_top, self.shape = x, y, cell, col0, row_top, shape
        self.at = None if _BILINEAR is not None else _bilinear_at(shape, x / cell - col0, row_top - y / cell)

    def sample(self, surface: np.ndarray) -> np.ndarray:
        if self.at is not None:
            return _bilinear(surface, self.at)
        out = np.empty(len(self.x))
        _BILINEAR(np.ascontiguousarray(surface, np.float64), self.shape[0], self.shape[1], len(self.x), self.x, self.y,
                  float(self.cell), int(self.col0), int(self.row_top), out)
        return out


def slope_threshold(zipro: np.ndarray, p: "SmrfParams") -> np.ndarray:
    """Per-cell SMRF threshold (vertical units): threshold + scalar x the surface's slope (true rise over run)."""
    if _SLOPE_THRESHOLD is not None:
        out = np.empty_like(zipro)
        _SLOPE_THRESHOLD(np.ascontiguousarray(zipro, np.float64), zipro.shape[0], zipro.shape[1], float(p.cell),
                         float(p.z_per_xy), float(p.threshold), float(p.scalar), out)
        return out
    # np.gradient refuses an axis of one cell: no slope along it, as the kernel has it
    gy = np.gradient(zipro, p.cell, axis=0) if zipro.shape[0] > 1 else np.zeros_like(zipro)
    gx = np.gradient(zipro, p.cell, axis=1) if zipro.shape[1] > 1 else np.zeros_like(zipro)
    grade = np.sqrt(gx * gx + gy * gy) / p.z_per_xy  # true rise over run (as the kernel computes it)
    return p.threshold + p.scalar * grade


def cell_mean(flat: np.ndarray, z: np.ndarray, on: np.ndarray, size: int) -> np.ndarray:
    """Mean z of the points ``on`` in each of ``size`` cells (flat index per point), NaN where none."""
    if _CELL_MEAN is not None:
        out = np.empty(size)
        _CELL_MEAN(len(flat), np.ascontiguousarray(flat, np.int64), np.ascontiguousarray(z, np.float64),
                   np.ascontiguousarray(on, np.uint8), size, np.empty(size), np.empty(size, np.int64), out)
        return out
    total = np.bincount(flat[on], weights=z[on], minlength=size)
    count = np.bincount(flat[on], minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def smrf_ground(x, y, z, candidates: np.ndarray, p: SmrfParams) -> tuple[np.ndarray, np.ndarray]:
    """(ground, provisional DEM at each point): ``ground`` True for the ``candidates`` (e.g. last and only returns,
    not noise) within the threshold of ZIpro; the DEM (vertical units) for every point, for noise rules."""
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    ground = np.zeros(len(x), bool)
    if not candidates.any():
        return ground, np.full(len(x), np.nan)
    cx, cy, cz = x[candidates], y[candidates], z[candidates]
    zimin, col0, row_top, cell_of = min_surface(cx, cy, cz, p.cell)
    zimin = fill_gaps(zimin)
    slope_z = p.slope * p.z_per_xy
    low = progressive_filter(-zimin, p.cell, 5.0 * p.z_per_xy, p.cell)
    obj = progressive_filter(zimin, p.cell, slope_z, p.window)
    zipro = zimin.copy()
    zipro[obj | low] = np.nan
    zipro = fill_gaps(zipro)
    thresh = slope_threshold(zipro, p)
    at = _Points(x, y, p.cell, col0, row_top, zipro.shape)
    dem = at.sample(zipro)
    cell_thresh = at.sample(thresh)
    dz0 = cz - dem[candidates]
    ground[candidates] = (dz0 <= cell_thresh[candidates]) & (dz0 >= -p.below * cell_thresh[candidates])
    if p.refine and ground.any():
        # ZIpro is a surface of cell minima, below the mean ground by about two noise deviations: the
        # upper half of noisy ground returns falls outside a tight threshold. Measure again against
        # the mean of the ground points found (ZIfin, Pingel's final surface), inpainted the same way.
        zifin = fill_gaps(cell_mean(cell_of, cz, ground[candidates], zimin.size).reshape(zimin.shape))
        dem = at.sample(zifin)
        ground[candidates] = np.abs(cz - dem[candidates]) <= cell_thresh[candidates]
    if p.tin and np.count_nonzero(ground) >= 3:
        # smrftin: a lattice blurs ridges, terrace edges and steep slopes by up to a cell; a TIN of the ground
        # found follows them. Its vertices keep their class (each is its own height there); the other
        # candidates within the same slope-scaled threshold of the TIN join the ground (Axelsson's
        # densification, one step, the threshold as the iteration distance).
        from .tin import tin_at_points

        cand = np.flatnonzero(candidates)
        open_ = ~ground[cand] & (np.abs(cz - dem[cand]) <= TIN_REACH * cell_thresh[cand])
        ask = cand[open_]
        # the TIN of the ground in the cells around those points only (its triangles there are the same)
        near = np.zeros(zimin.size, bool)
        near[cell_of[open_]] = True
        near = ndimage.maximum_filter(near.reshape(zimin.shape), size=2 * TIN_RING + 1, mode="constant").ravel()
        g = cand[ground[cand] & near[cell_of]]
        zt = tin_at_points(x[g], y[g], z[g], x[ask], y[ask]) if len(g) >= 3 else np.full(len(ask), np.nan)
        inside = np.isfinite(zt)
        d = np.where(inside, z[ask] - zt, z[ask] - dem[ask])
        ground[ask] = (d <= cell_thresh[ask]) & (d >= -p.below * cell_thresh[ask])
        dem = dem.copy()
        dem[ask[inside]] = zt[inside]
    if p.step > 0 and p.patch > 0 and ground.any():
        ground &= ~raised_patches(x, y, z, ground, PATCH_CELL * p.cell, PATCH_CELL * p.step, p.patch)
    return ground, dem


PATCH_REACH = 2  # patch cells: ground cells this far apart (a wall's empty cells between) are neighbours
PATCH_CELL = 1.5  # patch cells are this many SMRF cells
TIN_REACH = 5.0  # smrftin's TIN step tests the points within this many thresholds of the lattice surface
TIN_RING = 2  # cells: the TIN is built of the ground points this near to a tested point's cell
PATCH_FLOOR = 100  # cells: a lower patch smaller than this (low points, a pit) does not vote


def raised_patches(x, y, z, ground: np.ndarray, cell: float, step: float, patch: float) -> np.ndarray:
    """The ground points of patches standing above every ground around them: roofs and decks the morphological
    filter kept (buildings wider than its window, buildings at the data's edge, bridges).

    The lowest ground point of each cell of ``cell`` (absolute lattice); cells up to PATCH_REACH cells apart are
    one patch when their heights differ by at most ``step`` per cell of distance (the terrain's slopes join,
    walls part). A patch narrower than ``patch`` (CRS units, its longest side) is an object when at least 90 %
    of its height differences with the patches around it (cell pairs within reach, at least 8) go down, counting
    only neighbours of PATCH_FLOOR cells or more or as wide as ``patch`` (low points do not make a roof of the
    terrain). Terraces and embankments join the terrain on one side or along their length, so they stay.
    Tiled == merged when the buffer exceeds twice ``patch`` plus the ground filter's own reach."""
    out = np.zeros(len(x), bool)
    gi = np.flatnonzero(ground)
    if len(gi) < 3:
        return out
    zimin, _col0, _row_top, flat = min_surface(x[gi], y[gi], z[gi], cell)
    if _RAISED is not None:  # one compiled pass (union-find), the same cells as the numpy form
        zc = np.ascontiguousarray(zimin, np.float64)
        cell_roof = np.empty(zc.size, np.uint8)
        _RAISED(zc, zc.shape[0], zc.shape[1], PATCH_REACH, float(step), float(cell), float(patch), PATCH_FLOOR,
                np.empty(8 * zc.size, np.int64), cell_roof)
        cell_roof = cell_roof.view(bool)
    else:
        cell_roof = _raised_cells_numpy(zimin, cell, step, patch)
    out[gi[cell_roof[flat]]] = True
    return out


_RAISED = kernel.function("gt_raised_patches")


def _raised_cells_numpy(zimin: np.ndarray, cell: float, step: float, patch: float) -> np.ndarray:
    """raised_patches' cells without the compiled kernel (scipy's connected components; the same comparisons)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    h, w = zimin.shape
    zc = zimin.ravel()
    ids = np.flatnonzero(np.isfinite(zc))
    rr, cc = np.divmod(ids, w)
    pos = np.full(zc.size, -1, np.int64)
    pos[ids] = np.arange(len(ids))
    a_list, b_list, dz_list, dist_list = [], [], [], []
    reach = PATCH_REACH
    for dr in range(0, reach + 1):
        for dc in range(-reach, reach + 1):
            if dr == 0 and dc <= 0:
                continue
            r2, c2 = rr + dr, cc + dc
            ok = (r2 < h) & (c2 >= 0) & (c2 < w)
            a, b = ids[ok], r2[ok] * w + c2[ok]
            keep = pos[b] >= 0
            a, b = a[keep], b[keep]
            a_list.append(pos[a])
            b_list.append(pos[b])
            dz_list.append(zc[a] - zc[b])
            dist_list.append(np.full(len(a), math.sqrt(dr * dr + dc * dc)))
    a, b, dz, dist = (np.concatenate(v) for v in (a_list, b_list, dz_list, dist_list))
    joined = np.abs(dz) <= step * dist
    graph = coo_matrix((np.ones(int(joined.sum())), (a[joined], b[joined])), shape=(len(ids), len(ids)))
    n, label = connected_components(graph, directed=False)
    size = np.bincount(label, minlength=n)
    lo_c = np.full(n, np.iinfo(np.int64).max)
    hi_c = np.full(n, np.iinfo(np.int64).min)
    lo_r, hi_r = lo_c.copy(), hi_c.copy()
    np.minimum.at(lo_c, label, cc)
    np.maximum.at(hi_c, label, cc)
    np.minimum.at(lo_r, label, rr)
    np.maximum.at(hi_r, label, rr)
    extent = np.maximum(hi_c - lo_c, hi_r - lo_r) * cell
    la, lb = label[a], label[b]
    higher = np.where(dz > 0, la, lb)
    lower = np.where(dz > 0, lb, la)
    vote = (la != lb) & ((size[lower] >= PATCH_FLOOR) | (extent[lower] >= patch))
    down = np.bincount(higher[vote], minlength=n)
    up = np.bincount(lower[vote], minlength=n)
    total = down + up
    roof = (total >= 8) & (down >= 0.9 * total) & (extent < patch)
    cell_roof = np.zeros(zc.size, bool)
    cell_roof[ids[roof[label]]] = True
    return cell_roof


def plane_residuals(x, y, z) -> np.ndarray:
    """Each point's height above the least-squares plane through its Delaunay neighbours, itself left out (vertical
    units): the ground's noise where the points are ground. A point of the convex hull leaves out one hull
    neighbour. NaN where a point is in no triangle (a repeated position) or its neighbours do not span a plane.
    One compiled pass where the kernel is built, else numpy: the same float64 operations either way."""
    from .tin import delaunay_triangles

    x, y, z = (np.ascontiguousarray(a, np.float64) for a in (x, y, z))
    n = len(x)
    out = np.full(n, np.nan)
    tris = delaunay_triangles(x, y) if n >= 3 else np.empty((0, 3), np.int32)
    if len(tris) == 0:
        return out
    if _PLANE_RESIDUALS is not None:
        _PLANE_RESIDUALS(n, x, y, z, len(tris), np.ascontiguousarray(tris, np.int32), np.empty(9 * n), out)
        return out
    return _plane_residuals_numpy(x, y, z, tris, out)


_PLANE_RESIDUALS = kernel.function("gt_plane_residuals")


def _plane_residuals_numpy(x, y, z, tris: np.ndarray, out: np.ndarray) -> np.ndarray:
    n = len(x)
    t = tris.astype(np.int64)
    area = ((x[t[:, 1]] - x[t[:, 0]]) * (y[t[:, 2]] - y[t[:, 0]])
            - (x[t[:, 2]] - x[t[:, 0]]) * (y[t[:, 1]] - y[t[:, 0]]))
    t[area > 0] = t[area > 0][:, [0, 2, 1]]  # every triangle clockwise: an inner edge is i -> j in one, j -> i in the other
    a, b = t.ravel(), t[:, [1, 2, 0]].ravel()  # each vertex's edges to all its neighbours (on the hull: all but one)
    dx, dy, dz = x[b] - x[a], y[b] - y[a], z[b] - z[a]

    def total(w=None):
        return np.bincount(a, weights=w, minlength=n)

    s1, sx, sy, sz = total(), total(dx), total(dy), total(dz)
    sxx, sxy, syy, sxz, syz = total(dx * dx), total(dx * dy), total(dy * dy), total(dx * dz), total(dy * dz)
    minor = sxx * syy - sxy * sxy
    det = s1 * minor - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy)
    det0 = sz * minor - sx * (sxz * syy - sxy * syz) + sy * (sxz * sxy - sxx * syz)
    ok = (s1 >= 3) & (np.abs(det) > 1e-9 * np.maximum(s1 * sxx * syy, 1e-300))
    out[ok] = -det0[ok] / det[ok]  # the plane's height at the point is z + det0 / det
    return out


def noise_histogram(residuals: np.ndarray, z_metres: float) -> np.ndarray:
    """Counts of |residual| in NOISE_BINS steps of NOISE_BIN_M (the last bin: everything beyond); NaN left out.
    Tiles' histograms add up to the merged points' one, so the median is the same however the data are tiled."""
    r = np.abs(residuals[np.isfinite(residuals)]) * z_metres
    return np.bincount(np.minimum((r / NOISE_BIN_M).astype(np.int64), NOISE_BINS), minlength=NOISE_BINS + 1)


def noise_from_histogram(counts: np.ndarray, z_metres: float) -> float | None:
    """The ground noise (vertical units): 1.4826 x the median |residual| (the standard deviation of a normal noise,
    robust to the low vegetation some ground points are), None with fewer than 30 residuals."""
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    if total < 30:
        return None
    k = int(np.searchsorted(np.cumsum(counts), (total + 1) / 2))
    return 1.4826 * (k + 0.5) * NOISE_BIN_M / z_metres


def for_noise(p: SmrfParams, noise: float | None) -> SmrfParams:
    """smrftin's parameters for ground of this noise (vertical units): its tight set up to ``noise_band[0]``, its
    own thresholds, scalar and slope from ``noise_band[1]`` on, linear between, the threshold never below
    NOISE_SIGMAS x the noise; its own when the noise is unknown."""
    if not p.noise_band or noise is None:
        return replace(p, noise_band=(), noise=noise)
    lo, hi = p.noise_band
    f = min(1.0, max(0.0, (noise - lo) / (hi - lo)))
    t_thr, t_scalar, t_slope = p.tight
    threshold = max(t_thr + f * (p.threshold - t_thr), NOISE_SIGMAS * noise)  # never inside the ground's own noise
    return replace(p, threshold=threshold, scalar=t_scalar + f * (p.scalar - t_scalar),
                   slope=t_slope + f * (p.slope - t_slope), noise_band=(), noise=noise)


def canopy_cell(canopy: tuple, density: float | None) -> float:
    """The canopy set's cell (CRS units) for a survey of ``density`` last returns per square CRS unit: its own up
    to the density of ``canopy`` (about 10 last returns a cell), then as wide as holds as many, down to its smallest.
    The lowest of more returns a cell lies lower in their noise (by about 2.4 sigma among 16), and a 5 cm threshold
    around it would keep only the lowest ground returns of a dense survey."""
    cell, _threshold, _scalar, _slope, reference, smallest = canopy
    if not density or density <= reference:
        return cell
    return max(smallest, cell * math.sqrt(reference / density))


def for_data(p: SmrfParams, noise: float | None, multi: float | None, density: float | None = None) -> SmrfParams:
    """smrftin's or adaptive's parameters for this survey. Under a canopy (``p.canopy`` given, a ``multi`` share
    of points of multi-return pulses at least CANOPY_SHARE): the canopy set, its cell from the survey's
    ``density`` (canopy_cell). Residuals among the ground found there measure the understory and the forest
    floor's roughness as much as the scanner, and thresholds loosened by them take low vegetation for ground.
    Otherwise: ``for_noise``, thresholds from the measured ground noise."""
    if p.canopy and multi is not None and multi >= CANOPY_SHARE:
        _cell, threshold, scalar, slope, _reference, _smallest = p.canopy
        return replace(p, cell=canopy_cell(p.canopy, density), threshold=threshold, scalar=scalar, slope=slope,
                       noise_band=(), noise=noise, canopy=(), multi=multi, density=density)
    return replace(for_noise(p, noise), canopy=(), multi=multi, density=density)


def survey_returns(x, y, return_number, number_of_returns, cell: float) -> tuple[int, int, int, np.ndarray]:
    """(points, points of multi-return pulses, last returns, the sorted keys of the ``cell`` cells that hold a
    point) of these points: adaptive's measures of a survey, added up over its tiles (the cells as a union). The
    share of multi-return points tells a canopy: ISPRS-era scans record one return a pulse (0 %); autzen
    (suburban) 18 %, lidR's forests 31-58 %."""
    rn, nr = np.asarray(return_number), np.asarray(number_of_returns)
    ix = np.floor(np.asarray(x, np.float64) / cell).astype(np.int64)
    iy = np.floor(np.asarray(y, np.float64) / cell).astype(np.int64)
    return (len(rn), int(np.count_nonzero(nr >= 2)), int(np.count_nonzero(rn >= nr)),
            np.unique(ix * 4_294_967_296 + iy))


def survey_density(last: int, cells: int, cell: float) -> float | None:
    """Last returns per square CRS unit over the ``cells`` cells of side ``cell`` that hold a point."""
    return last / (cells * cell * cell) if cells else None


NOISE_BLOCK_M = 100.0  # smrftin measures a large survey's ground noise in blocks of 100 m (the absolute lattice) ...
NOISE_POINTS = 250_000  # ... every stride-th block east and north, the stride leaving about this many points in them


NOISE_ENOUGH = NOISE_POINTS // 10  # fewer ground residuals than this in the blocks: measured on every point instead


def noise_stride(points: int) -> int:
    """The stride of the blocks in which smrftin measures the ground noise of a survey of ``points`` points (every
    point of the files, withheld and noise included, as their headers count them): 1 (every point, no blocks) below
    4 x NOISE_POINTS, else the largest whose 1 / stride**2 share of the area holds about NOISE_POINTS (16 M points:
    every 8th block each way; a county of a billion: every 63rd). A survey whose blocks hold fewer than NOISE_ENOUGH
    ground residuals (a narrow corridor between the blocks, a small dense site) is measured again on every point."""
    return max(1, math.isqrt(max(int(points), 0) // NOISE_POINTS))


@dataclass(frozen=True)
class NoiseBlocks:
    """The blocks in which smrftin measures a large survey's ground noise (CRS units): every ``stride``-th block of
    ``block`` east and north (absolute numbers x // block, y // block multiples of ``stride``), each classified with
    the points within ``margin`` of it. Called with (x, y), where a point may be in a block or its margin (a superset,
    cheap: its place in the period of the blocks)."""

    block: float
    margin: float
    stride: int

    @classmethod
    def of(cls, p: SmrfParams, z_metres: float, stride: int) -> "NoiseBlocks":
        """NOISE_BLOCK_M blocks, margins of the filter's window plus 10 cells, for data of these units."""
        return cls(NOISE_BLOCK_M / (p.z_per_xy * z_metres), p.window + 10 * p.cell, int(stride))

    @property
    def reach(self) -> float:
        """How far beyond a tile its blocks' points may lie: a block and its margin."""
        return self.block + self.margin

    def __call__(self, x, y) -> np.ndarray:
        period = self.stride * self.block
        slack = 1e-6 * period
        if self.block + 2 * self.margin + 2 * slack >= period:  # margins wider than the gaps between the blocks
            return np.ones(len(x), bool)
        near = np.ones(len(x), bool)
        for v in (np.asarray(x, np.float64), np.asarray(y, np.float64)):
            o = v - np.floor(v / period) * period
            near &= (o < self.block + self.margin + slack) | (o >= period - self.margin - slack)
        return near


def survey_noise_histogram(x, y, z, return_number, number_of_returns, classification, own: np.ndarray,
                           p: SmrfParams, noise: NoiseParams, z_metres: float, stride: int = 1,
                           candidates: np.ndarray | None = None) -> np.ndarray:
    """smrftin's first pass: each ``own`` ground point's plane residual among the ground of its tight set (raised
    patches left in), as noise_histogram; the other points are neighbours, not counted.

    ``stride`` 1: every point, classified together. ``stride`` > 1 (large surveys, ``noise_stride``): only the
    points of the ``NoiseBlocks``, each block classified with the points of its margin and nothing else: a block's
    residuals do not depend on how the survey is tiled, so tiled == merged (a tile needs its neighbours' points
    within ``NoiseBlocks.reach``). ``candidates``: the ground candidates of these points (ground_candidates), if
    the caller has them (``stride`` 1 only: a block's are its own)."""
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    fields = (np.asarray(return_number), np.asarray(number_of_returns), np.asarray(classification))
    tight = replace(for_noise(p, 0.0), patch=0.0)
    if stride <= 1:
        return _noise_counts(x, y, z, fields, own, None, tight, noise, z_metres, candidates)
    blocks = NoiseBlocks.of(p, z_metres, stride)
    block, margin = blocks.block, blocks.margin
    idx = np.flatnonzero(blocks(x, y))
    bx, by = np.floor(x[idx] / block).astype(np.int64), np.floor(y[idx] / block).astype(np.int64)
    mine = idx[own[idx] & (bx % stride == 0) & (by % stride == 0)]
    numbers = np.unique(np.column_stack([np.floor(x[mine] / block), np.floor(y[mine] / block)]).astype(np.int64), axis=0)
    total = np.zeros(NOISE_BINS + 1, np.int64)
    xs, ys = x[idx], y[idx]
    for i, j in numbers:
        w, s_ = i * block, j * block
        clip = idx[(xs >= w - margin) & (xs < w + block + margin) & (ys >= s_ - margin) & (ys < s_ + block + margin)]
        # the same points in the same order however the survey is tiled (ties in a triangulation go by order)
        clip = clip[np.lexsort((*(f[clip] for f in reversed(fields)), z[clip], y[clip], x[clip]))]
        inside = (np.floor(x[clip] / block) == i) & (np.floor(y[clip] / block) == j)
        total += _noise_counts(x[clip], y[clip], z[clip], tuple(f[clip] for f in fields), own[clip], inside, tight,
                               noise, z_metres)
    return total


def too_few_in_blocks(stride: int, counts: np.ndarray) -> bool:
    """Whether a noise histogram measured in the blocks of ``stride`` holds too few residuals (fewer than
    NOISE_ENOUGH): the survey is then measured on every point."""
    return stride > 1 and int(np.sum(counts)) < NOISE_ENOUGH


def _survey_noise(x, y, z, return_number, number_of_returns, classification, p: SmrfParams, noise: NoiseParams,
                  z_metres: float, candidates: np.ndarray) -> np.ndarray:
    """survey_noise_histogram of every point of one array (the library's call): in the blocks of its stride, on
    every point if they hold too few residuals."""
    args = (x, y, z, return_number, number_of_returns, classification, np.ones(len(x), bool), p, noise, z_metres)
    stride = noise_stride(len(x))
    counts = survey_noise_histogram(*args, stride, candidates)
    return survey_noise_histogram(*args, 1, candidates) if too_few_in_blocks(stride, counts) else counts


def _noise_counts(x, y, z, fields, own, inside, tight: SmrfParams, noise: NoiseParams, z_metres: float,
                  candidates: np.ndarray | None = None) -> np.ndarray:
    """noise_histogram of the plane residuals of the ``own`` (and ``inside``, if given) points the ``tight`` SMRF
    finds ground among these points (``candidates``: theirs, if known)."""
    if candidates is None:
        _noise, _open, candidates = ground_candidates(x, y, z, *fields, noise)
    ground, _dem = smrf_ground(x, y, z, candidates, tight)
    gi = np.flatnonzero(ground)
    r = plane_residuals(x[gi], y[gi], z[gi])
    count = own[gi] if inside is None else own[gi] & inside[gi]
    return noise_histogram(r[count], z_metres)


GROUND_CLASS, LOW_NOISE, HIGH_NOISE, UNCLASSIFIED = 2, 7, 18, 1
RECLASSIFIED = (0, 1, 2, 7, 18)  # never classified, unclassified, ground, noise: the classes a run decides anew
GROUND_METHODS = choices("ground_method")  # declared in gistools.parameters (rasters' GROUND_METHODS)
TIN_METHODS = ("smrftin", "adaptive")  # SMRF then a TIN of its ground, thresholds from the survey


@dataclass(frozen=True)
class NoiseParams:
    """Noise rules in the data's units: ``method`` ivf | sor | none; IVF voxel ``res`` (CRS units) and ``n``; SOR
    ``k`` and ``multiplier``; ``low_depth`` (vertical unit): a point this far below the ground surface is low noise."""

    method: str = default_for("noise")
    res: float = _metres("ivf_res")
    n: int = default_for("ivf_n")
    k: int = default_for("sor_k")
    multiplier: float = default_for("sor_multiplier")
    low_depth: float = _metres("low_noise_depth")


@dataclass(frozen=True)
class CsfParams:
    """Cloth Simulation Filter parameters (lidR ``csf()`` / PDAL ``filters.csf``): ``resolution`` (CRS units),
    ``threshold`` (vertical unit), ``rigidness`` 1-3, ``time_step``, ``iterations``, ``slope_smooth``."""

    resolution: float = _metres("csf_resolution")
    threshold: float = _metres("csf_threshold")
    rigidness: int = default_for("csf_rigidness")
    time_step: float = default_for("csf_time_step")
    iterations: int = default_for("csf_iterations")
    slope_smooth: bool = default_for("csf_slope_smooth")


def csf_ground(x, y, z, candidates: np.ndarray, p: CsfParams) -> np.ndarray:
    """Ground by the Cloth Simulation Filter (Zhang et al. 2016) through ``cloth-simulation-filter`` (its ``CSF``
    module); True for the ``candidates`` it calls ground."""
    try:
        import CSF  # noqa: F401 - run in gistools.lidar.cloth
    except ImportError:
        raise ImportError("the csf method needs cloth-simulation-filter: pip install 'gistools[ground]'") from None
    from .cloth import stoppable_cloth_ground_indices

    ground = np.zeros(len(x), bool)
    idx = np.flatnonzero(candidates)
    if len(idx) == 0:
        return ground
    pts = np.column_stack([x[idx], y[idx], z[idx]])
    settings = {"bSloopSmooth": p.slope_smooth, "cloth_resolution": p.resolution, "class_threshold": p.threshold,
                "rigidness": p.rigidness, "time_step": p.time_step,
                "interations": p.iterations}  # sic: the library's spellings
    ground[idx[stoppable_cloth_ground_indices(pts - pts.min(axis=0), settings)]] = True
    return ground


def _noise_points(x, y, z, noise: NoiseParams) -> np.ndarray:
    """Where the noise filter (IVF, SOR or none) finds noise."""
    if noise.method == "ivf":
        from .noise import isolated_points

        return isolated_points(x, y, z, res=noise.res, n=noise.n)
    if noise.method == "sor":
        from .noise import statistical_outliers

        return statistical_outliers(x, y, z, k=noise.k, multiplier=noise.multiplier)
    return np.zeros(len(x), bool)


def ground_candidates(x, y, z, return_number, number_of_returns, classification, noise: NoiseParams):
    """(noise points, points whose class a run decides, ground candidates: last and only returns of those, not
    noise)."""
    rn, nr = np.asarray(return_number), np.asarray(number_of_returns)
    old = np.asarray(classification)
    is_noise = _noise_points(x, y, z, noise)
    open_ = np.isin(old, RECLASSIFIED)
    is_noise &= open_
    candidates = open_ & (rn >= nr) & ~is_noise  # last and only returns (return number 0 = not recorded: only)
    return is_noise, open_, candidates


def classify_ground_and_noise(x, y, z, return_number, number_of_returns, classification, *,
                              method: str = default_for("ground_method"),
                              smrf: SmrfParams | None = None, csf: CsfParams | None = None,
                              smrftin: SmrfParams | None = None, adaptive: SmrfParams | None = None,
                              noise: NoiseParams = NoiseParams(), keep_classes: bool = False,
                              z_metres: float = 1.0) -> np.ndarray:
    """New ASPRS classes of the points: noise first (IVF or SOR: 7 low noise below the ground surface, 18 high
    noise above it; the 5-bit class field of point formats 0-5 holds 18 too), then ground (2) among the last
    and only returns that are not noise; points more than ``noise.low_depth`` below the SMRF surface are low
    noise even in clusters (multipath). Only points of RECLASSIFIED classes change: water (9), buildings (6),
    vegetation (3-5) and any other class a provider gave stay as they are (and out of the ground surface).
    Points that were ground or noise and are not now become 1, unless ``keep_classes``. smrftin and adaptive measure
    the ground's noise on these points first unless their ``noise`` is given (``z_metres``: metres per vertical
    unit); adaptive measures the share of multi-return points and the density of last returns too unless its
    ``multi`` and ``density`` are given (``for_data``)."""
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    old = np.asarray(classification)
    is_noise, open_, candidates = ground_candidates(x, y, z, return_number, number_of_returns, old, noise)
    if method == "csf":
        ground = csf_ground(x, y, z, candidates, csf or CsfParams())
        surface = None
    elif method in TIN_METHODS:
        p = (adaptive or adaptive_params()) if method == "adaptive" else (smrftin or smrftin_params())
        if p.noise_band:  # thresholds from the ground's noise: given by the run, or measured on these points
            ground_noise = p.noise if p.noise is not None else noise_from_histogram(
                _survey_noise(x, y, z, return_number, number_of_returns, old, p, noise, z_metres, candidates), z_metres)
            if p.multi is None or p.density is None:  # measured on these points
                dc = DENSITY_CELL_M / (p.z_per_xy * z_metres)
                n, multi, last, cells = survey_returns(x, y, return_number, number_of_returns, dc)
                p = replace(p, multi=multi / n if n else None, density=survey_density(last, len(cells), dc))
            p = for_data(p, ground_noise, p.multi, p.density)
        ground, surface = smrf_ground(x, y, z, candidates, p)
    else:
        ground, surface = smrf_ground(x, y, z, candidates, smrf or SmrfParams())
    new = old.copy()
    if not keep_classes:
        new[open_ & np.isin(old, (GROUND_CLASS, LOW_NOISE, HIGH_NOISE))] = UNCLASSIFIED
    new[ground] = GROUND_CLASS
    if surface is not None and noise.low_depth is not None:
        deep = open_ & ~ground & (z < surface - noise.low_depth)  # multipath: far below the ground, even in a cluster
        is_noise |= deep
    if surface is not None:
        new[is_noise] = np.where(z[is_noise] < surface[is_noise], LOW_NOISE, HIGH_NOISE)
    else:
        new[is_noise] = HIGH_NOISE
    return new.astype(old.dtype, copy=False)
