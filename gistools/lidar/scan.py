"""Pass 1 of the rasters over one chunk of a streamed tile: the tile's running grids and the ground points to keep.

Pure functions over numpy arrays; the rasters task (products/rasters.py ``_scan_tile``) reads the chunks and writes the
scratch files. Per chunk: point counts by class and by return number; the DSM (highest first return of the surface
classes) and the class of its point; the ground and water points per cell; the first returns kept for the height
band counts; and the chunk's ground points with the halo strip (within the buffer of the tile's west, east, south
or north edge) each lies in, for the neighbours' DEMs. One compiled pass where the kernel is built, else numpy:
the same values either way (tests/test_scan.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grid import Grid, cell_index
from .accumulate import _max_with_class_numpy, is_groundish, max_into

__all__ = ["GROUND_CLASS", "WATER_CLASS", "ScanGrids", "ChunkScan", "scan_chunk", "surface_mask"]

GROUND_CLASS = 2
WATER_CLASS = 9
_EMPTY_BOX = (np.inf, np.inf, -np.inf, -np.inf)


@dataclass
class ScanGrids:
    """A tile's running pass-1 grids (flat, one value per cell) and point counts, updated in place chunk by chunk.

    dsm: float64 heights (CRS vertical unit), -inf where no surface return is yet; top_class: uint8 class of the
    DSM's point (filled when ``track_top``); bare_first: int64 ground and water first returns per cell (when
    ``keep_first``); ground_count, water_count: int64 usable ground / water points per cell (when ``keep_ground``);
    by_class, by_return: int64 counts of every point of the chunk (return numbers above 15 counted as 15)."""

    dsm: np.ndarray
    top_class: np.ndarray
    bare_first: np.ndarray
    ground_count: np.ndarray
    water_count: np.ndarray
    by_class: np.ndarray
    by_return: np.ndarray
    track_top: bool = False
    keep_first: bool = False
    keep_ground: bool = False

    @classmethod
    def empty(cls, cells: int, *, track_top: bool, keep_first: bool, keep_ground: bool, nodata_class: int = 255):
        return cls(np.full(cells, -np.inf), np.full(cells, nodata_class, np.uint8), np.zeros(cells, np.int64),
                   np.zeros(cells, np.int64), np.zeros(cells, np.int64), np.zeros(256, np.int64), np.zeros(16, np.int64),
                   track_top, keep_first, keep_ground)


@dataclass
class ChunkScan:
    """What a chunk gives beyond the grids: each point's flat cell index (``cell``, int64, -1 outside the grid); its
    usable ground points as the LAS integers X, Y, Z (``ground_xyz``, n x
    3 int32, in order; ``ground_index``: their indices into the chunk, when asked for), those within the buffer of an
    edge again (``halo_xyz``) with their strip (``halo_side``: 1-4 = west, east, south, north), the extents (west,
    south, east, north, CRS units) of all of them and of each strip (``boxes``, 5 x 4, inf where empty), its
    non-bare surface first returns (cell int32, z float32) and how many points lie outside the grid."""

    cell: np.ndarray
    ground_xyz: np.ndarray
    ground_index: np.ndarray | None
    halo_xyz: np.ndarray
    halo_side: np.ndarray
    boxes: np.ndarray
    first_cell: np.ndarray
    first_z: np.ndarray
    outside: int


def surface_mask(cell, cls, return_number, withheld, surface: np.ndarray) -> np.ndarray:
    """The points that make the DSM: inside the grid, not withheld, a class of the ``surface`` table (class code
    -> bool), first returns (return number 0 = not recorded, taken as first)."""
    return (cell >= 0) & ~withheld & surface[cls] & (return_number <= 1)


def _kernel():
    """The compiled kernel's gt_scan_chunk (csrc/scan.c), or None where it is not built."""
    from .. import kernel

    return kernel.function("gt_scan_chunk")


def _strided_int32(a) -> np.ndarray:
    """A 1-D int32 view (any positive stride: laspy's fields of the point records) or copy."""
    a = np.asarray(a)
    if a.dtype != np.int32 or a.ndim != 1 or a.strides[0] <= 0:
        a = np.ascontiguousarray(a, np.int32)
    return a


