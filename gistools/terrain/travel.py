"""A walker's travel time over a DEM's cells: Tobler's hiking function on the slope along each step, speed factors,
and the shortest walks from the start cells, an anisotropic Dijkstra (``scipy.sparse.csgraph``) over the whole grid's
graph, or block by block with a halo when the graph passes the memory limit; arrays in, arrays out. ``gistools
travel`` (gistools.products.travel) reads the DEM, the shrub classes, roads and water and writes the outputs; the
documentation's "Search and rescue" page states the model with its references."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, OutOfMemoryError

__all__ = ["travel_minutes", "walk_graph", "tobler_speed", "neighbour_offsets", "plan_memory", "gradient_magnitude", "SHRUB_FACTORS",
           "ISOCHRONES", "BYTES_PER_CELL", "CELL_BYTES", "NEIGHBOUR_BOUND"]

TOBLER = (6.0, 3.5, 0.05)  # km/h, per unit of slope, slope of the fastest walk (downhill 5 %)
SHRUB_FACTORS = (0.92, 0.83, 0.75)  # light, medium, heavy shrub (classes 1, 2, 3 of the shrub chain); none: 1
ISOCHRONES = (30.0, 60.0, 120.0, 240.0)  # minutes
CLASS_ROAD, CLASS_WATER = 4, 5  # the shrub chain's classes raster
# peak bytes a cell of the graph and its building (benchmarks/bench_travel.py: 1.55 GB for 2.56 M cells)
BYTES_PER_CELL = {8: 330, 16: 600}
# peak bytes a cell of the arrays kept whole when the graph goes block by block (heights, speed factors, fixed
# speeds, minutes, the classes and the outputs' arrays of gistools travel; benchmarks/bench_travel.py: about 70)
CELL_BYTES = 80
HALO = 2  # cells around a block in its graph: a knight's move reaches 2 cells
MIN_BLOCK = 16  # the smallest block side chosen from the memory limit
# worst over-estimate of a straight walk's length on flat ground: 1 / cos(half the widest angle between two moves)
NEIGHBOUR_BOUND = {8: 1.0 / math.cos(math.radians(45.0 / 2)) - 1.0,
                   16: 1.0 / math.cos(math.atan(0.5) / 2) - 1.0}  # 8.24 %, 2.75 %
MINUTES_PER_HOUR = 60.0


def neighbour_offsets(neighbours: int = 16) -> list[tuple[int, int]]:
    """(row, column) moves: 8 (the king's) or 16 (and the knight's)."""
    king = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
    if neighbours == 8:
        return king
    if neighbours == 16:
        return king + [(-2, -1), (-2, 1), (-1, -2), (-1, 2), (1, -2), (1, 2), (2, -1), (2, 1)]
    raise InputError(f"neighbours={neighbours!r}: 8 or 16", hint="16 (with the knight's moves) is the closer to straight lines")


def plan_memory(shape, neighbours: int, max_memory: float, block=None) -> dict:
    """How ``travel_minutes`` solves a grid of ``shape`` within ``max_memory`` bytes.

    The whole mosaic's graph (``BYTES_PER_CELL`` a cell) when it fits; else the cell arrays whole (``CELL_BYTES`` a
    cell) and the graph block by block, the block's side (cells) the largest whose graph with its halo fits what
    the arrays leave. ``block`` (cells, or (rows, columns)) forces the block-wise method with such blocks. Returns
    ``{"method": "whole" or "blocks", "block": (rows, columns) or None, "bytes": the estimate, "graph_bytes": the
    whole graph's estimate}``; OutOfMemoryError when even the cell arrays pass ``max_memory``.
    """
    from ..parameters import option

    rows, cols = shape
    per = BYTES_PER_CELL[int(neighbours)]
    whole = per * rows * cols
    if block is None and whole <= max_memory:
        return {"method": "whole", "block": None, "bytes": whole, "graph_bytes": whole}
    cells = CELL_BYTES * rows * cols
    if cells > max_memory:
        raise OutOfMemoryError(f"the travel time of {rows:,} x {cols:,} cells needs about {cells / 1e9:.2f} GB for "
                               f"its cell arrays ({CELL_BYTES} bytes a cell, the graph then block by block; the whole "
                               f"graph {whole / 1e9:.2f} GB), more than the {max_memory / 1e9:.2f} GB allowed",
                               hint="Clip the DEM to the search area, use coarser cells, or raise "
                                    f"{option('max_memory')} if the machine has the memory")
    if block is None:
        side = max(MIN_BLOCK, math.isqrt(int((max_memory - cells) / per)) - 2 * HALO)
        block = (side, side)
    else:
        block = (int(block), int(block)) if np.ndim(block) == 0 else tuple(int(v) for v in block)
        if len(block) != 2 or min(block) < 1:
            raise InputError(f"block={block!r}: a block is at least 1 x 1 cells", hint="e.g. block=512")
    window = min(block[0] + 2 * HALO, rows) * min(block[1] + 2 * HALO, cols)
    return {"method": "blocks", "block": block, "bytes": cells + per * window, "graph_bytes": whole}


def _graph(dem, factor, fixed, grad, cell_m, z_metres, tob, offsets, progress=None, extra=None):
    """The directed graph (CSR, minutes) of the cells of ``dem``: the whole grid or a window of it.

    ``factor`` and ``fixed`` as ``travel_minutes`` takes them (None: 1, NaN); ``grad`` each cell's steepest slope
    (isotropic) or None. A step reads only the cells of the rectangle it spans, so a window's steps are the grid's.
    ``extra``: (cells, minutes) of a virtual node, the last, with a step of those minutes to each cell (a window's
    cells seeded with their times). ``progress`` is told after each move's edges.
    """
    from scipy.sparse import csr_matrix

    from ..progress import report

    a_, b_, c_ = tob
    rows, cols = dem.shape
    n = rows * cols
    factor = np.ones_like(dem) if factor is None else factor
    fixed = np.full_like(dem, np.nan) if fixed is None else fixed
    # a cell at a fixed speed (a road, water waded) needs no height: water often has none (no ground under it)
    has_z = np.isfinite(dem)
    passable = (has_z & (np.nan_to_num(factor) > 0)) | (np.isfinite(fixed) & (fixed > 0))
    factor = np.where(passable, np.nan_to_num(factor), 0.0)
    z = np.where(has_z, dem, 0.0)
    iso = None if grad is None else _slowness(grad, factor, fixed, a_, b_, c_)
    index = np.arange(n, dtype=np.int64).reshape(rows, cols)
    k = len(offsets)
    targets = np.full((rows, cols, k), -1, dtype=np.int32 if n < 2**31 - 1 else np.int64)
    weights = np.zeros((rows, cols, k), dtype=np.float64)

    def shifted(a, dr, dc, src):
        """``a`` at the cells (r + dr, c + dc) of the cells ``src``."""
        rs, cs = src
        return a[rs.start + dr:rs.stop + dr, cs.start + dc:cs.stop + dc]

    for m, (dr, dc) in enumerate(offsets):
        # the cells (r, c) whose neighbour (r + dr, c + dc) is on the grid
        src = (slice(max(0, -dr), rows - max(0, dr)), slice(max(0, -dc), cols - max(0, dc)))
        step_m = cell_m * math.hypot(dr, dc)
        # the cells the step crosses: a knight's move crosses two more cells, a quarter of its length in each
        # (start, two between, end); a diagonal passes a corner, closed when both cells beside it are impassable
        if abs(dr) == 2 or abs(dc) == 2:
            mids = [(dr // 2, 0), (dr // 2, dc)] if abs(dr) == 2 else [(0, dc // 2), (dr, dc // 2)]
        else:
            mids = []
        crossed = [(0, 0), *mids, (dr, dc)]
        ok = np.logical_and.reduce([shifted(passable, a, b, src) for a, b in crossed])
        if abs(dr) == 1 and abs(dc) == 1:
            ok &= shifted(passable, dr, 0, src) | shifted(passable, 0, dc, src)
        if iso is not None:
            slow = np.mean([shifted(iso, a, b, src) for a, b in crossed], axis=0)
        else:
            slope = (shifted(z, dr, dc, src) - z[src]) * z_metres / step_m
            slope[~(has_z[src] & shifted(has_z, dr, dc, src))] = 0.0  # to or from a cell without height: level
            slow = np.mean([_slowness(slope, shifted(factor, a, b, src), shifted(fixed, a, b, src), a_, b_, c_)
                            for a, b in crossed], axis=0)
        t = targets[src + (m,)]
        t[ok] = shifted(index, dr, dc, src)[ok]
        weights[src + (m,)] = np.where(ok, step_m / 1000.0 * slow * MINUTES_PER_HOUR, 0.0)
        report(progress, (m + 1) / k, f"the walk's graph: move {m + 1} of {k}")
    del index, z, has_z, passable, factor, fixed, iso
    valid = targets >= 0
    size = n if extra is None else n + 1
    indptr = np.zeros(size + 1, dtype=np.int64)
    np.cumsum(valid.reshape(n, k).sum(axis=1), out=indptr[1:n + 1])
    data, indices = weights[valid], targets[valid]
    del targets, weights, valid
    if extra is not None:  # the virtual node's steps: the last row
        seeds, seed_minutes = extra
        indptr[n + 1] = indptr[n] + len(seeds)
        data = np.concatenate([data, seed_minutes])
        indices = np.concatenate([indices, seeds.astype(indices.dtype)])
    return csr_matrix((data, indices, indptr), shape=(size, size))


def walk_graph(dem: np.ndarray, cell_size: float, *, factor=None, fixed_speed=None, xy_metres: float = 1.0,
               z_metres: float | None = None, neighbours: int = 16, isotropic: bool = False,
               tobler: tuple = TOBLER, progress=None):
    """The whole grid's directed graph of ``travel_minutes`` (CSR, minutes a step, node ``r * cols + c``): for
    routes, ``scipy.sparse.csgraph.dijkstra(graph, indices=..., return_predecessors=True)`` gives the same
    minutes as ``travel_minutes`` and the path of each. Takes ``BYTES_PER_CELL`` bytes a cell."""
    dem = np.asarray(dem, dtype=np.float64)
    z_metres = xy_metres if z_metres is None else z_metres
    cell_m = cell_size * xy_metres
    grad = gradient_magnitude(dem, cell_m, z_metres) if isotropic else None
    return _graph(dem, None if factor is None else np.asarray(factor, dtype=np.float64),
                  None if fixed_speed is None else np.asarray(fixed_speed, dtype=np.float64), grad, cell_m, z_metres,
                  tuple(float(v) for v in tobler), neighbour_offsets(neighbours), progress=progress)


def _seeded_times(dem, factor, fixed, grad, t0, cell_m, z_metres, tob, offsets) -> np.ndarray:
    """Shortest times over a window's graph from every cell whose current time ``t0`` is finite, starting at it.

    scipy's Dijkstra starts all its sources at 0: a virtual node starts at 0 with a step of ``t0`` minutes to each
    seeded cell (0 + t0 is t0 exactly, so the sums are the whole grid's); cells at 0 (the points last seen) are
    sources themselves (a step of 0 minutes could be taken for no step).
    """
    from scipy.sparse.csgraph import dijkstra

    t = t0.ravel()
    n = t.size
    finite = np.isfinite(t)
    later = np.flatnonzero(finite & (t > 0))
    graph = _graph(dem, factor, fixed, grad, cell_m, z_metres, tob, offsets, extra=(later, t[later]))
    start = np.concatenate([[n], np.flatnonzero(finite & (t <= 0))])
    return dijkstra(graph, directed=True, indices=start, min_only=True)[:n].reshape(t0.shape)


def _block_times(dem, factor, fixed, start, block, isotropic, cell_m, z_metres, tob, offsets, progress=None,
                 info=None) -> np.ndarray:
    """Minutes by blocks of ``block`` (rows, columns) cells, each solved with a halo of ``HALO`` cells.

    A block waits while cells of it got lower times from a neighbour's solve; the waiting block with the lowest
    such time is solved next (its whole window seeded with the current times), until none waits. Every step lies
    in the window of its start cell's block, which is solved again after that cell's time last fell: the times
    are the whole graph's shortest paths.
    """
    import heapq

    from ..progress import report

    rows, cols = dem.shape
    sr, sc = block
    nbr, nbc = -(-rows // sr), -(-cols // sc)
    minutes = np.full((rows, cols), np.inf)
    waiting = np.full(nbr * nbc, np.inf)  # the lowest new time in each block since its last solve
    heap = []
    for r, c in start:
        minutes[r, c] = 0.0
        b = (r // sr) * nbc + c // sc
        if waiting[b] > 0.0:
            waiting[b] = 0.0
            heapq.heappush(heap, (0.0, b))
    solves, seen = 0, np.zeros(nbr * nbc, dtype=bool)
    while heap:
        low, b = heapq.heappop(heap)
        if low != waiting[b]:
            continue  # solved since, or waiting with a lower time
        waiting[b] = np.inf
        br, bc = divmod(b, nbc)
        seen[b] = True
        solves += 1
        report(progress, 0.95 * seen.sum() / (nbr * nbc),
               f"shortest walks by blocks: solve {solves}, block {br + 1},{bc + 1} of {nbr} x {nbc}, "
               f"{int(np.isfinite(waiting).sum())} more waiting")
        r0, r1 = max(0, br * sr - HALO), min(rows, (br + 1) * sr + HALO)
        c0, c1 = max(0, bc * sc - HALO), min(cols, (bc + 1) * sc + HALO)
        win = (slice(r0, r1), slice(c0, c1))
        grad = None
        if isotropic:  # central differences read one cell more: the window's slopes are the grid's
            e0, e1, f0, f1 = max(0, r0 - 1), min(rows, r1 + 1), max(0, c0 - 1), min(cols, c1 + 1)
            grad = gradient_magnitude(dem[e0:e1, f0:f1], cell_m, z_metres)[r0 - e0:r1 - e0, c0 - f0:c1 - f0]
        old = minutes[win]
        new = _seeded_times(dem[win], None if factor is None else factor[win], None if fixed is None else fixed[win],
                            grad, old, cell_m, z_metres, tob, offsets)
        lower = new < old
        if not lower.any():
            continue
        old[lower] = new[lower]  # minutes[win] is a view: halo cells lowered too
        rr, cc = np.nonzero(lower)
        blocks = ((rr + r0) // sr) * nbc + (cc + c0) // sc
        lowest = np.full(nbr * nbc, np.inf)
        np.minimum.at(lowest, blocks, new[lower])
        for other in np.flatnonzero(lowest < waiting):
            if other != b:
                waiting[other] = lowest[other]
                heapq.heappush(heap, (float(lowest[other]), int(other)))
    if info is not None:
        info.update(block_solves=solves, blocks=nbr * nbc, blocks_reached=int(seen.sum()))
    return minutes


def tobler_speed(slope, a: float = TOBLER[0], b: float = TOBLER[1], c: float = TOBLER[2]):
    """Tobler's hiking function: walking speed in km/h on ``slope`` (rise over run, uphill positive)."""
    return a * np.exp(-b * np.abs(np.asarray(slope, dtype=np.float64) + c))


def _slowness(slope, factor, fixed, a, b, c):
    """Hours per km on ``slope`` of cells with vegetation ``factor`` (0: impassable) or a ``fixed`` speed (km/h)."""
    with np.errstate(divide="ignore"):
        tob = 1.0 / (tobler_speed(slope, a, b, c) * factor)
        return np.where(np.isfinite(fixed), 1.0 / np.where(np.isfinite(fixed), fixed, 1.0), tob)


def gradient_magnitude(dem: np.ndarray, cell_metres: float, z_metres: float) -> np.ndarray:
    """The steepest slope of each cell (rise over run; central differences, one-sided at edges and beside nodata)."""
    z = dem * z_metres
    gy = np.gradient(z, cell_metres, axis=0) if z.shape[0] > 1 else np.zeros_like(z)  # an axis of one cell: flat
    gx = np.gradient(z, cell_metres, axis=1) if z.shape[1] > 1 else np.zeros_like(z)
    # where a neighbour is NaN, np.gradient's central difference is NaN: take the cell as flat there
    return np.nan_to_num(np.hypot(gx, gy), nan=0.0)


def travel_minutes(dem: np.ndarray, cell_size: float, sources, *, factor=None, fixed_speed=None, xy_metres: float = 1.0,
                   z_metres: float | None = None, neighbours: int = 16, isotropic: bool = False,
                   tobler: tuple = TOBLER, max_memory: float = 4e9, block=None, progress=None,
                   info: dict | None = None) -> np.ndarray:
    """Minutes to walk from the nearest of ``sources`` to each cell of ``dem``.

    A directed graph of the grid's cells, each step weighted by its length times the mean slowness (1 / speed) of
    the cells it crosses on the step's slope (uphill one way, downhill the other), solved by scipy's Dijkstra:
    over the whole grid when its graph fits ``max_memory``, else block by block (``plan_memory``), with the same
    result. Speeds in km/h.

    Parameters
    ----------
    dem : numpy.ndarray
        2-D array of heights, rows north to south, square cells. NaN: no data, impassable unless at a
        ``fixed_speed`` (a step to or from such a cell is taken as level).
    cell_size : float
        The cell's side in CRS units (``xy_metres`` metres each).
    sources : sequence of (int, int)
        (row, column) of the start cells.
    factor : numpy.ndarray, optional
        Multiplier of Tobler's speed per cell (1 open ground; 0 or NaN impassable). None: 1 everywhere.
    fixed_speed : numpy.ndarray, optional
        Speed in km/h per cell that replaces Tobler's (roads at a road speed, water waded); NaN where Tobler's
        function applies. None: NaN everywhere.
    xy_metres : float
        Metres per CRS unit (1 for metres, 0.3048 for feet, 1200 / 3937 for US survey feet).
    z_metres : float, optional
        Metres per height unit. None: ``xy_metres``.
    neighbours : int
        8 (the king's moves) or 16 (and the knight's, closer to straight walks). A knight's move crosses two more
        cells, whose slowness counts in its mean.
    isotropic : bool
        Each cell's speed from its steepest slope taken uphill, the same both ways (with 8 neighbours, the cost of
        ``skimage.graph.MCP_Geometric``).
    tobler : tuple of float
        (a in km/h, b, c) of Tobler's hiking function ``v = a exp(-b |s + c|)``, s the slope (rise over run).
    max_memory : float
        Bytes the work may take: the whole graph (``BYTES_PER_CELL`` a cell) when it fits, else the cell arrays
        (``CELL_BYTES`` a cell) and the graph of one block with its halo at a time.
    block : int or (int, int), optional
        Solve block by block with blocks of this many cells (rows, columns) whatever ``max_memory`` allows.
        None: chosen from ``max_memory``.
    progress : callable, optional
        ``progress(fraction, message)`` (returning False cancels): told after each move's edges are built over the
        whole grid (scipy's Dijkstra then runs without a word), or before each block's solve.
    info : dict, optional
        Filled with ``method`` ("whole" or "blocks"), ``block``, the memory ``estimate`` in bytes, and block by
        block ``block_solves`` (blocks solved, again when a neighbour lowered their times), ``blocks`` and
        ``blocks_reached``.

    Returns
    -------
    numpy.ndarray
        float64 minutes, the shape of ``dem``: 0 at the sources, ``inf`` where no walk reaches (water, no data, cut
        off).

    Raises
    ------
    InputError
        ``neighbours`` is not 8 or 16, or ``block`` is below 1.
    OutOfMemoryError
        Even the cell arrays (``CELL_BYTES`` a cell) pass ``max_memory``.
    Cancelled
        ``progress`` returned False.

    Examples
    --------
    >>> import numpy as np
    >>> from gistools import travel_minutes
    >>> t = travel_minutes(np.zeros((3, 41)), 1.0, [(1, 0)], neighbours=8)
    >>> round(float(t[1, 40]), 4)  # 40 m on flat ground at 6 exp(-0.175) km/h
    0.4765
    >>> bool(np.array_equal(travel_minutes(np.zeros((3, 41)), 1.0, [(1, 0)], neighbours=8, block=(2, 5)), t))
    True
    """
    from scipy.sparse.csgraph import dijkstra

    from ..progress import report, sub_progress

    dem = np.asarray(dem, dtype=np.float64)
    rows, cols = dem.shape
    offsets = neighbour_offsets(neighbours)
    plan = plan_memory((rows, cols), neighbours, max_memory, block)
    z_metres = xy_metres if z_metres is None else z_metres
    tob = tuple(float(v) for v in tobler)
    factor = None if factor is None else np.asarray(factor, dtype=np.float64)
    fixed = None if fixed_speed is None else np.asarray(fixed_speed, dtype=np.float64)
    cell_m = cell_size * xy_metres
    start = sorted({(int(r), int(c)) for r, c in sources})
    if info is not None:
        info.update(method=plan["method"], block=plan["block"], estimate=plan["bytes"])
    if plan["method"] == "blocks":
        minutes = _block_times(dem, factor, fixed, start, plan["block"], isotropic, cell_m, z_metres, tob, offsets,
                               progress=progress, info=info)
        report(progress, 1.0, "shortest walks by blocks: done")
        return minutes
    grad = gradient_magnitude(dem, cell_m, z_metres) if isotropic else None
    graph = _graph(dem, factor, fixed, grad, cell_m, z_metres, tob, offsets, progress=sub_progress(progress, 0.0, 0.5))
    del grad
    report(progress, 0.6, "shortest walks from the points last seen")
    minutes = dijkstra(graph, directed=True, indices=[r * cols + c for r, c in start], min_only=True)
    return minutes.reshape(rows, cols)
