"""Canopy height models from first returns' heights above ground (lidR ``rasterize_canopy``).

``p2r``: the highest first return of each cell (lidR ``p2r()``); ``tin``: a Delaunay TIN of the first returns at the
cell centres (lidR ``dsmtin()``); ``pitfree``: Khosravipour et al. (2014), as lidR ``pitfree()``: TINs of the first
returns above each height threshold, triangles with an edge longer than the layer's limit dropped, stacked by their
maximum, so that returns that went deep into a crown leave no pit. Pure functions over numpy arrays; heights and
lengths in the data's units; NaN where no value.
"""

from __future__ import annotations

import numpy as np

from ..grid import Grid
from .gridding import cell_statistic
from .tin import tin_to_grid

__all__ = ["CHM_METHODS", "chm_p2r", "chm_tin", "chm_pitfree", "pitfree_thresholds", "pits"]

CHM_METHODS = ("p2r", "pitfree", "tin")


def chm_p2r(x, y, h, grid: Grid) -> np.ndarray:
    """The highest height of each cell (NaN where a cell has no point)."""
    return cell_statistic(grid, x, y, h, "max")


def chm_tin(x, y, h, grid: Grid, *, max_edge: float | None = None, engine: str | None = None) -> np.ndarray:
    """A TIN of the points at the cell centres (``max_edge``: longer triangles give no value; None: no limit)."""
    return tin_to_grid(x, y, h, grid, max_edge=max_edge, engine=engine)


def pitfree_thresholds(thresholds, step: float | None, top: float) -> list[float]:
    """The layers' thresholds: those given, then (``step`` > 0) one every ``step`` above the last, below ``top``."""
    out = sorted(float(t) for t in thresholds)
    if step:
        while out[-1] + step < top:
            out.append(out[-1] + step)
    return out


def chm_pitfree(x, y, h, grid: Grid, *, thresholds=(0.0, 2.0, 5.0, 10.0, 15.0), max_edges=(None, 1.0),
                step: float | None = None, engine: str | None = None) -> np.ndarray:
    """Khosravipour's pit-free CHM: for each threshold t, the TIN of the points with h >= t (the first layer: every
    point, negatives at 0) with triangles longer than its edge limit dropped (``max_edges``: the first layer's, then
    the others'; None = no limit), the layers stacked by their maximum. ``step``: more thresholds above the last
    given, one every ``step`` up to the highest point (lidR stops at the thresholds given: step None). Cells no
    layer covers are NaN."""
    h = np.maximum(np.asarray(h, np.float64), 0.0)
    out = np.full(grid.shape, np.nan)
    base_edge, upper_edge = max_edges
    for k, t in enumerate(pitfree_thresholds(thresholds, step, float(h.max(initial=0.0)))):
        keep = h >= t if k else np.ones(len(h), bool)
        if np.count_nonzero(keep) < 3:
            break
        layer = tin_to_grid(np.asarray(x)[keep], np.asarray(y)[keep], h[keep], grid, max_edge=base_edge if k == 0
                            else upper_edge, engine=engine)
        np.fmax(out, layer, out=out)
    return out


def pits(chm: np.ndarray, depth: float) -> np.ndarray:
    """Cells more than ``depth`` below all of their 8 neighbours (each neighbour with a value)."""
    a = np.asarray(chm, np.float64)
    pad = np.pad(a, 1, constant_values=np.nan)
    low = np.isfinite(a)
    rows, cols = a.shape
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                nb = pad[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
                low &= np.isfinite(nb) & (nb > a + depth)
    return low
