"""Per-cell statistics of points (cell metrics, lasR ``rasterize(res, "z_p95")`` / lidR ``pixel_metrics``).

Names as lasR's metric engine spells them: ``<attribute>_<metric>``, attribute ``z`` (elevation), ``i``
(intensity) or ``hag`` (height above ground), metric ``count``, ``min``, ``max``, ``mean``, ``median``, ``sum``,
``sd``, ``cv``, ``pNN`` (percentile, 0-100) or ``aboveX`` (the share of points above X, 0-1). Besides:
``count`` and ``density`` (points per square metre), ``cover_aboveX`` (the share of first returns more than X
above the ground), ``fhd`` and ``vci`` (foliage height diversity and vertical complexity index of the heights
above ground, 1 m layers) and ``fuel_A_B`` (ladder fuel: the share of the returns at most B above the ground that
are more than A above it). Definitions (the same as lasR's code where lasR has the metric): percentiles by linear
interpolation between order statistics (R's type 7, numpy's default); sd is the sample standard deviation (n - 1;
nodata for one point); cv = sd / mean (nodata where the mean is 0); aboveX is strictly above.

Pure functions over numpy arrays; thresholds arrive in the points' units (the task converts "2m" / "6ft").
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .. import kernel
from ..errors import InputError
from ..parameters import option

__all__ = ["MetricSpec", "parse_metric", "cell_metrics", "ATTRIBUTES", "STATISTICS", "needs_heights", "LAYER_HEIGHT_M"]

ATTRIBUTES = ("z", "i", "hag")
STATISTICS = ("count", "min", "max", "mean", "median", "sum", "sd", "cv")
LAYER_HEIGHT_M = 1.0  # fhd / vci layers (metres)
_NUMBER = r"(\d+(?:\.\d+)?)"
_LENGTH = r"(\d+(?:\.\d+)?)([a-zA-Z]*)"
_CELL_SORT = kernel.function("gt_cell_sort")
_CELL_MOMENTS = kernel.function("gt_cell_moments")
_CELL_PERCENTILE = kernel.function("gt_cell_percentile")


@dataclass(frozen=True)
class MetricSpec:
    """One metric: its name, attribute (z, i, hag or None), statistic, and its thresholds as written (number,
    unit text: "" is the data's unit)."""

    name: str
    attribute: str | None
    statistic: str
    numbers: tuple = ()

    @property
    def on_heights(self) -> bool:
        return self.attribute == "hag" or self.statistic in ("cover", "fhd", "vci", "fuel")


def _bad(name: str, why: str) -> InputError:
    example = option("metrics", "count,z_max,z_p95,hag_above2m,cover_above2m,fuel_1_3m")
    return InputError(f"metric {name!r}: {why}", hint=f"e.g. {example} (the documentation's \"Cell metrics\" lists them)")


def parse_metric(name: str) -> MetricSpec:
    """A MetricSpec from a name; InputError naming the metric when it is not one (or a percentile is outside 0-100)."""
    text = name.strip()
    if text in ("count", "density", "fhd", "vci"):
        return MetricSpec(text, None, text)
    if m := re.fullmatch(r"cover_above" + _LENGTH, text):
        return MetricSpec(text, None, "cover", ((float(m[1]), m[2]),))
    if m := re.fullmatch(r"fuel_" + _NUMBER + "_" + _LENGTH, text):
        low, high = float(m[1]), float(m[2])
        if not low < high:
            raise _bad(text, f"the stratum {low:g} to {high:g} is empty (give the lower height first)")
        return MetricSpec(text, None, "fuel", ((low, m[3]), (high, m[3])))
    attribute, _, stat = text.partition("_")
    if attribute not in ATTRIBUTES or not stat:
        raise _bad(text, f"not a metric name (attributes are {', '.join(ATTRIBUTES)}: z_max, i_mean, hag_p95, ...)")
    if stat in STATISTICS:
        return MetricSpec(text, attribute, stat)
    if m := re.fullmatch(r"p" + r"(-?\d+(?:\.\d+)?)", stat):
        p = float(m[1])
        if not 0 <= p <= 100:
            raise _bad(text, f"percentile {p:g} is outside 0-100")
        return MetricSpec(text, attribute, "percentile", ((p, ""),))
    if m := re.fullmatch(r"above" + r"(-?\d+(?:\.\d+)?)([a-zA-Z]*)", stat):
        if attribute == "i" and m[2]:
            raise _bad(text, "intensity thresholds have no unit")
        return MetricSpec(text, attribute, "above", ((float(m[1]), m[2]),))
    raise _bad(text, f"{stat!r} is not one of {', '.join(STATISTICS)}, pNN or aboveX")


def needs_heights(specs) -> bool:
    """True when a metric needs heights above ground."""
    return any(s.on_heights for s in specs)


def cell_sorted(cell, values, ncells: int) -> tuple[np.ndarray, np.ndarray]:
    """(the values grouped by cell, each cell's ascending with NaN last, the index where each cell begins, length
    ``ncells`` + 1) for points in cells ``cell`` (0..ncells-1): ``values[numpy.lexsort((values, cell))]``. The
    compiled kernel's counting sort when built, else two numpy sorts (the same values)."""
    cell = np.ascontiguousarray(cell, np.int64)
    values = np.ascontiguousarray(values, np.float64)
    if _CELL_SORT is not None:
        start, pos, out = np.empty(ncells + 1, np.int64), np.empty(ncells, np.int64), np.empty(len(values))
        _CELL_SORT(len(values), cell, values, ncells, start, pos, out)
        return out, start
    # stable, as lexsort (equal values, -0.0 and 0.0, in point order); then a stable sort by cell keeps each cell's
    # values ascending
    by_value = np.argsort(values, kind="stable")
    out = values[by_value[np.argsort(cell[by_value], kind="stable")]]
    start = np.concatenate([[0], np.cumsum(np.bincount(cell, minlength=ncells))])
    return out, start


class _Sorted:
    """An attribute's values grouped by cell and sorted within each (NaN last), computed once: percentiles, and
    every other statistic from contiguous runs of memory (``reduceat``), which is about twice as fast as gathering
    them point by point (``bincount`` weights, ``ufunc.at``) and shares the one sort with the percentiles."""

    def __init__(self, cell, values, count):
        self.values, self.bounds = cell_sorted(cell, values, len(count))
        self.start = self.bounds[:-1]
        self.count = count
        self.ok = count > 0
        self._sums = None

    def _cells(self, per_cell: np.ndarray) -> np.ndarray:
        out = np.full(len(self.count), np.nan)
        out[self.ok] = per_cell
        return out

    def sums(self) -> tuple[np.ndarray, np.ndarray]:
        """(sum, sum of squared deviations from the mean) of each cell, 0 where a cell has no point."""
        if self._sums is None:
            n = len(self.count)
            if _CELL_MOMENTS is not None:  # one pass over each cell's run, numpy's sums bit for bit
                total, squares = np.empty(n), np.empty(n)
                _CELL_MOMENTS(n, self.bounds, self.values, total, squares, np.empty(max(int(self.count.max()), 1)))
            else:
                first, k = self.start[self.ok], self.count[self.ok]
                total, squares = np.zeros(n), np.zeros(n)
                if len(first):
                    total[self.ok] = np.add.reduceat(self.values, first)
                    dev = self.values - np.repeat(total[self.ok] / k, k)
                    squares[self.ok] = np.add.reduceat(dev * dev, first)
            self._sums = total, squares
        return self._sums

    def statistic(self, stat: str) -> np.ndarray:
        """sum, mean, sd, cv, min, max or median per cell; NaN where a cell has no point (sd, cv: fewer than two),
        and where a cell holds a NaN value (but median)."""
        if stat in ("min", "max"):
            k = self.count[self.ok]
            first = self.start[self.ok]
            last = self.values[first + k - 1]  # NaN sorts last: a cell with a NaN has it there
            return self._cells(last if stat == "max" else np.where(np.isnan(last), np.nan, self.values[first]))
        if stat == "median":
            return self.percentile(50.0)
        if stat not in ("sum", "mean", "sd", "cv"):
            raise ValueError(f"not a statistic of an attribute's values: {stat!r}")
        total, squares = self.sums()
        if stat == "sum":
            return np.where(self.ok, total, np.nan)
        k = self.count
        mean = np.divide(total, k, out=np.full(len(k), np.nan), where=self.ok)
        if stat == "mean":
            return mean
        with np.errstate(divide="ignore", invalid="ignore"):
            sd = np.sqrt(np.divide(squares, k - 1, out=np.full(len(k), np.nan), where=k > 1))
            return sd if stat == "sd" else np.where(mean != 0, sd / mean, np.nan)

    def percentile(self, p: float) -> np.ndarray:
        """The p-th percentile (0..100) of each cell's values, linear between ranks (numpy's default); NaN where a
        cell has no point."""
        if _CELL_PERCENTILE is not None:
            out = np.empty(len(self.count))
            _CELL_PERCENTILE(len(self.count), self.bounds, self.values, float(p), out)
            return out
        k = self.count
        ok = k > 0
        rank = p / 100.0 * (k[ok] - 1)
        lo = np.floor(rank).astype(np.int64)
        hi = np.ceil(rank).astype(np.int64)
        s = self.start[ok]
        a, b = self.values[s + lo], self.values[s + hi]
        out = np.full(len(k), np.nan)
        out[ok] = a + (b - a) * (rank - lo)
        return out


def _share(cell, hit, base, n) -> np.ndarray:
    """Per cell: (points of ``base`` with ``hit``) / (points of ``base``); NaN where the cell has none of ``base``."""
    den = np.bincount(cell[base], minlength=n)
    num = np.bincount(cell[base & hit], minlength=n)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / np.maximum(den, 1), np.nan)


