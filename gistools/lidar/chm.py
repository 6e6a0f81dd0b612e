"""Canopy height models from first returns' heights above ground (lidR ``rasterize_canopy``).

``p2r``: the highest first return of each cell (lidR ``p2r()``); ``tin``: a Delaunay TIN of the first returns at the
cell centres (lidR ``dsmtin()``); ``pitfree``: Khosravipour et al. (2014), as lidR ``pitfree()``: TINs of the first
returns above each height threshold, triangles with an edge longer than the layer's limit dropped, stacked by their
maximum with the highest return of each cell, so that returns that went deep into a crown leave no pit and no cell
is lower than its highest return (a TIN at the cell centre would lower a tree top between its apex and the returns
around it). The upper layers' edge limit follows the returns' spacing (``auto_edge``): a limit shorter than the
gaps between the returns above a threshold leaves that layer full of holes, and the layers below show through them
as pits. Pure functions over numpy arrays; heights and lengths in the data's units; NaN where no value.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid
from .gridding import cell_statistic
from .tin import tin_to_grid

__all__ = ["CHM_METHODS", "EDGE_SPACINGS", "chm_p2r", "chm_tin", "chm_pitfree", "pitfree_thresholds", "pits",
           "nominal_spacing", "auto_edge"]

CHM_METHODS = ("p2r", "pitfree", "tin")
# the upper layers' automatic edge limit, in nominal spacings of the first returns: a layer holds only the returns
# above its threshold, so its points are sparser than the survey's; 4 spacings bridge the holes that deep returns
# leave in it (lidR's spikefree() advises 3 pulse spacings "or a little higher" for the freeze distance of
# Khosravipour et al. 2016, the same bridge); at 0.5 m, 3 spacings leave 13 % of the p2r pits of lidR's
# MixedConifer, 4 leave 2 % (docs/commands/chm.md)
EDGE_SPACINGS = 4.0


def chm_p2r(x, y, h, grid: Grid) -> np.ndarray:
    """The highest height of each cell (NaN where a cell has no point)."""
    return cell_statistic(grid, x, y, h, "max")


def chm_tin(x, y, h, grid: Grid, *, max_edge: float | None = None, engine: str | None = None) -> np.ndarray:
    """A TIN of the points at the cell centres (``max_edge``: longer triangles give no value; None: no limit)."""
    return tin_to_grid(x, y, h, grid, max_edge=max_edge, engine=engine)


def nominal_spacing(points: int, area: float) -> float:
    """The nominal spacing of ``points`` returns spread evenly over ``area`` (square length units): the side of the
    square each one has, sqrt(area / points), in the area's length unit; NaN without points or area."""
    return math.sqrt(area / points) if points > 0 and area > 0 else math.nan


def auto_edge(spacing: float) -> float:
    """The pit-free upper layers' edge limit for returns of nominal ``spacing`` (length units): EDGE_SPACINGS
    spacings, to 2 significant digits (an estimate: tiles of one survey whose areas add up to slightly different
    figures get one limit)."""
    return float(f"{EDGE_SPACINGS * spacing:.2g}")


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
    the others'; None = no limit), the layers stacked by their maximum, then with the highest point of each cell
    (``chm_p2r``), so that a cell is never below its highest return. ``step``: more thresholds above the last
    given, one every ``step`` up to the highest point (lidR stops at the thresholds given: step None). Heights,
    thresholds and edges in the data's units. Cells no layer covers are NaN."""
    h = np.maximum(np.asarray(h, np.float64), 0.0)
    x, y = np.asarray(x), np.asarray(y)
    out = chm_p2r(x, y, h, grid)
    base_edge, upper_edge = max_edges
    for k, t in enumerate(pitfree_thresholds(thresholds, step, float(h.max(initial=0.0)))):
        keep = h >= t if k else np.ones(len(h), bool)
        if np.count_nonzero(keep) < 3:
            break
        layer = tin_to_grid(x[keep], y[keep], h[keep], grid, max_edge=base_edge if k == 0 else upper_edge,
                            engine=engine)
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
