"""A unit's isopach: its thickness interpolated from the boreholes that reach both its top and its base.

Two independent TINs of a unit's top and base cross where the unit pinches out and its base is sampled by fewer
boreholes than its top (the dissertation's Milan case; the synthetic aquifer's AU/AD: thickness -7.7 m, a
negative volume of 29.7e6 m3, where the true thickness is 0). The isopach, a TIN of the thicknesses measured in the
boreholes, is never below 0 and is exact where the thickness is linear between boreholes (a lower surface
upper - isopach is never above the upper one): geology's usual way (isopach / isochore maps).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from ..errors import InputError
from .surface import build_surface

__all__ = ["isopach"]


def isopach(points: pd.DataFrame, upper: str, lower: str, xy_tol: float):
    """The unit's thickness as a TIN of the boreholes that reach both its top and its base (the same borehole_id,
    else the same position within ``xy_tol``), negative thicknesses set to 0: the isopach, which is never below 0
    and keeps a pinch-out's zero where two independent TINs of top and base would cross. None with < 3 such pairs."""
    top, base = points[points["layer"] == upper], points[points["layer"] == lower]
    if "borehole_id" in points.columns and top["borehole_id"].notna().all() and base["borehole_id"].notna().all():
        pairs = base.merge(top, on="borehole_id", suffixes=("", "_top"))
    else:
        dist, k = cKDTree(top[["x", "y"]].to_numpy()).query(base[["x", "y"]].to_numpy())
        near = dist <= xy_tol
        pairs = base[near].assign(z_top=top["z"].to_numpy()[k[near]])
    pairs = pairs.drop_duplicates(subset=["x", "y"])
    if len(pairs) < 3:
        return None
    t = np.maximum(pairs["z_top"].to_numpy() - pairs["z"].to_numpy(), 0.0)
    try:
        return build_surface(f"{upper}/{lower} thickness", pairs["id"].to_numpy(), pairs["x"].to_numpy(),
                             pairs["y"].to_numpy(), t)
    except InputError:  # the pairs do not span an area
        return None
