"""Pass 1 of the rasters over a chunk (lidar/scan.py): the compiled and numpy forms against a point-by-point
reference written here, on points with every case the pass distinguishes (outside the grid, withheld, noise, ground,
water, return numbers 0 to 20, tied heights, every halo strip), from strided LAS integers as laspy gives them."""

import numpy as np
import pytest
from affine import Affine

from gistools.grid import Grid

from gistools.lidar.accumulate import surface_classes
from gistools.lidar.scan import ScanGrids, _kernel, _scan_chunk_numpy, scan_chunk

BARE = {2, 9}
EDGES = (10.0, 90.0, 10.0, 90.0)  # west + b, east - b, south + b, north - b of a 100 x 100 tile with a 10 unit buffer
GRID = Grid(Affine(5.0, 0, 0.0, 0, -5.0, 100.0), 20, 20)  # the tile's 5-unit cells
SCALES, OFFSETS = (0.5, 0.5, 0.5), (0.0, 0.0, 100.0)


def _points(rng, m):
    """Points on a 0.5 lattice of a 100 x 100 tile (some outside the grid), as a LAS record array: X, Y, Z are
    strided int32 views (scale 0.5, offsets 0 / 0 / 100), heights in whole units (many ties)."""
    rec = np.zeros(m, dtype=[("X", "<i4"), ("Y", "<i4"), ("Z", "<i4"), ("pad", "u1", 5)])
    rec["X"] = rng.integers(-4, 204, m)
    rec["Y"] = rng.integers(-4, 204, m)
    rec["Z"] = 2 * rng.integers(0, 4, m)
    cls = rng.choice(np.array([1, 2, 2, 2, 3, 5, 7, 9, 18], np.uint8), m)
    rn = rng.integers(0, 21, m).astype(np.uint8)
    rn[rng.random(m) < 0.6] = 1
    withheld = rng.random(m) < 0.05
    x, y = rec["X"] * 0.5, rec["Y"] * 0.5
    col, row = np.floor(x / 5.0), 19 - np.floor(y / 5.0)
    cell = np.where((col >= 0) & (col < 20) & (row >= 0) & (row < 20), row * 20 + col, -1).astype(np.int64)
    return rec, x, y, cls, rn, withheld, cell


def _reference(parts, surface_table, keep_first, keep_ground, track_top):
    """Point by point: the grids and, per chunk, the ground records, halo records and sides, boxes, first returns."""
    n = 400
    dsm, top = np.full(n, -np.inf), np.full(n, 255, np.uint8)
    bare_first, gcount, wcount = np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64)
    by_class, by_return = np.zeros(256, np.int64), np.zeros(16, np.int64)
    chunks = []
    for rec, x, y, cls, rn, withheld, cell in parts:
        best, win, grec, hrec, hside, first = {}, {}, [], [], [], []
        boxes = [[np.inf, np.inf, -np.inf, -np.inf] for _ in range(5)]
        outside = 0
        for i in range(len(cell)):
            by_class[cls[i]] += 1
            by_return[min(rn[i], 15)] += 1
            c = cell[i]
            if c < 0:
                outside += 1
                continue
            if withheld[i]:
                continue
            if surface_table[cls[i]] and rn[i] <= 1:
                z = rec["Z"][i] * 0.5 + 100.0
                if keep_first:
                    if cls[i] in BARE:
                        bare_first[c] += 1
                    else:
                        first.append((c, np.float32(z)))
                if c not in best or z > best[c]:
                    best[c], win[c] = z, cls[i]
                elif z == best[c] and (cls[i] in BARE or win[c] not in BARE):
                    win[c] = cls[i]
            if not keep_ground:
                continue
            wcount[c] += cls[i] == 9
            if cls[i] != 2:
                continue
            gcount[c] += 1
            xyz = (rec["X"][i], rec["Y"][i], rec["Z"][i])
            grec.append(xyz)
            side = 1 if x[i] < EDGES[0] else 2 if x[i] > EDGES[1] else 3 if y[i] < EDGES[2] else 4 if y[i] > EDGES[3] else 0
            if side:
                hrec.append(xyz)
                hside.append(side)
            for b in {0, side}:
                boxes[b] = [min(boxes[b][0], x[i]), min(boxes[b][1], y[i]), max(boxes[b][2], x[i]), max(boxes[b][3], y[i])]
        for c in best:  # the chunk's maxima merged into the earlier chunks' (ties: the chunk's class when bare)
            if track_top and (best[c] > dsm[c] or (best[c] == dsm[c] and win[c] in BARE)):
                top[c] = win[c]
            dsm[c] = max(dsm[c], best[c])
        chunks.append((grec, hrec, hside, boxes, first, outside))
    return (dsm, top, bare_first, gcount, wcount, by_class, by_return), chunks


@pytest.mark.parametrize("keep", [(True, True, True), (False, False, False), (True, False, True), (False, True, False)])
@pytest.mark.parametrize("chunks", [1, 3])
def test_scan_chunk_matches_a_point_by_point_reference(keep, chunks):
    if _kernel() is None:
        pytest.fail("the compiled kernel is not built (pip install -e . with a C compiler)")
    keep_first, keep_ground, track_top = keep
    rng = np.random.default_rng(5 + chunks)
    parts = [_points(rng, 3000) for _ in range(chunks)]
    table = surface_classes(None)  # every class but noise 7, 18
    grids_ref, chunks_ref = _reference(parts, table, keep_first, keep_ground, track_top)
    for form in (scan_chunk, _scan_chunk_numpy):
        g = ScanGrids.empty(400, track_top=track_top, keep_first=keep_first, keep_ground=keep_ground)
        for (rec, x, y, cls, rn, withheld, cell), (grec, hrec, hside, boxes, first, outside) in zip(parts, chunks_ref):
            args = (g, GRID, (rec["X"], rec["Y"], rec["Z"]), SCALES, OFFSETS, cls, rn, withheld)
            s = form(*args, surface=table, halo_edges=EDGES) if form is scan_chunk else form(*args, table, EDGES)
            assert s.cell.dtype == np.int64 and np.array_equal(s.cell, cell)
            assert s.outside == outside
            assert s.ground_xyz.dtype == np.int32 and s.ground_xyz.tolist() == [list(r) for r in grec]
            assert s.halo_xyz.tolist() == [list(r) for r in hrec] and s.halo_side.tolist() == hside
            if keep_ground:
                assert np.array_equal(s.boxes, np.array(boxes))
            assert s.first_cell.tolist() == [c for c, _ in first]
            assert s.first_z.dtype == np.float32 and s.first_z.tolist() == [z for _, z in first]
        got = (g.dsm, g.top_class, g.bare_first, g.ground_count, g.water_count, g.by_class, g.by_return)
        for a, b in zip(got, grids_ref):
            assert np.array_equal(a, b), form.__name__


def test_scan_chunk_gives_the_ground_points_indices_when_asked():
    rng = np.random.default_rng(3)
    rec, x, y, cls, rn, withheld, cell = _points(rng, 2000)
    g = ScanGrids.empty(400, track_top=False, keep_first=False, keep_ground=True)
    s = scan_chunk(g, GRID, (rec["X"], rec["Y"], rec["Z"]), SCALES, OFFSETS, cls, rn, withheld,
                   surface=surface_classes(None), halo_edges=EDGES, ground_index=True)
    want = np.flatnonzero((cell >= 0) & ~withheld & (cls == 2))
    assert np.array_equal(s.ground_index, want)
    assert np.array_equal(s.ground_xyz[:, 0], rec["X"][want])
