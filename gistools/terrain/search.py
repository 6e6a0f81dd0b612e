"""Search planning on a DEM's grid, arrays in, arrays out: the probability of area (POA) from a lost person
category's distance rings, barriers (cliffs, water, thickets) and handrails (roads, drainages, ridges, thicket
edges), searchable segments, the probability of detection (POD) of an effort, and routes on the travel graph.
``gistools search-plan`` (gistools.products.search_plan) reads the shrub chain's folder and writes the outputs;
the documentation's "Search and rescue" page states the model and the sources of its tables."""

from __future__ import annotations

import math

import numpy as np

from ..grid import affine_apply

__all__ = ["RING_SHARES", "annulus_inside_fraction", "probability_of_area", "slope_degrees", "cliff_cells",
           "thicket_cells", "flow_receivers", "contributing_cells", "receiver_lines", "near_cells", "segment_cells",
           "coverage", "detection_probability", "cell_path", "corridor_open"]

# the probability within each ring of the distance statistics: 25 % to the first quartile, 25 % to the median, 25 %
# to the third quartile, 20 % to the 95th percentile; 5 % beyond it (the "rest of world")
RING_SHARES = (0.25, 0.25, 0.25, 0.20)


def annulus_inside_fraction(centre, r0: float, r1: float, inside, transform, radial: int = 64,
                            angular: int = 1440) -> float:
    """The share of the area of the annulus ``r0 <= r < r1`` around ``centre`` (CRS units) that falls on cells
    where ``inside`` is True (the DEM's data), by a polar lattice of ``radial`` x ``angular`` points weighted by
    their radius (the area element); 1 when the annulus lies wholly on such cells."""
    if r1 <= r0:
        return 0.0
    r = r0 + (np.arange(radial) + 0.5) / radial * (r1 - r0)
    a = (np.arange(angular) + 0.5) / angular * 2 * math.pi
    x = centre[0] + np.outer(r, np.cos(a))
    y = centre[1] + np.outer(r, np.sin(a))
    col, row = affine_apply(~transform, (x, y))
    row, col = np.floor(row).astype(np.int64), np.floor(col).astype(np.int64)
    rows, cols = inside.shape
    on = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
    hit = np.zeros(on.shape, dtype=bool)
    hit[on] = inside[row[on], col[on]]
    weight = np.broadcast_to(r[:, None], hit.shape)
    return float(weight[hit].sum() / weight.sum())


def _rake(mass: np.ndarray, groups, iterations: int = 50) -> np.ndarray:
    """``mass`` rescaled so that each split of ``groups`` ((masks, shares), ...) holds its shares (iterative
    proportional fitting); a group without mass gives its share to the others of its split."""
    total = mass.sum()
    if total <= 0:
        return mass
    for _ in range(iterations if len(groups) > 1 else 1):
        for masks, shares in groups:
            held = [mass[m].sum() for m in masks]
            present = sum(s for s, h in zip(shares, held) if h > 0)
            if present <= 0:
                continue
            for m, s, h in zip(masks, shares, held):
                if h > 0:
                    mass[m] *= total * s / present / h
    return mass


