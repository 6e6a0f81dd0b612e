"""Triangle meshes to files: binary PLY and Wavefront OBJ, written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import atomic_path

__all__ = ["write_ply", "write_obj"]


def write_ply(path, vertices: np.ndarray, faces: np.ndarray, *, overwrite: bool = True) -> Path:
    """Binary little-endian PLY (float64 vertices, int32 faces), atomically; read by trimesh, MeshLab, CloudCompare."""
    path = Path(path)
    header = (f"ply\nformat binary_little_endian 1.0\ncomment gistools aquifer unit\nelement vertex {len(vertices)}\n"
              "property double x\nproperty double y\nproperty double z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode("ascii")
    fa = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    fa["n"], fa["i"] = 3, faces
    with atomic_path(path, overwrite=overwrite) as tmp:
        with open(tmp, "wb") as f:
            f.write(header)
            f.write(np.ascontiguousarray(vertices, "<f8").tobytes())
            f.write(fa.tobytes())
    return path


def write_obj(path, vertices: np.ndarray, faces: np.ndarray, *, overwrite: bool = True) -> Path:
    """Wavefront OBJ (text), atomically; QGIS 3D, Blender."""
    path = Path(path)
    with atomic_path(path, overwrite=overwrite) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write("# gistools aquifer unit\n")
            np.savetxt(f, vertices, fmt="v %.6f %.6f %.6f")
            np.savetxt(f, faces + 1, fmt="f %d %d %d")
    return path
