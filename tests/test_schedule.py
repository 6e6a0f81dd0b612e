"""The two-pass schedule and the neighbour search in n log n: the same tasks, in the same order, as the plain
all-pairs search and the rescanning schedule written out below as the reference."""

from __future__ import annotations

import random

import pytest

from gistools.engine.schedule import TwoPassSchedule, neighbour_pairs


def pairs_by_brute_force(bounds, d):
    out = []
    for i, (w, s, e, n) in enumerate(bounds):
        out.append([j for j, (ow, os_, oe, on) in enumerate(bounds)
                    if j != i and ow <= e + d and oe >= w - d and os_ <= n + d and on >= s - d])
    return out


class Rescanning:
    """The schedule as first written: a scan of every tile at each step (quadratic), kept as the reference."""

    def __init__(self, scan_order, todo, deps):
        self.scan_order, self.grid_order, self.deps = list(scan_order), [n for n in scan_order if n in todo], deps
        self.users = {v: {n for n in todo if v in deps[n]} for v in scan_order}
        self.scanned, self.gridded, self._started, self._releasable, self.scratch_peak = set(), set(), set(), [], 0

    def next_task(self, failed):
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

    def done(self, kind, name):
        if kind == "scan":
            self.scanned.add(name)
            live = len(self.scanned) - sum(self.users[v] <= self.gridded for v in self.scanned)
            self.scratch_peak = max(self.scratch_peak, live)
        else:
            self._grid_done(name)

    def _grid_done(self, name):
        self.gridded.add(name)
        self._releasable += [v for v in self.deps[name] if self.users[v] <= self.gridded]

    def releasable(self):
        out, self._releasable = self._releasable, []
        return out


def blocks(seed):
    rng = random.Random(seed)
    cols, rows = rng.randint(1, 9), rng.randint(1, 9)
    size = 1000.0
    bounds = [(c * size, r * size, (c + 1) * size - rng.choice([0, 0, 0.5]), (r + 1) * size)
              for r in range(rows) for c in range(cols) if rng.random() > 0.15]
    bounds += [(rng.uniform(0, cols * size),) * 2 for _ in range(rng.randint(0, 2))]  # odd tiles: a point's box
    bounds = [b if len(b) == 4 else (b[0], b[1], b[0], b[1]) for b in bounds]
    return bounds, rng.choice([0.0, 10.0, 700.0])


@pytest.mark.parametrize("all_pairs", [0, 512], ids=["rtree", "numpy"])
@pytest.mark.parametrize("seed", range(40))
def test_neighbours_are_those_of_the_all_pairs_search(seed, all_pairs, monkeypatch):
    """Both searches (shapely's R-tree for many boxes, numpy's all pairs at once for few) find the pairs of a loop
    over every pair."""
    from gistools.engine import schedule

    monkeypatch.setattr(schedule, "ALL_PAIRS", all_pairs)
    bounds, d = blocks(seed)
    assert neighbour_pairs(bounds, d) == pairs_by_brute_force(bounds, d)


@pytest.mark.parametrize("all_pairs", [0, 512], ids=["rtree", "numpy"])
def test_an_inverted_box_is_taken_as_its_envelope_by_both_searches(all_pairs, monkeypatch):
    """A header whose minimum lies past its maximum (an empty tile's) is its envelope for both searches."""
    from gistools.engine import schedule

    monkeypatch.setattr(schedule, "ALL_PAIRS", all_pairs)
    assert neighbour_pairs([(0, 0, 10, 10), (20, 10, 10, 0), (50, 50, 60, 60)], 1.0) == [[1], [0], []]


def _drive(schedule, failed, rng, in_flight):
    """Run a schedule as the engine does, finishing the running tasks in a random order; the log of events."""
    log, running = [], []
    while True:
        while len(running) < in_flight and (task := schedule.next_task(lambda n: n in failed)) is not None:
            running.append(task)
            log.append(("start", task))
        if not running:
            break
        kind, name = running.pop(rng.randrange(len(running)))
        schedule.done(kind, name)
        log.append(("done", kind, name, tuple(sorted(set(schedule.releasable())))))
    return log, schedule.scratch_peak


@pytest.mark.parametrize("seed", range(40))
def test_the_schedule_gives_the_rescanning_schedules_tasks_in_its_order(seed):
    bounds, d = blocks(seed)
    names = [f"t{i:03d}" for i in range(len(bounds))]
    pairs = neighbour_pairs(bounds, d)
    rng = random.Random(seed)
    todo = {n for n in names if rng.random() > 0.2}
    needed = todo | {names[j] for i, n in enumerate(names) if n in todo for j in pairs[i]}
    scan = sorted((n for n in names if n in needed), key=lambda n: (-bounds[names.index(n)][3], bounds[names.index(n)][0]))
    deps = {n: ({n} | {names[j] for j in pairs[names.index(n)]}) & needed for n in todo}
    failed = {n for n in todo if rng.random() < 0.1}
    in_flight = rng.choice([1, 2, 4])
    new = _drive(TwoPassSchedule(scan, todo, deps), failed, random.Random(seed), in_flight)
    old = _drive(Rescanning(scan, todo, deps), failed, random.Random(seed), in_flight)
    assert new[0] == old[0] and new[1] == old[1]