def probability_of_area(distance, rings, inside_fractions, *, weight=None, splits=()) -> tuple[np.ndarray, list]:
    """The probability of each cell holding the lost person, from the distance rings of their category.

    Ring k (distances from ``rings[k-1]``, 0 for the first, up to ``rings[k]``) holds ``RING_SHARES[k]`` of the
    probability, times the share of its area on the grid's data (``inside_fractions[k]``); within a ring the cells
    share it by ``weight`` (1: by area), then each split ((masks, shares): cells near linear features or not,
    downhill, level or uphill of the point last seen) is made to hold its shares. What no cell holds (beyond the
    last ring, or parts of rings off the data) is the rest of the world.

    Parameters
    ----------
    distance : numpy.ndarray
        Each cell's distance from the point last seen, metres (as the crow flies or walked); NaN or inf: no data,
        or not reached.
    rings : sequence of float
        The category's distances within which 25, 50, 75 and 95 % were found, metres, increasing.
    inside_fractions : sequence of float
        The share of each ring's area on cells with data (``annulus_inside_fraction``).
    weight : numpy.ndarray, optional
        Each cell's relative weight within its ring (0: never there, as water). None: 1.
    splits : sequence of (list of bool arrays, list of float)
        Shares within each ring: the masks of a split partition the cells, its shares sum to 1.

    Returns
    -------
    (numpy.ndarray, list of float)
        The probability of each cell (float64, 0 outside every ring) and the probability each ring holds.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.array([[0.0, 50.0, 150.0, 250.0, 350.0]])
    >>> p, held = probability_of_area(d, [100, 200, 300, 400], [1, 1, 1, 1])
    >>> p.tolist(), round(float(1 - p.sum()), 2)
    ([[0.125, 0.125, 0.25, 0.25, 0.2]], 0.05)
    """
    distance = np.asarray(distance, dtype=np.float64)
    weight = np.ones(distance.shape) if weight is None else np.asarray(weight, dtype=np.float64)
    finite = np.isfinite(distance)
    d = np.where(finite, distance, np.inf)
    poa = np.zeros(distance.shape)
    held = []
    low = 0.0
    for k, high in enumerate(rings):
        ring = finite & (d >= low) & (d < high) & (weight > 0)
        share = RING_SHARES[k] * float(inside_fractions[k])
        if ring.any() and share > 0:
            mass = weight[ring].copy()
            groups = [([m[ring] for m in masks], list(shares)) for masks, shares in splits]
            mass = _rake(mass, groups)
            poa[ring] = share * mass / mass.sum()
            held.append(share)
        else:
            held.append(0.0)
        low = high
    return poa, held


# --- barriers and handrails ---------------------------------------------------------------------------------------

def _axis_gradient(z: np.ndarray, step: float, axis: int) -> np.ndarray:
    """dz / step along ``axis``: central differences where both neighbours have a height, one-sided where one has
    (the grid's edge, beside nodata), 0 where neither has; NaN on cells without a height."""
    z = np.moveaxis(z, axis, 0)
    n = z.shape[0]
    out = np.zeros(z.shape)
    if n > 1:
        ahead = np.full(z.shape, np.nan)
        behind = np.full(z.shape, np.nan)
        ahead[:-1] = (z[1:] - z[:-1]) / step
        behind[1:] = (z[1:] - z[:-1]) / step
        both = np.isfinite(ahead) & np.isfinite(behind)
        out = np.where(both, (ahead + behind) / 2, np.where(np.isfinite(ahead), ahead,
                                                            np.where(np.isfinite(behind), behind, 0.0)))
    out = np.where(np.isfinite(z), out, np.nan)
    return np.moveaxis(out, 0, axis)


def slope_degrees(dem: np.ndarray, cell_metres: float, z_metres: float) -> np.ndarray:
    """The steepest slope of each cell in degrees: central differences, one-sided at the grid's edge and beside
    cells without a height (so a scarp beside a hole keeps its slope); NaN where the cell has no height.

    >>> z = np.array([[0.0, 1.0, np.nan, 0.0]])
    >>> slope_degrees(z, 1.0, 1.0).round(1).tolist()
    [[45.0, 45.0, nan, 0.0]]
    """
    z = np.asarray(dem, dtype=np.float64) * z_metres
    gy, gx = _axis_gradient(z, cell_metres, 0), _axis_gradient(z, cell_metres, 1)
    return np.degrees(np.arctan(np.hypot(gx, gy)))


_EIGHT = np.ones((3, 3), dtype=bool)


def cliff_cells(dem: np.ndarray, cell_metres: float, z_metres: float, *, min_slope: float,
                min_height: float) -> np.ndarray:
    """Cells of cliffs: 8-connected areas steeper than ``min_slope`` degrees whose height (the highest less the
    lowest height within them and the cells around them) is at least ``min_height`` metres."""
    from scipy import ndimage

    with np.errstate(invalid="ignore"):
        steep = slope_degrees(dem, cell_metres, z_metres) >= min_slope
    labels, count = ndimage.label(steep, structure=_EIGHT)
    if not count:
        return steep
    grown = ndimage.grey_dilation(labels, footprint=_EIGHT)  # each area and the cells around it
    z = np.where(np.isfinite(dem), dem * z_metres, np.nan)
    index = np.arange(1, count + 1)
    where = (grown > 0) & np.isfinite(z)
    high = ndimage.maximum(np.where(where, z, -np.inf), grown, index)
    low = ndimage.minimum(np.where(where, z, np.inf), grown, index)
    keep = np.concatenate([[False], (np.asarray(high) - np.asarray(low)) >= min_height])
    return keep[labels]