def scan_chunk(grids: ScanGrids, grid: Grid, xyz_raw, scales, offsets, cls, return_number, withheld, *,
               surface: np.ndarray, halo_edges, ground_index: bool = False) -> ChunkScan:
    """One chunk into ``grids`` (in place; ``grid``: the tile's); returns its :class:`ChunkScan`.

    xyz_raw: the LAS integers X, Y, Z, with the header's ``scales`` and ``offsets`` (x = X * x scale + x offset, CRS
    units, as laspy scales them; the cells as grid.cell_index finds them); cls, return_number: uint8; withheld: bool;
    surface: the class table of the DSM (accumulate.surface_classes); halo_edges: (west + buffer, east - buffer,
    south + buffer, north - buffer) of the tile: a ground point west of the first is in the west strip, else east
    of the second in the east strip, else south, else north. ``ground_index``: also give the ground points' indices."""
    fn = _kernel()
    if fn is None:
        return _scan_chunk_numpy(grids, grid, xyz_raw, scales, offsets, cls, return_number, withheld, surface,
                                 halo_edges, ground_index)
    raw = [_strided_int32(a) for a in xyz_raw]
    count = len(raw[0])
    cell = np.empty(count, np.int64)
    scale_offset = np.array([*scales, *offsets], np.float64)
    lattice = np.array([grid.cell_size, grid.col0, grid.row_top, grid.width, grid.height], np.float64)
    cls, return_number, withheld = (np.ascontiguousarray(a).view(np.uint8) if np.asarray(a).dtype == bool
                                    else np.ascontiguousarray(a, np.uint8) for a in (cls, return_number, withheld))
    ncells = len(grids.dsm)
    g = grids
    first_cell = np.empty(count if g.keep_first else 0, np.int32)
    first_z = np.empty(count if g.keep_first else 0, np.float32)
    ground_xyz = np.empty((count if g.keep_ground else 0, 3), np.int32)
    halo_xyz = np.empty((count if g.keep_ground else 0, 3), np.int32)
    halo_side = np.empty(count if g.keep_ground else 0, np.uint8)
    index = np.empty(count, np.int64) if ground_index and g.keep_ground else None
    boxes = np.array([_EMPTY_BOX] * 5)
    counts = np.zeros(4, np.int64)
    scratch = (np.empty(ncells), np.empty(ncells, np.uint8)) if g.track_top else (np.empty(0), np.empty(0, np.uint8))

    def address(a, on=True):
        return a.ctypes.data if on and a is not None else None

    fn(count, *(v for a in raw for v in (address(a), a.strides[0])), scale_offset, lattice, cell, cls, return_number,
       withheld, np.ascontiguousarray(surface).view(np.uint8), is_groundish.view(np.uint8), ncells, g.dsm,
       address(g.top_class, g.track_top), *scratch, g.by_class, g.by_return, address(g.bare_first, g.keep_first),
       first_cell, first_z, GROUND_CLASS, WATER_CLASS, address(g.ground_count, g.keep_ground),
       address(g.water_count, g.keep_ground), np.asarray(halo_edges, np.float64), ground_xyz, address(index), halo_xyz,
       halo_side, boxes, counts)
    nf, ng, outside, nh = (int(v) for v in counts)
    return ChunkScan(cell, ground_xyz[:ng], index[:ng] if index is not None else None, halo_xyz[:nh], halo_side[:nh],
                     boxes, first_cell[:nf], first_z[:nf], outside)


def _scan_chunk_numpy(grids: ScanGrids, grid: Grid, xyz_raw, scales, offsets, cls, return_number, withheld, surface,
                      halo_edges, ground_index=False) -> ChunkScan:
    """scan_chunk in numpy (where the kernel is not built; the reference its compiled form is tested against)."""
    g = grids
    X, Y, Z = (np.asarray(a) for a in xyz_raw)
    x, y = X * float(scales[0]) + float(offsets[0]), Y * float(scales[1]) + float(offsets[1])
    z_scale, z_offset = float(scales[2]), float(offsets[2])
    cell = cell_index(grid, x, y)
    g.by_class += np.bincount(cls, minlength=256)[:256]
    g.by_return += np.bincount(np.minimum(return_number, 15), minlength=16)[:16]
    inside = cell >= 0
    usable = inside & ~withheld
    surf = surface_mask(cell, cls, return_number, withheld, surface)
    z = Z[surf] * z_scale + z_offset
    first_cell, first_z = np.empty(0, np.int32), np.empty(0, np.float32)
    if g.keep_first:
        bare = surf & is_groundish[cls]
        g.bare_first += np.bincount(cell[bare], minlength=len(g.bare_first))
        other = surf & ~bare
        first_cell = cell[other].astype(np.int32)
        first_z = (Z[other] * z_scale + z_offset).astype(np.float32)
    if g.track_top:
        _max_with_class_numpy(g.dsm, g.top_class, cell[surf], z, cls[surf])
    else:
        max_into(g.dsm, cell[surf], z)
    boxes = np.array([_EMPTY_BOX] * 5)
    outside = int(len(cell) - np.count_nonzero(inside))
    none = np.empty((0, 3), np.int32)
    if not g.keep_ground:
        return ChunkScan(cell, none, None, none, np.empty(0, np.uint8), boxes, first_cell, first_z, outside)
    ground = usable & (cls == GROUND_CLASS)
    g.ground_count += np.bincount(cell[ground], minlength=len(g.ground_count))
    g.water_count += np.bincount(cell[usable & (cls == WATER_CLASS)], minlength=len(g.water_count))
    west, east, south, north = halo_edges
    w = x < west
    e = (x > east) & ~w
    between = ~(w | e)
    s = between & (y < south)
    n = between & (y > north) & ~s
    side = np.zeros(len(cell), np.uint8)
    for code, m in enumerate((w, e, s, n), 1):
        side[m] = code
    for k, m in enumerate((ground, ground & w, ground & e, ground & s, ground & n)):
        if m.any():
            boxes[k] = (x[m].min(), y[m].min(), x[m].max(), y[m].max())
    xyz = np.column_stack([X[ground], Y[ground], Z[ground]]).astype(np.int32)
    side = side[ground]
    halo = side > 0
    return ChunkScan(cell, xyz, np.flatnonzero(ground) if ground_index else None, xyz[halo], side[halo], boxes,
                     first_cell, first_z, outside)
