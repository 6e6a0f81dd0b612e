"""Shrub density classes from cover fraction (S11), and class breaks.

Codes of the class raster: 0 none (no vegetation in reach), 1 light, 2 medium,
3 heavy, 4 road, 5 water, 255 nodata. Default breaks on cover fraction f, from the
structural foliage-cover forms the dissertation cites (L1768-1780): light
0 < f <= 0.30, medium 0.30 < f <= 0.70, heavy f > 0.70.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..parameters import choices, option

__all__ = ["CLASS_NAMES", "CLASS_STYLE", "CLASS_NODATA", "CLASS_METHODS", "DEFAULT_BREAKS", "sample_step", "lattice_sample",
           "breaks_from_sample", "shrub_classes", "quantile_breaks", "jenks_breaks"]

CLASS_NAMES = {0: "none", 1: "light", 2: "medium", 3: "heavy", 4: "road", 5: "water"}
# The dissertation's legend (L4766): white no vegetation, green light, yellow medium, red heavy, gray roads, blue
# water: the map's colours and the class rasters' colour table and category names
CLASS_STYLE = {
    0: ("no vegetation", "#ffffff"),
    1: ("light", "#2ca02c"),
    2: ("medium", "#ffd700"),
    3: ("heavy", "#d62728"),
    4: ("road", "#808080"),
    5: ("water", "#1f77b4"),
}
CLASS_NODATA = 255
DEFAULT_BREAKS = (0.30, 0.70)
CLASS_METHODS = choices("classify")  # fixed cover breaks, or breaks from the data (gistools.parameters.shrub)


def shrub_classes(cover: np.ndarray, breaks=DEFAULT_BREAKS, *, road: np.ndarray | None = None,
                  water: np.ndarray | None = None, nodata: np.ndarray | None = None) -> np.ndarray:
    """uint8 class codes from cover fraction (NaN = no vegetation in reach = none)."""
    b1, b2 = breaks
    if not 0 <= b1 < b2 <= 1:
        raise InputError(f"class breaks {breaks} must satisfy 0 <= light/medium < medium/heavy <= 1",
                         hint=f"e.g. {option('class_breaks', DEFAULT_BREAKS)}")
    f = np.nan_to_num(np.asarray(cover, np.float64), nan=0.0)
    codes = np.select([f <= 0, f <= b1, f <= b2], [0, 1, 2], 3).astype(np.uint8)
    if nodata is not None:
        codes[nodata] = CLASS_NODATA
    if water is not None:
        codes[water] = 5
    if road is not None:
        codes[road] = 4
    return codes


def quantile_breaks(values: np.ndarray) -> tuple[float, float]:
    """Breaks splitting the positive values into three equal-count classes."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return DEFAULT_BREAKS
    return tuple(float(q) for q in np.quantile(v, [1 / 3, 2 / 3]))  # type: ignore[return-value]


def jenks_breaks(values: np.ndarray, *, sample: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Fisher-Jenks natural breaks (3 classes) of the positive values, on a sample of at most ``sample`` values.

    >>> jenks_breaks(np.array([0.1, 0.11, 0.12, 0.5, 0.52, 0.9, 0.95]))
    (0.12, 0.52)
    """
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v) & (v > 0)]
    if v.size < 3:
        return DEFAULT_BREAKS
    if v.size > sample:
        v = np.random.default_rng(seed).choice(v, sample, replace=False)
    v = np.sort(v)
    n = v.size
    c1 = np.concatenate([[0.0], np.cumsum(v)])
    c2 = np.concatenate([[0.0], np.cumsum(v * v)])

    def ssd(i, j):  # sum of squared deviations of v[i:j], vectorised over i
        m = j - i
        s = c1[j] - c1[i]
        return (c2[j] - c2[i]) - s * s / m

    # two cut points a < b: classes v[:a], v[a:b], v[b:]
    best, best_ab = np.inf, (1, 2)
    for b in range(2, n):
        a = np.arange(1, b)
        cost = ssd(np.zeros_like(a), a) + ssd(a, np.full_like(a, b)) + ssd(b, n)
        k = int(np.argmin(cost))
        if cost[k] < best:
            best, best_ab = cost[k], (int(a[k]), b)
    a, b = best_ab
    return float(v[a - 1]), float(v[b - 1])


# Breaks from the data (quantile, jenks) are computed on a sample of cover cells that does not depend on how the
# extent is cut into tiles or blocks: the cells whose global lattice row and column are multiples of a step, the
# step set by the extent's size, each cell once. So the chain (per tile), gistools classify and QGIS's
# gistools:classify (per block of a mosaic) choose the same breaks.
SAMPLE_CELLS = 250_000


def sample_step(extent_cells: int, target: int = SAMPLE_CELLS) -> int:
    """Lattice step giving about ``target`` sample cells over an extent of ``extent_cells`` cells."""
    return max(1, int(np.ceil(np.sqrt(max(extent_cells, 1) / target))))


def lattice_sample(cover: np.ndarray, col0: int, row_top: int, step: int) -> tuple[np.ndarray, np.ndarray]:
    """(global (row, col) keys, values) of the finite cells of ``cover`` on the sample lattice. ``col0``: global
    column of the first column; ``row_top``: global index of the north edge (a row r is lattice row row_top - 1 - r)."""
    rows = row_top - 1 - np.arange(cover.shape[0])
    cols = col0 + np.arange(cover.shape[1])
    r = np.flatnonzero(rows % step == 0)
    c = np.flatnonzero(cols % step == 0)
    sub = np.asarray(cover, np.float64)[np.ix_(r, c)]
    ok = np.isfinite(sub)
    rr, cc = np.nonzero(ok)
    return np.column_stack([rows[r][rr], cols[c][cc]]).astype(np.int64), sub[ok]


def breaks_from_sample(keys: list, values: list, method: str) -> tuple[float, float]:
    """Quantile or Jenks breaks of the sampled cells (each lattice cell once, in a fixed order)."""
    if not values:
        return DEFAULT_BREAKS
    k = np.concatenate(keys)
    v = np.concatenate(values)
    _, first = np.unique(k, axis=0, return_index=True)  # a cell two tiles share is counted once
    v = np.sort(v[first])
    return quantile_breaks(v) if method == "quantile" else jenks_breaks(v)