def thicket_cells(classes: np.ndarray, cell_area_m2: float, *, min_area: float, heavy: int = 3) -> np.ndarray:
    """Cells of thickets: 8-connected areas of heavy shrub of at least ``min_area`` square metres."""
    from scipy import ndimage

    dense = classes == heavy
    labels, count = ndimage.label(dense, structure=_EIGHT)
    if not count:
        return dense
    sizes = np.bincount(labels.ravel())[1:] * cell_area_m2
    return np.concatenate([[False], sizes >= min_area])[labels]


OFFSETS8 = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


def flow_receivers(dem: np.ndarray) -> np.ndarray:
    """D8: the flat index of the steepest lower neighbour of each cell (drop over distance), -1 where none is
    lower (a pit, a flat, the edge's outlets) or the cell has no height (O'Callaghan & Mark 1984)."""
    rows, cols = dem.shape
    z = np.where(np.isfinite(dem), dem, np.inf)
    best = np.zeros(dem.shape)
    receiver = np.full(dem.shape, -1, dtype=np.int64)
    index = np.arange(rows * cols, dtype=np.int64).reshape(rows, cols)
    for dr, dc in OFFSETS8:
        src = (slice(max(0, -dr), rows - max(0, dr)), slice(max(0, -dc), cols - max(0, dc)))
        dst = (slice(max(0, dr), rows - max(0, -dr)), slice(max(0, dc), cols - max(0, -dc)))
        with np.errstate(invalid="ignore"):
            drop = (z[src] - z[dst]) / math.hypot(dr, dc)
        drop[~np.isfinite(drop)] = 0.0
        better = drop > best[src]
        best[src] = np.where(better, drop, best[src])
        receiver[src] = np.where(better, index[dst], receiver[src])
    return receiver


def contributing_cells(receiver: np.ndarray) -> np.ndarray:
    """The number of cells draining through each cell, itself included: the sparse system (I - R^T) a = 1 of the
    receivers, solved at once (a tree: every cell drains to one receiver)."""
    from scipy.sparse import csr_matrix, identity
    from scipy.sparse.linalg import spsolve

    n = receiver.size
    r = receiver.ravel()
    has = np.flatnonzero(r >= 0)
    # row j of R^T holds the cells i draining into j
    drain = csr_matrix((np.ones(has.size), (r[has], has)), shape=(n, n))
    return spsolve((identity(n, format="csc") - drain.tocsc()), np.ones(n)).reshape(receiver.shape)