def _layer_entropy(cell, h, count, n, layer: float) -> tuple[np.ndarray, np.ndarray]:
    """(Shannon entropy -sum p ln p of the points' shares in ``layer``-thick layers from the ground, the number of
    layers from 0 to the cell's highest point) per cell; heights below 0 count in the first layer."""
    layer_of = np.floor(np.maximum(h, 0) / layer).astype(np.int64)
    top = np.zeros(n, np.int64)
    np.maximum.at(top, cell, layer_of)
    key = cell * (int(layer_of.max(initial=0)) + 1) + layer_of
    keys, per = np.unique(key, return_counts=True)
    kcell = keys // (int(layer_of.max(initial=0)) + 1)
    p = per / count[kcell]
    entropy = np.bincount(kcell, weights=-p * np.log(p), minlength=n)
    return entropy, top + 1


def cell_metrics(cell, n: int, specs, *, z=None, intensity=None, hag=None, first=None, thresholds=None,
                 cell_area_m2: float = 1.0, layer: float = 1.0) -> dict:
    """{metric name: float64 array of ``n`` cells, NaN where a cell has no point} for the points in cells ``cell``
    (flat indices 0..n-1). ``z``, ``intensity``, ``hag``: per point (those the metrics need); ``first``: True for
    first returns (cover). ``thresholds``: {metric name: numbers in the data's unit}, default the specs' numbers.
    ``layer``: fhd / vci layer thickness in the heights' unit."""
    cell = np.asarray(cell, np.int64)
    count = np.bincount(cell, minlength=n)
    values = {"z": z, "i": None if intensity is None else np.asarray(intensity, np.float64), "hag": hag}
    cache: dict = {}
    out = {}
    entropy = None
    for spec in specs:
        nums = (thresholds or {}).get(spec.name, [v for v, _ in spec.numbers])
        if spec.statistic in ("count", "density"):
            r = np.where(count > 0, count.astype(np.float64), np.nan)
            out[spec.name] = r if spec.statistic == "count" else r / cell_area_m2
        elif spec.statistic == "cover":
            out[spec.name] = _share(cell, hag > nums[0], np.asarray(first, bool), n)
        elif spec.statistic == "fuel":
            out[spec.name] = _share(cell, hag > nums[0], hag <= nums[1], n)
        elif spec.statistic in ("fhd", "vci"):
            if entropy is None:
                entropy = _layer_entropy(cell, hag, count, n, layer)
            h, layers = entropy
            with np.errstate(divide="ignore", invalid="ignore"):
                r = h if spec.statistic == "fhd" else np.where(layers > 1, h / np.log(layers), np.nan)
            out[spec.name] = np.where(count > 0, r, np.nan)
        else:
            v = values[spec.attribute]
            if spec.statistic == "above":
                out[spec.name] = np.where(count > 0, np.bincount(cell[v > nums[0]], minlength=n) / np.maximum(count, 1),
                                          np.nan)
            elif spec.statistic == "percentile":
                out[spec.name] = _sorted(cache, spec.attribute, cell, v, count).percentile(nums[0])
            else:
                out[spec.name] = _sorted(cache, spec.attribute, cell, v, count).statistic(spec.statistic)
    return out


def _sorted(cache: dict, attribute: str, cell, v, count) -> _Sorted:
    if attribute not in cache:
        cache[attribute] = _Sorted(cell, v, count)
    return cache[attribute]
