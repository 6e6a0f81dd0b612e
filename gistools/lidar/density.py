"""Point density of vegetation cells over a circular neighbourhood (the dissertation's Point Density, S10).

Each vegetation cell stands for one Raster-To-Point point at its centre. Density =
points within radius r of a cell centre / (pi r^2), in points per CRS area unit (per
ft^2 on a feet CRS, as the dissertation's SQUARE_FEET); cover = points / number of cell
centres within r, a fraction 0-1. Cells with no point in reach are NaN (nodata), as ArcGIS.
Give the mask a halo of at least ``ceil(r / cell_size)`` cells from neighbouring tiles
and crop it afterwards, so density does not drop at tile edges.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..parameters import option

__all__ = ["disk_kernel", "disk_count", "point_density", "halo_cells"]


def halo_cells(radius: float, cell_size: float) -> int:
    """Cells of halo a neighbourhood of ``radius`` (CRS units) needs."""
    return int(np.ceil(radius / cell_size - 1e-5))


def disk_kernel(radius: float, cell_size: float) -> np.ndarray:
    """Boolean kernel of the cell centres within ``radius`` of the centre cell's centre (CRS units).

    Centres at the radius count, with a 1e-5 relative tolerance, so that a radius converted
    between foot definitions (2 ppm apart) keeps the same cells.

    >>> int(disk_kernel(25.0, 5.0).sum())
    81
    """
    if not radius > 0:
        raise InputError(f"density radius {radius!r} must be positive", hint=f"e.g. {option('radius', '25ft')}")
    k = halo_cells(radius * (1 + 1e-5), cell_size)
    off = np.arange(-k, k + 1) * cell_size
    return (off[:, None] ** 2 + off[None, :] ** 2) <= radius * radius * (1 + 2e-5)


def disk_count(mask: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Number of True cells of ``mask`` under ``kernel`` (a disk_kernel) centred on every cell; 0 beyond the edges.

    The same as ``scipy.ndimage.correlate(mask, kernel, mode="constant")``, in integers: each kernel row is a
    run of cells, summed as the difference of two row-wise cumulative sums (4x faster on a 25 ft / 5 ft disk).
    """
    k = kernel.shape[0] // 2
    m = np.asarray(mask, np.int32)
    height, width = m.shape
    # csum[r, j]: sum of padded row r over the columns before j (a zero column first)
    padded = np.zeros((height + 2 * k, width + 2 * k + 1), np.int32)
    padded[k:k + height, k + 1:k + 1 + width] = m
    csum = np.cumsum(padded, axis=1, dtype=np.int32)
    out = np.zeros((height, width), np.int32)
    for dy in range(-k, k + 1):
        row = kernel[dy + k]
        if not row.any():
            continue
        w = (int(row.sum()) - 1) // 2  # the row's run: columns -w .. w (disks are symmetric and convex)
        rows = csum[k + dy:k + dy + height]
        out += rows[:, k + w + 1:k + w + 1 + width] - rows[:, k - w:k - w + width]
    return out


def point_density(mask: np.ndarray, cell_size: float, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(count, density, cover) of the True cells of ``mask`` around every cell.

    count: points within ``radius`` (float32); density: count / (pi r^2) per CRS area unit;
    cover: count / kernel size. density and cover are NaN where count is 0.
    """
    kernel = disk_kernel(radius, cell_size)
    count = disk_count(mask, kernel).astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        density = np.where(count > 0, count / (np.pi * radius * radius), np.nan)
        cover = np.where(count > 0, count / kernel.sum(), np.nan)
    return count, density, cover
