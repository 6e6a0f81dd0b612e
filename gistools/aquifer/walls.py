"""Closed unit meshes of the aquifer (S6, S9): a unit's upper surface (normals up), its lower surface
(flipped) and the wall between their boundary rings (``gistools.mesh.wall``): watertight, with every edge
used once in each direction.
"""

from __future__ import annotations

import numpy as np

from ..mesh import wall
from .surface import Surface

__all__ = ["ring_pairs", "unit_mesh"]


def ring_pairs(upper: Surface, lower: Surface) -> list[tuple[np.ndarray, np.ndarray]]:
    """Outer ring with outer ring; each hole of the upper surface with the lower surface's hole of nearest centroid."""
    pairs = [(upper.rings[0], lower.rings[0])]
    holes_l = list(lower.rings[1:])
    for hu in upper.rings[1:]:
        if not holes_l:
            break
        cu = upper.xyz[hu, :2].mean(axis=0)
        k = int(np.argmin([np.linalg.norm(lower.xyz[h, :2].mean(axis=0) - cu) for h in holes_l]))
        pairs.append((hu, holes_l.pop(k)))
    return pairs


def unit_mesh(upper: Surface, lower: Surface) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3), faces (m, 3)) of the closed unit between two surfaces: upper TIN, walls, lower TIN flipped.

    Walls join the outer rings and, where masking opened holes in both surfaces, the holes (paired by
    nearest centroid); :func:`is_closed` says whether the result is watertight (holes in one surface only
    leave it open)."""
    nu = len(upper.x)
    vertices = np.vstack([upper.xyz, lower.xyz])
    faces = [upper.triangles, lower.triangles[:, ::-1] + nu]
    for ru, rl in ring_pairs(upper, lower):
        w = wall(upper.xyz[ru], lower.xyz[rl])
        faces.append(np.concatenate([ru, rl + nu])[w])
    return vertices, np.vstack(faces)
