"""Triangle meshes as arrays (vertices (n, 3) float, faces (m, 3) int): rings matched and joined by walls,
closedness and volume.

The dissertation matches each perimeter vertex of a layer with the nearest perimeter vertex
of the next layer by 3D distance, in both directions, with no cut-off (every printed distance
is reproduced that way). The wall between two rings is a triangle strip (a "zipper"): both
rings counter-clockwise, starting at the shortest link, each step takes the shorter new
diagonal; every ring edge is used once, so a wall has nA + nB triangles.

Shared by the aquifer units and the structure envelope; readers and writers are in ``gistools.io.meshes``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .errors import InputError

__all__ = ["match_rings", "wall", "is_closed", "mesh_volume"]


def match_rings(a_xyz: np.ndarray, b_xyz: np.ndarray, metric: str = "3d", max_distance: float | None = None):
    """For each vertex of ring A, the nearest vertex of ring B: (index in A, index in B, distance).

    ``metric``: "3d" (the dissertation's) or "2d". Links longer than ``max_distance`` are dropped.
    """
    if metric not in ("3d", "2d"):
        raise InputError(f"matching metric {metric!r} is not 3d or 2d")
    dims = 3 if metric == "3d" else 2
    origin = a_xyz[:, :dims].mean(axis=0)
    d, j = cKDTree(b_xyz[:, :dims] - origin).query(a_xyz[:, :dims] - origin)
    i = np.arange(len(a_xyz))
    keep = np.ones(len(i), bool) if max_distance is None else d <= max_distance
    return i[keep], j[keep], d[keep]


def wall(a_xyz: np.ndarray, b_xyz: np.ndarray) -> np.ndarray:
    """Triangles (indices: ring A as 0..nA-1, ring B as nA..nA+nB-1) of the strip between two CCW rings.

    A is the upper ring. Triangles wind so that, with the upper surface CCW (normals up) and the
    lower one flipped, the closed mesh has every edge once in each direction.
    """
    na, nb = len(a_xyz), len(b_xyz)
    if na < 3 or nb < 3:
        raise InputError("a wall needs two rings of at least 3 vertices")
    ia, jb, d = match_rings(a_xyz, b_xyz)
    k = int(np.argmin(d))
    a0, b0 = int(ia[k]), int(jb[k])
    A = np.roll(np.arange(na), -a0)
    B = np.roll(np.arange(nb), -b0)
    Ap = np.vstack([a_xyz[A], a_xyz[A[:1]]])
    Bp = np.vstack([b_xyz[B], b_xyz[B[:1]]])
    tris = []
    i = j = 0
    while i < na or j < nb:
        if i < na and (j == nb or np.linalg.norm(Ap[i + 1] - Bp[j]) <= np.linalg.norm(Ap[i] - Bp[j + 1])):
            tris.append((A[(i + 1) % na], A[i], na + B[j % nb]))  # advance on A
            i += 1
        else:
            tris.append((na + B[j % nb], na + B[(j + 1) % nb], A[i % na]))  # advance on B
            j += 1
    return np.asarray(tris, np.int64)


def is_closed(faces: np.ndarray) -> bool:
    """Every directed edge has exactly one reverse partner: watertight with consistent winding."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    fwd = (e[:, 0] << 32) | e[:, 1]
    rev = (e[:, 1] << 32) | e[:, 0]
    uf, cf = np.unique(fwd, return_counts=True)
    if (cf != 1).any():
        return False
    return bool(np.isin(rev, uf).all())


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume of a closed, consistently wound mesh (divergence theorem), vertices centred first."""
    v = vertices - vertices.mean(axis=0)
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
