"""Hydro-flattening of a DEM (USGS 3DEP practice): each water body one flat surface at the lowest ground elevation
of its shore, so a water surface is never above its banks, and the voids elsewhere filled or left.

Pure functions over numpy arrays; elevations in the DEM's unit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["shore_minimum", "flatten_cells", "merge_minima"]


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


def flatten_cells(dem: np.ndarray, inside: np.ndarray, elevation: float) -> int:
    """In place: the cells ``inside`` a water body at its ``elevation``, filled where they had no value; returns
    how many cells changed."""
    changed = inside & ~(dem == elevation)
    dem[inside] = elevation
    return int(np.count_nonzero(changed))
