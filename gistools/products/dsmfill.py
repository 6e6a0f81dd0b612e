"""The rasters' DSM pinholes filled (``gistools rasters --dsm-fill tin|nearest|subcircle``; also in the shrub chain).

Pass 1 keeps what the fill needs in each tile's partial grids: the position of every cell's highest first return
(``tin``, ``nearest``) and the returns at the corners of the tile's convex hull (``tin``), or the DSM of the returns
spread on their subcircles over the tile's grid grown by the radius (``subcircle``). Pass 2 takes them from the
tile and its neighbours, so a cell near a tile edge is filled as in one merged run: the TIN sees the neighbours'
returns within the buffer and the corners of the hull of the tile's and its neighbours' returns (a hole wider than
the buffer is filled from the returns within it), the nearest fill a ring of cells, the subcircles cross the edges.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import Grid, snapped_grid
from ..io.scratch import grids_folder, load_grid
from ..lidar.dsmfill import fill_from_nearest, fill_from_tin, hull_points, max_with_position, subcircle_into

__all__ = ["DsmFillScan", "fill_tile_dsm", "NEAREST_CELLS"]

NEAREST_CELLS = 3  # nearest: the farthest return an empty cell takes, in cells


def _sub_grid(bounds, run) -> Grid:
    w, s, e, n = bounds
    r = run.subcircle
    return snapped_grid((w - r, s - r, e + r, n + r), run.cell_size)


class DsmFillScan:
    """Pass 1: what the fill needs, chunk by chunk (``add``), as grids to save with the tile's (``grids``)."""

    def __init__(self, run, info, grid: Grid):
        self.method, self.run = run.dsm_fill, run
        n = grid.width * grid.height
        self.shape = grid.shape
        if self.method in ("tin", "nearest"):
            self.z = np.full(n, -np.inf)
            self.x, self.y = np.full(n, np.nan), np.full(n, np.nan)
            self.hull = np.empty((0, 3))  # tin: the returns at the corners of the hull, x, y, z
        else:
            self.grid = _sub_grid(info.bounds, run)
            self.z = np.full(self.grid.width * self.grid.height, -np.inf)

    def add(self, x, y, z, cell) -> None:
        """The surface returns of a chunk (x, y, z; ``cell``: their cells on the tile's grid)."""
        if self.method in ("tin", "nearest"):
            max_with_position(self.z, self.x, self.y, cell, z, x, y)
            if self.method == "tin" and len(x):
                points = np.concatenate([self.hull, np.column_stack([x, y, z])])
                self.hull = points[hull_points(points[:, 0], points[:, 1])]
        else:
            subcircle_into(self.z, self.grid, x, y, z, self.run.subcircle)

    def grids(self) -> dict:
        z = np.where(np.isinf(self.z), np.nan, self.z)
        if self.method in ("tin", "nearest"):
            return {"fill_x": self.x.reshape(self.shape), "fill_y": self.y.reshape(self.shape), "fill_hull": self.hull}
        return {"fill_z": z.reshape(self.grid.shape)}


def fill_tile_dsm(info, neighbours, run, grid: Grid, dsm: np.ndarray, tile_grid) -> tuple[np.ndarray, int]:
    """(the tile's DSM with its pinholes filled, how many) from its and its neighbours' pass-1 grids; ``dsm``: the
    merged DSM of the tile; ``tile_grid(info)``: a tile's grid."""
    sources = [(info, tile_grid(info))] + [(o, tile_grid(o)) for o in neighbours
                                           if grids_folder(run.scratch, o.name).is_dir()]
    if run.dsm_fill == "subcircle":
        out = np.full(grid.shape, np.nan)
        for other, _g in sources:
            sub = _sub_grid(other.bounds, run)
            window = grid.window_in(sub)
            if window is not None:
                rs, cs_, ro, co = window
                part = load_grid(grids_folder(run.scratch, other.name), "fill_z", mmap=True)[ro, co]
                out[rs, cs_] = np.fmax(out[rs, cs_], part)
        return out, int(np.count_nonzero(np.isnan(dsm) & np.isfinite(out)))
    k = 2 * NEAREST_CELLS  # nearest: a ring the farthest return's cells fit in; tin: the buffer
    if run.dsm_fill == "tin":
        k = max(k, math.ceil(run.buffer / run.cell_size))
    ring = grid.grown(k)
    z, x, y = (np.full(ring.shape, np.nan) for _ in range(3))
    for other, g in sources:
        window = ring.window_in(g)
        if window is None:
            continue
        rs, cs_, ro, co = window
        folder = grids_folder(run.scratch, other.name)
        nz = load_grid(folder, "dsm", mmap=True)[ro, co]
        higher = np.isfinite(nz) & ~(z[rs, cs_] >= nz)
        for target, key in ((z, None), (x, "fill_x"), (y, "fill_y")):
            values = nz if key is None else load_grid(folder, key, mmap=True)[ro, co]
            view = target[rs, cs_]
            view[higher] = values[higher]
    out = dsm.copy()
    if run.dsm_fill == "nearest":
        return out, fill_from_nearest(out, grid, x.ravel(), y.ravel(), z.ravel(),
                                      max_distance=NEAREST_CELLS * run.cell_size)
    px, py, pz = _with_hull(x.ravel(), y.ravel(), z.ravel(), [grids_folder(run.scratch, o.name) for o, _g in sources])
    return out, fill_from_tin(out, grid, px, py, pz, max_edge=None)


def _with_hull(px, py, pz, folders) -> tuple:
    """The cells' highest returns (px, py, pz; NaN where none) and the corners of the hull of the returns of the
    tiles of ``folders`` (their pass-1 corners), those not already among them."""
    corners = np.concatenate([load_grid(f, "fill_hull") for f in folders])
    corners = corners[hull_points(corners[:, 0], corners[:, 1])]
    ok = np.isfinite(pz)
    new = ~np.isin(corners[:, 0] + 1j * corners[:, 1], px[ok] + 1j * py[ok])
    return (np.concatenate([px[ok], corners[new, 0]]), np.concatenate([py[ok], corners[new, 1]]),
            np.concatenate([pz[ok], corners[new, 2]]))
