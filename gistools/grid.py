"""Raster grids snapped to a global lattice of cells.

A :class:`Grid` is a north-up raster: an affine ``transform``, ``width`` and
``height`` in cells, and a ``crs``. Grids made by :func:`snapped_grid` have cell
edges on multiples of the cell size in CRS coordinates, so grids of adjoining
tiles share one lattice and mosaic without gaps, shifts or overlaps.

Cells are half-open: a cell covers ``[x0, x0 + cs)`` in x and ``(y1 - cs, y1]`` is
avoided in favour of ``[y1 - cs, y1)``; the cell of a point is
``floor(x / cs)``, ``floor(y / cs)`` on the global lattice, whatever tile it is read from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyproj
from affine import Affine

from . import kernel
from .errors import InputError
from .parameters import option

__all__ = ["Grid", "snapped_grid", "cell_index", "cell_centres", "evaluate_on_grid"]

_MATMUL = hasattr(Affine, "__matmul__")  # affine 3; affine 2 (Debian 12's QGIS venvs) has only ``*``


def affine_apply(transform: Affine, other):
    """``transform`` applied to ``other``: another Affine (their product) or coordinates (x, y), numbers or arrays.
    ``transform @ other`` with affine 3, which deprecates ``*`` for both; ``*`` with affine 2, which has no ``@``."""
    return transform @ other if _MATMUL else transform * other


@dataclass(frozen=True)
class Grid:
    """A north-up raster grid: transform, width and height in cells, crs."""

    transform: Affine
    width: int
    height: int
    crs: pyproj.CRS | None = None

    @property
    def cell_size(self) -> float:
        """Cell size in CRS units (square cells)."""
        return float(self.transform.a)

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols)."""
        return (self.height, self.width)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(west, south, east, north) in CRS units."""
        west, north = self.transform.c, self.transform.f
        return (west, north - self.height * self.cell_size, west + self.width * self.cell_size, north)

    @property
    def col0(self) -> int:
        """Global lattice column of the first column (west edge / cell size)."""
        return int(round(self.transform.c / self.cell_size))

    @property
    def row_top(self) -> int:
        """Global lattice index of the north edge (north / cell size)."""
        return int(round(self.transform.f / self.cell_size))

    def part(self, col: int, row: int, width: int, height: int) -> "Grid":
        """The grid of ``width`` x ``height`` cells whose first cell is this grid's (``col``, ``row``); negative
        offsets and sizes past the edges grow it (on the same lattice)."""
        return Grid(affine_apply(self.transform, Affine.translation(col, row)), width, height, self.crs)

    def grown(self, k: int) -> "Grid":
        """This grid with ``k`` cells more on every side."""
        return self.part(-k, -k, self.width + 2 * k, self.height + 2 * k)

    def window_in(self, other: "Grid") -> tuple[slice, slice, slice, slice] | None:
        """Overlap of this grid and ``other`` (same lattice) as slices.

        Returns (rows_self, cols_self, rows_other, cols_other), or None when they do not overlap.
        """
        if abs(other.cell_size - self.cell_size) > 1e-9 * self.cell_size:
            raise InputError("grids have different cell sizes", hint="Use one cell size for all tiles of a run")
        c0 = max(self.col0, other.col0)
        c1 = min(self.col0 + self.width, other.col0 + other.width)
        t0 = min(self.row_top, other.row_top)
        t1 = max(self.row_top - self.height, other.row_top - other.height)
        if c0 >= c1 or t1 >= t0:
            return None
        rs = slice(self.row_top - t0, self.row_top - t1)
        cs_ = slice(c0 - self.col0, c1 - self.col0)
        ro = slice(other.row_top - t0, other.row_top - t1)
        co = slice(c0 - other.col0, c1 - other.col0)
        return rs, cs_, ro, co


def snapped_grid(bounds, cell_size: float, crs: pyproj.CRS | None = None) -> Grid:
    """The smallest lattice-snapped grid whose cells hold every point inside ``bounds``.

    Cell edges fall on multiples of ``cell_size`` in CRS coordinates, so the grids of adjoining tiles share one
    lattice and mosaic without gaps or shifts.

    Parameters
    ----------
    bounds : tuple of float
        (west, south, east, north), in CRS units.
    cell_size : float
        Cell size, in CRS units (metres or feet).
    crs : pyproj.CRS, optional
        The grid's coordinate reference system, kept on the grid.

    Returns
    -------
    Grid
        A north-up grid (``transform``, ``width``, ``height``, ``crs``).

    Raises
    ------
    InputError
        ``cell_size`` is not positive.

    Examples
    --------
    >>> g = snapped_grid((12.0, 3.0, 27.0, 18.0), 5.0)
    >>> g.bounds, g.shape
    ((10.0, 0.0, 30.0, 20.0), (4, 4))
    """
    if not cell_size > 0:
        raise InputError(f"cell size {cell_size!r} must be positive", hint=f"Give e.g. {option('cell_size', '5ft')}")
    west, south, east, north = bounds
    c0 = int(np.floor(west / cell_size))
    c1 = int(np.floor(east / cell_size)) + 1
    r0 = int(np.floor(south / cell_size))
    r1 = int(np.floor(north / cell_size)) + 1
    transform = affine_apply(Affine.translation(c0 * cell_size, r1 * cell_size),  # north-up
                             Affine.scale(cell_size, -cell_size))
    return Grid(transform, c1 - c0, r1 - r0, crs)


def cell_index(grid: Grid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Flat cell index (row * width + column) of each point, -1 outside the grid.

    One compiled pass where the kernel is built, else numpy: the same float64 operations either way.

    Parameters
    ----------
    grid : Grid
        The grid (see `snapped_grid`).
    x, y : numpy.ndarray
        Point coordinates, in CRS units.

    Returns
    -------
    numpy.ndarray
        int64 cell index of each point; rows count from the north edge.

    Examples
    --------
    >>> import numpy as np
    >>> g = snapped_grid((0.0, 0.0, 9.0, 9.0), 5.0)
    >>> cell_index(g, np.array([1.0, 7.0, 12.0]), np.array([8.0, 2.0, 2.0])).tolist()
    [0, 3, -1]
    """
    fn = kernel.function("gt_cell_index")
    x, y = np.asarray(x), np.asarray(y)
    if fn is not None and x.shape == y.shape and x.ndim == 1:
        x = np.ascontiguousarray(x, np.float64)
        y = np.ascontiguousarray(y, np.float64)
        flat = np.empty(len(x), np.int64)
        fn(len(x), x, y, float(grid.cell_size), grid.col0, grid.row_top, grid.width, grid.height, flat)
        return flat
    return _cell_index_numpy(grid, x, y)


