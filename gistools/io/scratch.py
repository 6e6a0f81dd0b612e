"""The scratch files of the rasters' two passes (under ``--out``, in a ``.gistools-scratch-*`` folder).

Per tile: its ground points (``<tile>.ground.i4``, and the halo strips ``.haloW/E/S/N.i4`` a neighbour reads),
their scale, offset and extents (``<tile>.ground.json``, written last: none means pass 1 did not complete), the
first returns kept for the band counts (``<tile>.first.f8``) and the partial grids of pass 1
(``<tile>.grids/<array>.npy``, a folder renamed into place when complete).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

__all__ = ["GROUND_DTYPE", "HALO_SIDES", "FIRST_DTYPE", "ground_file", "ground_meta_file", "Extent", "grids_folder",
           "save_grids", "load_grid", "ground_sources", "read_ground"]


# Ground points in the scratch folder: the LAS file's own integers (X, Y, Z int32, 12 bytes a point, half
# of float64 x, y, z), scaled back with the tile's scale and offset exactly as laspy scales them. A tile
# writes all its ground points, and again those within the buffer of its edges in four strips (west and
# east whole, south and north between them), so a neighbour reads only the strips beside it.
GROUND_DTYPE = np.dtype([("X", "<i4"), ("Y", "<i4"), ("Z", "<i4")])
HALO_SIDES = ("W", "E", "S", "N")


def ground_file(scratch, name, side: str | None = None) -> Path:
    """Scratch file of a tile's ground points; ``side`` (W, E, S, N): its strip of points near that edge."""
    return Path(scratch) / f"{name}.{'halo' + side if side else 'ground'}.i4"


def ground_meta_file(scratch, name) -> Path:
    """Scale, offset and strip extents of a tile's ground files, written last (none: its pass 1 failed)."""
    return Path(scratch) / f"{name}.ground.json"


class Extent:
    """Running bounding box of points (west, south, east, north); None while empty."""

    def __init__(self):
        self.box = None

    def add(self, x, y, where):
        """Add the points of x, y under the boolean mask ``where`` (reduced in place, no copy)."""
        if where.any():
            self.add_box((np.min(x, where=where, initial=np.inf), np.min(y, where=where, initial=np.inf),
                          np.max(x, where=where, initial=-np.inf), np.max(y, where=where, initial=-np.inf)))

    def add_box(self, box):
        """Add a box (west, south, east, north) of points; an empty one (west > east) adds nothing."""
        b = tuple(float(v) for v in box)
        if b[0] <= b[2]:
            self.box = b if self.box is None else (min(self.box[0], b[0]), min(self.box[1], b[1]),
                                                   max(self.box[2], b[2]), max(self.box[3], b[3]))


def grids_folder(scratch, name) -> Path:
    """Scratch folder of a tile's partial grids of pass 1: one ``.npy`` file per array."""
    return Path(scratch) / f"{name}.grids"


def save_grids(folder: Path, **arrays) -> None:
    """Write the arrays as ``folder/<name>.npy``, atomically: the folder appears only once complete."""
    tmp = folder.with_name(folder.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for key, a in arrays.items():
        np.save(tmp / f"{key}.npy", a)
    shutil.rmtree(folder, ignore_errors=True)
    os.replace(tmp, folder)


def load_grid(folder: Path, key: str, mmap: bool = False) -> np.ndarray:
    """One array of a tile's partial grids; ``mmap``: memory-mapped, so a window reads only its own pages
    (a neighbour shares a row or column of cells: reading its whole grids cost 8 reads of 25 MB per tile)."""
    return np.load(folder / f"{key}.npy", mmap_mode="r" if mmap else None)


FIRST_DTYPE = np.dtype([("cell", "<i4"), ("z", "<f4")])


def ground_sources(scratch, name, bounds, deep: bool = True) -> list[tuple[Path, list, list, tuple]]:
    """The ground files of tile ``name`` that hold points inside ``bounds``: (path, scale, offset, extent);
    ``deep``: its whole ground file, else the halo strips. None when its pass 1 did not complete."""
    meta_file = ground_meta_file(scratch, name)
    if not meta_file.exists():
        return []
    meta = json.loads(meta_file.read_text(encoding="utf-8"))
    if meta["scale_offset"] is None:  # no ground point
        return []
    scale, offset = meta["scale_offset"]
    west, south, east, north = bounds
    out = []
    for key in ("ground",) if deep else HALO_SIDES:
        ext = meta["extents"][key]
        if ext is not None and ext[0] <= east and ext[2] >= west and ext[1] <= north and ext[3] >= south:
            out.append((ground_file(scratch, name, None if key == "ground" else key), scale, offset, tuple(ext)))
    return out


def read_ground(sources, bounds, chunk_points: int = 4_000_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, z (float64) of the ground points of ``sources`` (from ground_sources) inside ``bounds``,
    read a chunk at a time; a file whose extent lies inside ``bounds`` is taken whole."""
    west, south, east, north = bounds
    parts = []
    for path, scale, offset, ext in sources:
        whole = ext[0] >= west and ext[2] <= east and ext[1] >= south and ext[3] <= north
        with open(path, "rb") as fh:
            while True:
                raw = np.fromfile(fh, dtype=GROUND_DTYPE, count=chunk_points)
                if raw.size == 0:
                    break
                x = raw["X"] * scale[0] + offset[0]  # as laspy scales them: raw * scale + offset
                y = raw["Y"] * scale[1] + offset[1]
                if whole:
                    z = raw["Z"] * scale[2] + offset[2]
                else:
                    m = (x >= west) & (x <= east) & (y >= south) & (y <= north)
                    x, y, z = x[m], y[m], raw["Z"][m] * scale[2] + offset[2]
                if len(x):
                    parts.append((x, y, z))
    if not parts:
        return np.empty(0), np.empty(0), np.empty(0)
    if len(parts) == 1:
        return parts[0]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))
