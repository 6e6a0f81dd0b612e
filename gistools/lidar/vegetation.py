"""Vegetation cells of the height bands (S8-S9) and their cover (S10), as pure functions.

Codes of a vegetation raster: 0 not vegetation (B0, above B3), 1-3 the band (B1-B3) of
a vegetation cell, 4 road, 5 water, 255 nodata. Road wins over water where both hold
(a bridge deck is road). A cell belongs to a polygon when its centre does (the
dissertation's Clip / Select By Location on Raster To Point output).
"""

from __future__ import annotations

import numpy as np

from .bands import BAND_NODATA
from .density import point_density

__all__ = ["VEG_ROAD", "VEG_WATER", "VEG_NODATA", "vegetation", "vegetation_cover"]

VEG_ROAD, VEG_WATER, VEG_NODATA = 4, 5, 255


def vegetation(bands: np.ndarray, road: np.ndarray, water: np.ndarray, wetland: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(veg, wetveg) uint8 grids: band minus road minus water, and the vegetation inside wetlands.

    ``road``, ``water``, ``wetland``: boolean grids (cell centre inside the polygons).

    >>> veg, wet = vegetation(np.array([[0, 1, 3, 255]], np.uint8), np.array([[0, 1, 0, 0]], bool),
    ...                       np.zeros((1, 4), bool), np.array([[1, 1, 1, 1]], bool))
    >>> veg.tolist(), wet.tolist()
    ([[0, 4, 3, 255]], [[0, 0, 3, 0]])
    """
    veg = np.where((bands >= 1) & (bands <= 3), bands, 0).astype(np.uint8)
    veg[bands == BAND_NODATA] = VEG_NODATA
    veg[water] = VEG_WATER
    veg[road] = VEG_ROAD
    wetveg = np.where(wetland & (veg >= 1) & (veg <= 3), veg, 0).astype(np.uint8)
    return veg, wetveg


def vegetation_cover(veg: np.ndarray, cell_size: float, radius: float, density_bands=(1, 2, 3),
                     halo: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(density, cover) of the vegetation cells of ``density_bands`` within ``radius`` (CRS units).

    ``veg`` carries ``halo`` cells of its neighbours on each side (0 beyond the data);
    the results are cropped to the core. density: cells per CRS area unit; cover: 0-1.
    Cover is 0 where data lie in reach but no vegetation, NaN only with no data in reach.
    """
    count, density, cover = point_density(np.isin(veg, density_bands), cell_size, radius)
    has_data, _, _ = point_density(veg != VEG_NODATA, cell_size, radius)
    cover = np.where(np.isnan(cover) & (has_data > 0), 0.0, cover)
    rows, cols = veg.shape
    core = (slice(halo, rows - halo), slice(halo, cols - halo))
    return density[core], cover[core]
