"""Height bands of an nDSM (the dissertation's Select Layer By Attribute steps, S5).

Bands are disjoint half-open intervals of height above ground h:

====  ==============  ==========================
code  band            rule (thresholds T1-T3)
====  ==============  ==========================
0     B0 ground       h <= 0 (and see below)
1     B1 0-1 m        0 < h <= T1
2     B2 1-2 m        T1 < h <= T2
3     B3 2-6 m        T2 < h <= T3
4     above           h > T3 (trees, roofs: left out of the shrub chain)
255   nodata          no nDSM value
====  ==============  ==========================

Thresholds are given in metres and converted to the vertical unit of the data
(6 m = 19.685 ftUS, not the dissertation's 19.658). Bare ground must come out as
B0: a TIN DEM sits a little under a max-of-points DSM on sloping or rough ground,
so a cell whose highest first return is a ground or water point is B0 whatever h
is, and heights up to a noise floor (default 0.1 m) are B0 too.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..parameters import choices, option
from ..units import METRE, LinearUnit

__all__ = ["BAND_NAMES", "BAND_NODATA", "BAND_ABOVE", "PRESETS", "band_thresholds", "height_bands", "add_nodata_causes",
           "nodata_cause_shares"]

BAND_NAMES = ("B0", "B1", "B2", "B3")
BAND_ABOVE = 4
BAND_NODATA = 255
# Upper limits of B1, B2, B3. "exact": 1, 2, 6 m. "text_literal": the dissertation's printed feet (L4554-4592).
_LIMITS = {
    "exact": ((1.0, 2.0, 6.0), LinearUnit("metre", METRE)),
    "text_literal": ((3.28, 6.56, 19.658), LinearUnit("US survey foot", 1200.0 / 3937.0)),
}
PRESETS = {name: _LIMITS[name] for name in choices("bands")}  # the names declared in gistools.parameters.shrub


def band_thresholds(z_unit: LinearUnit, preset: str = "exact", breaks_m=None) -> tuple[float, float, float]:
    """T1, T2, T3 in ``z_unit``: from ``breaks_m`` (three heights in metres) or a named preset.

    >>> from gistools.units import LinearUnit
    >>> [round(t, 6) for t in band_thresholds(LinearUnit("US survey foot", 1200 / 3937))]
    [3.280833, 6.561667, 19.685]
    """
    if breaks_m is not None:
        values, unit = tuple(float(b) for b in breaks_m), LinearUnit("metre", METRE)
    elif preset in PRESETS:
        values, unit = PRESETS[preset]
    else:
        raise InputError(f"band preset {preset!r} is not one of {', '.join(PRESETS)}", hint=f"Use {option('bands', 'exact')}")
    if len(values) != 3 or not 0 < values[0] < values[1] < values[2]:
        raise InputError(f"band breaks {values} must be three increasing positive heights", hint="e.g. 1,2,6 (metres)")
    if abs(unit.metres - z_unit.metres) < 1e-12:
        return values  # type: ignore[return-value]
    return tuple(v * (unit.metres / z_unit.metres) for v in values)  # type: ignore[return-value]


def height_bands(ndsm: np.ndarray, thresholds, *, top_is_ground: np.ndarray | None = None,
                 noise_floor: float = 0.0) -> np.ndarray:
    """uint8 band codes (see the module table) of an nDSM (NaN = nodata).

    ``thresholds``: T1, T2, T3 in the nDSM's unit. ``top_is_ground``: boolean grid, the
    cell's highest first return is a ground or water point (then B0). ``noise_floor``:
    heights up to it are B0 (same unit).
    """
    t1, t2, t3 = thresholds
    h = np.asarray(ndsm, np.float64)
    codes = np.full(h.shape, BAND_NODATA, np.uint8)
    valid = np.isfinite(h)
    hv = h[valid]
    c = np.select([hv <= max(noise_floor, 0.0), hv <= t1, hv <= t2, hv <= t3], [0, 1, 2, 3], BAND_ABOVE).astype(np.uint8)
    codes[valid] = c
    if top_is_ground is not None:
        codes[valid & top_is_ground] = 0
    return codes


def add_nodata_causes(counts: dict, no_dsm: np.ndarray, no_dem: np.ndarray, top_class: np.ndarray) -> None:
    """Add to ``counts`` the cells of a block without a band, by cause: ``no_first_return`` (no DSM value), ``water``
    (no DEM value under a water return, class 9, on top), ``no_ground_near`` (no DEM value otherwise), and ``cells``."""
    no_dem = no_dem & ~no_dsm
    water = top_class == 9
    counts["no_first_return"] = counts.get("no_first_return", 0) + int(no_dsm.sum())
    counts["water"] = counts.get("water", 0) + int((no_dem & water).sum())
    counts["no_ground_near"] = counts.get("no_ground_near", 0) + int((no_dem & ~water).sum())
    counts["cells"] = counts.get("cells", 0) + no_dsm.size


def nodata_cause_shares(counts: dict) -> dict:
    """The counts of ``add_nodata_causes`` as shares of all cells."""
    cells = max(counts.get("cells", 0), 1)
    return {k: counts.get(k, 0) / cells for k in ("no_first_return", "water", "no_ground_near")}
