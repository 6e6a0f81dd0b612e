"""The order of the rasters' two passes over a block of tiles (pure: names in, names out).

Tiles are read (pass 1) north to south, west to east. A tile is gridded (pass 2) as soon as it and the
neighbours it depends on are read, and a tile's scratch files can go once every tile that reads them is
gridded: the scratch holds a front of a few tile rows, not the whole county.
"""

from __future__ import annotations

__all__ = ["TwoPassSchedule"]


class TwoPassSchedule:
    """``scan_order``: the tiles to read, in order; ``todo``: those to grid; ``deps[name]``: the tiles a tile to grid
    reads (itself and its neighbours)."""

    def __init__(self, scan_order: list[str], todo: set[str], deps: dict[str, set[str]]):
        self.scan_order = list(scan_order)
        self.grid_order = [n for n in scan_order if n in todo]
        self.deps = deps
        self.users = {v: {n for n in todo if v in deps[n]} for v in scan_order}
        self.scanned: set[str] = set()
        self.gridded: set[str] = set()
        self._started: set = set()
        self._releasable: list[str] = []
        self.scratch_peak = 0

    def next_task(self, failed) -> tuple[str, str] | None:
        """("grid", name) of the first tile whose dependencies are read, else ("scan", name) of the next tile to
        read, else None. ``failed(name)``: its own read failed, so it is not gridded (its dependencies are freed)."""
        for n in self.grid_order:
            if n not in self._started and self.deps[n] <= self.scanned:
                self._started.add(n)
                if failed(n):
                    self._grid_done(n)
                    continue
                return "grid", n
        for n in self.scan_order:
            if ("scan", n) not in self._started:
                self._started.add(("scan", n))
                return "scan", n
        return None

    def done(self, kind: str, name: str) -> None:
        """A tile was read (kind "scan") or gridded ("grid"), successfully or not."""
        if kind == "scan":
            self.scanned.add(name)
            live = len(self.scanned) - sum(self.users[v] <= self.gridded for v in self.scanned)
            self.scratch_peak = max(self.scratch_peak, live)
        else:
            self._grid_done(name)

    def _grid_done(self, name: str) -> None:
        self.gridded.add(name)
        self._releasable += [v for v in self.deps[name] if self.users[v] <= self.gridded]

    def releasable(self) -> list[str]:
        """The tiles whose scratch no tile still needs (each once... or again, harmlessly); cleared on reading."""
        out, self._releasable = self._releasable, []
        return out