def _cell_index_numpy(grid: Grid, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    cs = grid.cell_size
    col = np.floor(np.divide(x, cs, dtype=np.float64))
    col -= grid.col0
    row = np.floor(np.divide(y, cs, dtype=np.float64))
    np.subtract(grid.row_top - 1, row, out=row)
    inside = (col >= 0) & (col < grid.width) & (row >= 0) & (row < grid.height)
    row *= grid.width
    row += col
    flat = row.astype(np.int64)
    flat[~inside] = -1
    return flat


def cell_centres(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """The x of each column's and the y of each row's cell centres.

    Parameters
    ----------
    grid : Grid
        The grid (see `snapped_grid`).

    Returns
    -------
    xs : numpy.ndarray
        float64 x of the centres, one per column (west to east), in CRS units.
    ys : numpy.ndarray
        float64 y of the centres, one per row (north to south), in CRS units.

    Examples
    --------
    >>> xs, ys = cell_centres(snapped_grid((0.0, 0.0, 9.0, 9.0), 5.0))
    >>> xs.tolist(), ys.tolist()
    ([2.5, 7.5], [7.5, 2.5])
    """
    cs = grid.cell_size
    xs = (grid.col0 + np.arange(grid.width) + 0.5) * cs
    ys = (grid.row_top - np.arange(grid.height) - 0.5) * cs
    return xs, ys


def evaluate_on_grid(grid: Grid, fn, *, rows: int = 256) -> np.ndarray:
    """fn(x, y) (2-D arrays of cell-centre coordinates, float result, NaN = nodata) on every cell, a block of
    ``rows`` rows at a time so memory stays bounded."""
    xs, ys = cell_centres(grid)
    out = np.full(grid.shape, np.nan)
    for r0 in range(0, grid.height, rows):
        X, Y = np.meshgrid(xs, ys[r0:r0 + rows])
        out[r0:r0 + rows] = fn(X, Y)
    return out
