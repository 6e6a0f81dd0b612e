"""The order of the rasters' two passes over a block of tiles (pure: names in, names out).

Tiles are read (pass 1) north to south, west to east. A tile is gridded (pass 2) as soon as it and the
neighbours it depends on are read, and a tile's scratch files can go once every tile that reads them is
gridded: the scratch holds a front of a few tile rows, not the whole county.

Every step costs the tile's own neighbours, never the block: a tile to grid keeps a count of its neighbours not
yet read and enters a heap (by its place in the order) when that count reaches 0; a tile read keeps a count of
the tiles still to grid from it. A state of 10^5 tiles is scheduled in n log n.
"""

from __future__ import annotations

import heapq

__all__ = ["TwoPassSchedule", "neighbour_pairs"]

ALL_PAIRS = 512  # boxes up to which neighbour_pairs tests every pair (numpy) rather than build an R-tree


def neighbour_pairs(bounds, distance: float, reach=None) -> list[list[int]]:
    """For each box (w, s, e, n) of ``bounds``, the indices of the other boxes within ``distance`` of it (edges
    included), or that meet its box of ``reach`` (a box per box, where given), through an R-tree (shapely.STRtree):
    n log n, not all pairs. Up to ALL_PAIRS boxes, every pair is tested at once with numpy instead (the same
    inclusive box test, without importing shapely: a small run starts sooner)."""
    import numpy as np

    b = np.asarray(bounds, dtype=float).reshape(-1, 4)
    if len(b) == 0:
        return []
    b = _envelopes(b)  # an inverted box (an empty tile's header) is its envelope, then grown
    r = _envelopes(np.asarray(reach, dtype=float).reshape(-1, 4)) if reach is not None else None
    g = r if r is not None else b + np.array([-distance, -distance, distance, distance])
    if len(b) <= ALL_PAIRS:
        meet = ((g[:, None, 0] <= b[None, :, 2]) & (b[None, :, 0] <= g[:, None, 2])
                & (g[:, None, 1] <= b[None, :, 3]) & (b[None, :, 1] <= g[:, None, 3]))
        query, found = np.nonzero(meet)
    else:
        import shapely

        boxes = shapely.box(b[:, 0], b[:, 1], b[:, 2], b[:, 3])
        grown = shapely.box(g[:, 0], g[:, 1], g[:, 2], g[:, 3])
        query, found = shapely.STRtree(boxes).query(grown)  # the envelopes meet: edges touching count
    out: list[list[int]] = [[] for _ in range(len(b))]
    for i, j in zip(query.tolist(), found.tolist()):
        if i != j:
            out[i].append(j)
    return [sorted(o) for o in out]


def _envelopes(boxes):
    """Boxes (w, s, e, n) as envelopes, west <= east and south <= north, as shapely takes an inverted box."""
    import numpy as np

    return np.column_stack([np.minimum(boxes[:, 0], boxes[:, 2]), np.minimum(boxes[:, 1], boxes[:, 3]),
                            np.maximum(boxes[:, 0], boxes[:, 2]), np.maximum(boxes[:, 1], boxes[:, 3])])


def _users(scan_order, todo, deps) -> dict[str, set[str]]:
    """{tile: the tiles to grid that read it}, the inverse of ``deps``."""
    users: dict[str, set[str]] = {v: set() for v in scan_order}
    for n in todo:
        for v in deps[n]:
            users.setdefault(v, set()).add(n)
    return users


class TwoPassSchedule:
    """``scan_order``: the tiles to read, in order; ``todo``: those to grid; ``deps[name]``: the tiles a tile to grid
    reads (itself and its neighbours)."""

    def __init__(self, scan_order: list[str], todo: set[str], deps: dict[str, set[str]]):
        self.scan_order = list(scan_order)
        self.grid_order = [n for n in scan_order if n in todo]
        self.deps = deps
        self.users = _users(scan_order, todo, deps)
        self.scanned: set[str] = set()
        self.gridded: set[str] = set()
        self._rank = {n: k for k, n in enumerate(self.grid_order)}
        self._unread = {n: len(deps[n]) for n in self.grid_order}  # its dependencies not yet read
        self._ready = [self._rank[n] for n in self.grid_order if self._unread[n] == 0]
        heapq.heapify(self._ready)
        self._to_grid = {v: len(u) for v, u in self.users.items()}  # tiles still to grid from v's scratch
        self._next_scan = 0
        self._released = 0  # tiles read whose scratch no tile needs any more
        self._releasable: list[str] = []
        self.scratch_peak = 0

    def next_task(self, failed) -> tuple[str, str] | None:
        """("grid", name) of the first tile whose dependencies are read, else ("scan", name) of the next tile to
        read, else None. ``failed(name)``: its own read failed, so it is not gridded (its dependencies are freed)."""
        while self._ready:
            n = self.grid_order[heapq.heappop(self._ready)]
            if failed(n):
                self._grid_done(n)
                continue
            return "grid", n
        if self._next_scan < len(self.scan_order):
            self._next_scan += 1
            return "scan", self.scan_order[self._next_scan - 1]
        return None

    def done(self, kind: str, name: str) -> None:
        """A tile was read (kind "scan") or gridded ("grid"), successfully or not."""
        if kind == "scan":
            if name in self.scanned:
                return
            self.scanned.add(name)
            if self._to_grid.get(name, 0) == 0:
                self._released += 1
            for user in self.users.get(name, ()):
                self._unread[user] -= 1
                if self._unread[user] == 0:
                    heapq.heappush(self._ready, self._rank[user])
            self.scratch_peak = max(self.scratch_peak, len(self.scanned) - self._released)
        else:
            self._grid_done(name)

    def _grid_done(self, name: str) -> None:
        if name in self.gridded:
            return
        self.gridded.add(name)
        for v in self.deps[name]:
            self._to_grid[v] -= 1
            if self._to_grid[v] == 0:
                if v in self.scanned:
                    self._released += 1
                self._releasable.append(v)

    def releasable(self) -> list[str]:
        """The tiles whose scratch no tile still needs (each once); cleared on reading."""
        out, self._releasable = self._releasable, []
        return out
