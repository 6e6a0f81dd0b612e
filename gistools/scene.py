"""A surface grid as a triangle mesh with a colour per vertex: the 3D scene of the shrub map (deliver.scene).

Pure: heights and class codes on a grid in, vertices (metres, glTF's axes: x east, y up, z south), faces and RGBA
colours out.
"""

from __future__ import annotations

import numpy as np

__all__ = ["grid_mesh", "decimation_step", "BYTES_PER_VERTEX"]

# a vertex's share of a .glb: position (12 bytes) + colour (4) + two triangles of 3 uint32 indices (24)
BYTES_PER_VERTEX = 40


def decimation_step(rows: int, cols: int, max_bytes: float) -> int:
    """The smallest step k (every k-th cell of every k-th row) whose mesh stays under ``max_bytes``."""
    k = 1
    while (np.ceil(rows / k) * np.ceil(cols / k)) * BYTES_PER_VERTEX > max_bytes:
        k += 1
    return k


def grid_mesh(z, codes, colours: dict, *, x0: float, y0: float, cell: float, unit_m: float, z_unit_m: float,
              exaggeration: float = 1.0, nodata_colour=(200, 200, 200, 255)):
    """(vertices float32 (n, 3), faces uint32 (m, 3), colours uint8 (n, 4)) of the grid ``z`` (rows north to south,
    NaN = no value): a vertex at each cell centre with a value, two triangles per square of four of them. ``x0``,
    ``y0``: the centre of cell (0, 0) relative to the scene's origin, ``cell``: the cell size, both in CRS units of
    ``unit_m`` metres; heights in units of ``z_unit_m`` metres, times ``exaggeration``. ``codes``: a class per cell
    (or None), coloured by ``colours`` {code: (r, g, b)}."""
    z = np.asarray(z, np.float64)
    rows, cols = z.shape
    ok = np.isfinite(z)
    index = np.full(z.shape, -1, np.int64)
    index[ok] = np.arange(int(ok.sum()))
    r, c = np.nonzero(ok)
    east = (x0 + c * cell) * unit_m
    north = (y0 - r * cell) * unit_m
    up = z[ok] * z_unit_m * exaggeration
    vertices = np.column_stack([east, up, -north]).astype(np.float32)  # glTF: y up, z toward the viewer (south)
    a, b = index[:-1, :-1], index[:-1, 1:]
    d, e = index[1:, :-1], index[1:, 1:]
    quads = (a >= 0) & (b >= 0) & (d >= 0) & (e >= 0)
    # counter-clockwise seen from above (+y) in glTF's right-handed axes
    faces = np.concatenate([np.column_stack([a[quads], d[quads], b[quads]]),
                            np.column_stack([b[quads], d[quads], e[quads]])]).astype(np.uint32)
    rgba = np.tile(np.asarray(nodata_colour, np.uint8), (len(vertices), 1))
    if codes is not None:
        cv = np.asarray(codes)[ok]
        for code, rgb in colours.items():
            rgba[cv == code, :3] = rgb
    return vertices, faces, rgba
