"""Noise points: isolated points (IVF) and statistical outliers (SOR), before a ground filter sees them.

Pure functions over coordinate arrays (CRS units). Voxels lie on an absolute lattice (multiples of ``res``),
so a tile read with a buffer of its neighbours marks the same points as the merged tiles do.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..parameters import choices, default_for

__all__ = ["isolated_points", "statistical_outliers", "NOISE_METHODS"]

NOISE_METHODS = choices("noise")  # declared in gistools.parameters.lidar


def _voxel_keys(ix, iy, iz) -> np.ndarray:
    """One int64 key per voxel index triple (21 bits each, offset so negative indices work)."""
    off = 1 << 20
    return ((ix + off) << 42) | ((iy + off) << 21) | (iz + off)


_DENSE_VOXELS = 16_000_000  # a count grid up to this many voxels (64 MB of int32); past it, the sorted-key search


def isolated_points(x, y, z, *, res: float, n: int = default_for("ivf_n")) -> np.ndarray:
    """Isolated Voxel Filter (lidR ``ivf`` / lasR ``classify_with_ivf``): True for each point with at most ``n``
    other points in its 3 x 3 x 3 voxels of ``res`` (CRS units; lidR's default 5 m, n = 6)."""
    x, y, z = (np.asarray(a, np.float64) for a in (x, y, z))
    if len(x) == 0:
        return np.zeros(0, bool)
    ix, iy, iz = (np.floor(a / res).astype(np.int64) for a in (x, y, z))
    for a in (ix, iy, iz):
        a -= a.min() - 1  # voxel indices from 1: a free layer on each side for the 3 x 3 x 3 sums
    shape = (int(ix.max()) + 2, int(iy.max()) + 2, int(iz.max()) + 2)
    if shape[0] * shape[1] * shape[2] <= _DENSE_VOXELS:
        return _isolated_dense(ix, iy, iz, shape) <= n
    return _isolated_sparse(ix, iy, iz) <= n


def _isolated_dense(ix, iy, iz, shape) -> np.ndarray:
    """Other points in each point's 3 x 3 x 3 voxels, from a grid of counts summed along each axis in turn."""
    flat = (ix * shape[1] + iy) * shape[2] + iz
    grid = np.bincount(flat, minlength=shape[0] * shape[1] * shape[2]).astype(np.int32).reshape(shape)
    for axis in range(3):
        total = grid.copy()
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        total[tuple(hi)] += grid[tuple(lo)]
        total[tuple(lo)] += grid[tuple(hi)]
        grid = total
    return grid.ravel()[flat] - 1


def _isolated_sparse(ix, iy, iz) -> np.ndarray:
    """The same counts over the occupied voxels only (sorted keys), for extents too large for a grid."""
    if max(ix.max(), iy.max(), iz.max()) >= (1 << 20) - 2:
        raise ValueError("voxels span more than 2^20 along an axis: give a larger IVF resolution")
    keys = _voxel_keys(ix, iy, iz)
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    vx, vy, vz = (uniq >> 42) - (1 << 20), ((uniq >> 21) & ((1 << 21) - 1)) - (1 << 20), (uniq & ((1 << 21) - 1)) - (1 << 20)
    around = np.zeros(len(uniq), np.int64)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                k = _voxel_keys(vx + dx, vy + dy, vz + dz)
                pos = np.minimum(np.searchsorted(uniq, k), len(uniq) - 1)
                hit = uniq[pos] == k
                around[hit] += counts[pos[hit]]
    return around[inverse.ravel()] - 1


def statistical_outliers(x, y, z, *, k: int = default_for("sor_k"),
                         multiplier: float = default_for("sor_multiplier")) -> np.ndarray:
    """Statistical outlier rule (PDAL ``filters.outlier`` statistical, lidR ``sor``): True for each point whose mean
    distance to its ``k`` nearest neighbours exceeds the mean of those distances by ``multiplier`` standard deviations."""
    pts = np.column_stack([np.asarray(x, np.float64), np.asarray(y, np.float64), np.asarray(z, np.float64)])
    if len(pts) <= k:
        return np.zeros(len(pts), bool)
    d, _ = cKDTree(pts - pts.mean(axis=0)).query(pts - pts.mean(axis=0), k=k + 1)
    mean = d[:, 1:].mean(axis=1)
    return mean > mean.mean() + multiplier * mean.std()