def receiver_lines(mask: np.ndarray, receiver: np.ndarray, transform) -> list:
    """Lines (shapely) from each cell of ``mask`` to its receiver when that is in ``mask`` too, merged."""
    import shapely

    r = receiver.ravel()
    cells = np.flatnonzero(mask.ravel() & (r >= 0))
    cells = cells[mask.ravel()[r[cells]]]
    if not cells.size:
        return []
    cols = mask.shape[1]
    x0, y0 = affine_apply(transform, ((cells % cols) + 0.5, (cells // cols) + 0.5))
    x1, y1 = affine_apply(transform, ((r[cells] % cols) + 0.5, (r[cells] // cols) + 0.5))
    parts = shapely.linestrings(np.stack([np.stack([x0, y0], -1), np.stack([x1, y1], -1)], axis=1))
    merged = shapely.line_merge(shapely.union_all(parts))
    return list(getattr(merged, "geoms", [merged]))


def near_cells(features: np.ndarray, cell_metres: float, within: float) -> np.ndarray:
    """Cells whose centre lies within ``within`` metres of the centre of a cell of ``features``."""
    from scipy import ndimage

    if not features.any():
        return np.zeros(features.shape, dtype=bool)
    return ndimage.distance_transform_edt(~features, sampling=cell_metres) <= within


# --- segments -----------------------------------------------------------------------------------------------------

def _neighbour_pairs(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pairs of different labels beside each other, 4-connected, both above 0; how many cell sides they share)."""
    pairs = []
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1, :], labels[1:, :])):
        m = (a != b) & (a > 0) & (b > 0)
        pairs.append(np.stack([np.minimum(a[m], b[m]), np.maximum(a[m], b[m])], axis=1))
    pairs = np.concatenate(pairs)
    if not len(pairs):
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    unique, counts = np.unique(pairs, axis=0, return_counts=True)
    return unique, counts


def _merge_small(labels: np.ndarray, region: np.ndarray, zones: np.ndarray, min_cells: int) -> np.ndarray:
    """Pieces of fewer than ``min_cells`` cells joined, smallest first, to the neighbour they share the longest
    edge with: one of their own ``region`` when they have such a neighbour, else one of their zone (a thicket never
    joins open ground); a piece with neither stays as it is."""
    count = int(labels.max())
    size = np.bincount(labels.ravel(), minlength=count + 1).astype(np.int64)
    size[0] = 0
    region_of = np.zeros(count + 1, dtype=np.int64)
    region_of[labels.ravel()] = region.ravel()
    zone_of = np.zeros(count + 1, dtype=np.int64)
    zone_of[labels.ravel()] = zones.ravel()
    pairs, shared = _neighbour_pairs(labels)
    edges: dict[int, dict[int, int]] = {}
    for (a, b), n in zip(pairs.tolist(), shared.tolist()):
        edges.setdefault(a, {})[b] = n
        edges.setdefault(b, {})[a] = n
    parent = np.arange(count + 1)
    import heapq

    heap = [(int(size[k]), k) for k in range(1, count + 1) if 0 < size[k] < min_cells]
    heapq.heapify(heap)
    while heap:
        s, k = heapq.heappop(heap)
        if parent[k] != k or size[k] != s or s >= min_cells or not edges.get(k):
            continue
        around = edges[k]
        same = {j: n for j, n in around.items() if region_of[j] == region_of[k]}
        pick = same or {j: n for j, n in around.items() if zone_of[j] == zone_of[k]}
        if not pick:
            continue
        j = max(pick, key=lambda v: (pick[v], -v))
        parent[k] = j
        size[j] += size[k]
        size[k] = 0
        for other, n in edges.pop(k).items():
            edges[other].pop(k, None)
            if other != j:
                edges[j][other] = edges[j].get(other, 0) + n
                edges[other][j] = edges[other].get(j, 0) + n
        if size[j] < min_cells:
            heapq.heappush(heap, (int(size[j]), j))
    for k in range(1, count + 1):  # the roots of the joined pieces
        root = k
        while parent[root] != root:
            root = parent[root]
        parent[k] = root
    return parent[labels]


def segment_cells(searchable: np.ndarray, walls: np.ndarray, cell_metres: float, target_m2: float,
                  zones=None) -> np.ndarray:
    """Segments (int32 labels 1...n, 0 outside ``searchable``): the searchable cells cut by the ``walls`` cells
    (roads, trails, drainages, ridges) and where ``zones`` changes (thickets and the rest), the parts larger than
    1.5 targets cut further by a square lattice of the target's area, pieces smaller than a quarter of the target
    joined to the neighbour they share the longest edge with (within their part when they can), the wall cells
    given to the nearest segment, then pieces under a sixteenth of that size (a cell walled in by drainages, the
    corner of a thicket) joined to their longest-edge neighbour of any kind, or, where they have none (cells amid
    cliffs or water), to the nearest segment; numbered by their first cell from north-west to south-east.

    Examples
    --------
    >>> import numpy as np
    >>> walls = np.zeros((4, 9), bool); walls[:, 4] = True  # a road down the middle
    >>> segment_cells(np.ones((4, 9), bool), walls, 1.0, 16.0)[0].tolist()
    [1, 1, 1, 1, 1, 2, 2, 2, 2]
    """
    from scipy import ndimage

    inner = searchable & ~walls
    if searchable.any() and not inner.any():  # walls everywhere (drainages from a threshold of a cell): the lattice
        inner = searchable
    zones = np.zeros(searchable.shape, dtype=np.int64) if zones is None else np.asarray(zones, dtype=np.int64)
    region = np.zeros(searchable.shape, dtype=np.int64)
    count = 0
    for z in np.unique(zones[inner]):  # 4-connected: a wall one cell wide drawn corner to corner still cuts
        lab, n = ndimage.label(inner & (zones == z))
        region[lab > 0] = lab[lab > 0] + count
        count += n
    if not count:
        return np.zeros(searchable.shape, dtype=np.int32)
    side = max(1, int(round(math.sqrt(target_m2) / cell_metres)))
    rows, cols = searchable.shape
    rr, cc = np.indices((rows, cols))
    tile = (rr // side) * (-(-cols // side)) + cc // side
    cells_of = np.bincount(region.ravel(), minlength=count + 1)
    big = (cells_of * cell_metres ** 2 > 1.5 * target_m2)[region] & (region > 0)
    key = np.where(big, region.astype(np.int64) * (tile.max() + 1) + tile, region.astype(np.int64) * (tile.max() + 1))
    key[region == 0] = -1
    pieces = np.zeros(searchable.shape, dtype=np.int64)
    _, inverse = np.unique(key[region > 0], return_inverse=True)
    pieces[region > 0] = inverse + 1
    split = np.zeros(searchable.shape, dtype=np.int64)  # a lattice square cut in two by a bend: two pieces
    n = 0
    for k, sl in enumerate(ndimage.find_objects(pieces), start=1):
        if sl is None:
            continue
        part, m = ndimage.label(pieces[sl] == k)
        split[sl][part > 0] = part[part > 0] + n
        n += m
    min_cells = max(1, int(0.25 * target_m2 / cell_metres ** 2))
    merged = _merge_small(split, region, zones, min_cells)
    if (searchable & walls).any():  # wall cells to the nearest segment
        _, (ir, ic) = ndimage.distance_transform_edt(merged == 0, return_indices=True)
        merged = np.where(searchable, merged[ir, ic], 0)
    merged[~searchable] = 0
    # a piece too small to search on its own (under a sixteenth of the smallest segment kept: a cell walled in by
    # drainages, a thicket's corner): to the neighbour it shares the longest edge with, whatever its kind
    flat = np.zeros(searchable.shape, dtype=np.int64)
    tiny = min(max(2, min_cells // 16), min_cells)  # never past the smallest piece kept: a tiny target keeps its cells
    merged = _merge_small(merged, flat, flat, tiny)
    alone = (np.bincount(merged.ravel()) < tiny)[merged] & (merged > 0)  # islands of cells amid cliffs or water
    if alone.any() and (merged[~alone] > 0).any():  # to the nearest segment (it gains a small part of its own)
        kept = np.where(alone, 0, merged)
        _, (ir, ic) = ndimage.distance_transform_edt(kept == 0, return_indices=True)
        merged = np.where(alone, kept[ir, ic], merged)
    # numbered by their first cell, north-west to south-east
    flat = merged.ravel()
    present = flat > 0
    firsts = {}
    for lab, pos in zip(flat[present].tolist(), np.flatnonzero(present).tolist()):
        firsts.setdefault(lab, pos)
    order = sorted(firsts, key=firsts.get)
    lookup = np.zeros(int(merged.max()) + 1, dtype=np.int32)
    lookup[order] = np.arange(1, len(order) + 1)
    return lookup[merged]


# --- detection ----------------------------------------------------------------------------------------------------

def coverage(sweep_width_m, speed_kmh, hours, area_m2):
    """Coverage of a search effort: sweep width (m) x track length (speed x searcher-hours, m) / area (m2)."""
    return np.asarray(sweep_width_m, float) * np.asarray(speed_kmh, float) * 1000.0 * np.asarray(hours, float) \
        / np.asarray(area_m2, float)


def detection_probability(cov):
    """Koopman's exponential detection function: POD = 1 - exp(-coverage).

    >>> round(float(detection_probability(1.0)), 4)
    0.6321
    """
    return 1.0 - np.exp(-np.asarray(cov, dtype=np.float64))


# --- routes -------------------------------------------------------------------------------------------------------

def cell_path(predecessors: np.ndarray, target: int) -> list[int]:
    """The flat cell indices of the shortest path to ``target`` from its source, source first (scipy's
    predecessors: -9999 at a source and where no path reaches); [] where none reaches it."""
    path = [int(target)]
    while predecessors[path[-1]] >= 0:
        path.append(int(predecessors[path[-1]]))
        if len(path) > predecessors.size:
            raise RuntimeError("the predecessors hold a cycle")
    return path[::-1]


def corridor_open(blocked: np.ndarray, cell_metres: float, width_m: float) -> np.ndarray:
    """Cells where a team ``width_m`` wide fits: the edge of the nearest blocked cell at least half the width from
    the cell's centre (its centre's distance less half a cell)."""
    from scipy import ndimage

    if not blocked.any():
        return np.ones(blocked.shape, dtype=bool)
    d = ndimage.distance_transform_edt(~blocked, sampling=cell_metres)
    return (d - cell_metres / 2.0) >= width_m / 2.0 - 1e-9
