"""LiDAR products on snapped grids: DSM, DEM, nDSM."""

from .gridding import (
    DEM_METHODS,
    cell_statistic,
    dem_from_ground_points,
    dsm_from_points,
    ndsm_from,
    within_distance,
)
from .tin import tin_to_grid

__all__ = [
    "DEM_METHODS",
    "cell_statistic",
    "dem_from_ground_points",
    "dsm_from_points",
    "ndsm_from",
    "within_distance",
    "tin_to_grid",
]
