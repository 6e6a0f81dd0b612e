"""Hydro-flattening of a DEM (USGS 3DEP practice): each water body one flat surface at the lowest ground elevation
of its shore, so a water surface is never above its banks, and the voids elsewhere filled or left.

Pure functions over numpy arrays; elevations in the DEM's unit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["shore_minimum", "flatten_cells", "merge_minima", "is_river", "river_levels", "RIVER_ELONGATION"]

RIVER_ELONGATION = 8.0  # a water polygon this many times longer than wide is a river (stepped down along its flow)


def shore_minimum(z, on_shore) -> float | None:
    """The lowest of the ground elevations ``z`` on the shore (mask ``on_shore``), None when there is none."""
    z = np.asarray(z, np.float64)[np.asarray(on_shore, bool)]
    return float(z.min()) if z.size else None


def merge_minima(parts) -> dict:
    """{water body: lowest shore elevation} from the per-tile {body: elevation} dicts (a body's shore crosses tiles)."""
    out: dict = {}
    for part in parts:
        for key, value in (part or {}).items():
            if value is not None:
                out[key] = min(value, out.get(key, np.inf))
    return out


def flatten_cells(dem: np.ndarray, inside: np.ndarray, elevation) -> int:
    """In place: the cells ``inside`` a water body at its ``elevation`` (one value, or one per cell inside: a
    river's levels), filled where they had no value; returns how many cells changed."""
    before = dem[inside]
    after = np.broadcast_to(np.asarray(elevation, np.float64), before.shape)
    dem[inside] = after
    return int(np.count_nonzero(~(before == after)))


def is_river(area: float, perimeter: float) -> bool:
    """A strip much longer than wide: mean width w = 2A/P, length about P/2 (a lake is about as long as wide)."""
    if area <= 0 or perimeter <= 0:
        return False
    width = 2 * area / perimeter
    return (perimeter / 2) / width >= RIVER_ELONGATION


def river_levels(s_shore, z_shore, step: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """(bin edges along the river, the water level of each bin, True when the flow runs toward larger s) from
    shore points at distance ``s_shore`` along the river with ground elevations ``z_shore``: the lowest shore point
    of each ``step``-long bin (empty bins take the next bin's), then a running minimum from the upstream end (the
    end whose shore is higher), so the level steps down monotonically along the flow and is never above the
    lowest bank point of its bin or of the bins beside it."""
    s_shore = np.asarray(s_shore, np.float64)
    z_shore = np.asarray(z_shore, np.float64)
    top = float(s_shore.max(initial=0.0))
    n = max(1, int(np.ceil((top + 1e-9) / step)))
    edges = np.arange(n + 1) * step
    low = np.full(n, np.inf)
    np.minimum.at(low, np.minimum((s_shore / step).astype(np.int64), n - 1), z_shore)
    have = np.isfinite(low)
    if not have.any():
        return edges, low, True
    idx = np.arange(n)
    # an empty bin takes the nearest bin with shore points (ties: the downstream one, decided below)
    filled = np.interp(idx, idx[have], low[have])
    first, last = filled[: max(1, n // 4)].mean(), filled[-max(1, n // 4):].mean()
    downhill_forward = first >= last
    levels = np.minimum.accumulate(filled) if downhill_forward else np.minimum.accumulate(filled[::-1])[::-1]
    # each bin at its downstream neighbour's level too: a cell near a bin's end is not above the bank just beyond it
    if downhill_forward:
        levels[:-1] = np.minimum(levels[:-1], levels[1:])
    else:
        levels[1:] = np.minimum(levels[1:], levels[:-1])
    return edges, levels, downhill_forward
