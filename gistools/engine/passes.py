"""The one tile engine: a block of tiles in two passes, each tile seeing its neighbours.

Pass 1 reads each tile (``read``: what its neighbours will need of it, kept in a scratch folder); pass 2 makes
each tile's products (``make``) as soon as it and its neighbours are read, and the scratch a tile left is freed
once no tile still to make needs it (:class:`~gistools.engine.schedule.TwoPassSchedule`: n log n, a front of a few
tile rows in the scratch, not the county). Tasks run inline or in a pool (local processes or a Dask cluster, the
same door); a tile that fails is marked and the batch goes on; a full disk or a read-only output stops the run;
Ctrl-C and cancellation stop it with the pool. ``gistools rasters`` and the buffered commands (``ground``,
``normalize``, ``metrics``, ``chm``) run through it; the shrub chain's steps are its single-pass stages
(:func:`~gistools.engine.batch.run_each`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..errors import Cancelled
from .batch import drive, fail, run_each, timed, worker_timed
from .schedule import TwoPassSchedule

__all__ = ["Passes", "Stage", "TileState", "run_stages", "run_two_passes", "scan_order"]


@dataclass
class TileState:
    """A tile's line in report.json, as every tile command has it; each command's state adds its own fields."""

    name: str
    path: str
    status: str = "ok"  # ok / failed / skipped (kept from an earlier run)
    error: str | None = None  # one line: the file, the problem, the fix
    warnings: list = field(default_factory=list)


def scan_order(bounds: dict) -> list[str]:
    """Tile names in reading order: north to south, then west to east (``bounds``: name -> (w, s, e, n))."""
    return sorted(bounds, key=lambda n: (-bounds[n][3], bounds[n][0]))


@dataclass
class Passes:
    """What a command gives the engine.

    read(name, inline) / make(name): the task of a tile's pass 1 / pass 2, as (function, arguments); ``inline``:
    the task runs in this process, on its thread or a pool's (it may then take a progress callback). on_read / on_made(name, value,
    seconds): take a task's result. A failed read marks the tile's read state (``read_results``, else its state)
    and, for a tile to make, its state: it is not made. release(names): free the scratch of tiles no tile still needs. tick(message): one task done (progress)."""

    read: Callable
    make: Callable
    on_read: Callable
    on_made: Callable
    results: dict  # name -> the state of a tile to make (``status`` / ``error``): failures are marked there
    read_results: dict | None = None  # name -> the state of a tile's read, where it is kept apart (else results)
    release: Callable = lambda names: None
    tick: Callable = lambda message: None
    verbs: tuple = ("read", "made")


def run_two_passes(order: list[str], todo: set[str], deps: dict[str, set[str]], passes: Passes, pool, *,
                   owned: bool, out=None, in_flight: int | None = None) -> int:
    """Read the tiles of ``order`` (in that order) and make those of ``todo``, each after the tiles of
    ``deps[name]`` (itself and its neighbours) are read; returns the scratch's peak in tiles.

    ``pool``: None (inline), a ThreadPool, a ProcessPool or a DaskPool; an ``owned`` pool is closed at the end. ``out``: the
    output folder (a write failure there stops the run; it is no tile's fault)."""
    schedule = TwoPassSchedule(order, todo, deps)
    pending: dict = {}

    def finish(kind, name, value, seconds, err):
        if err is not None and kind == "scan" and passes.read_results is not None:
            fail(passes.read_results[name], err, out)
            if name in passes.results:  # its own read failed: the tile is not made
                passes.results[name].status, passes.results[name].error = "failed", passes.read_results[name].error
        elif err is not None:
            fail(passes.results[name], err, out)
        elif kind == "scan":
            passes.on_read(name, value, seconds)
        else:
            passes.on_made(name, value, seconds)
        schedule.done(kind, name)
        passes.release(schedule.releasable())
        passes.tick(f"{name} {passes.verbs[0] if kind == 'scan' else passes.verbs[1]}")

    in_process = pool is None or getattr(pool, "shares_process", False)  # a tile's own progress can be shown

    def start(kind, name):
        try:
            fn, args = passes.read(name, in_process) if kind == "scan" else passes.make(name)
        except Cancelled:
            raise
        except Exception as err:  # one bad tile never stops the batch; it is reported
            return finish(kind, name, None, 0.0, err)
        if pool is not None:
            pending[pool.submit(worker_timed, fn, args)] = (kind, name)
            return
        try:
            value, seconds = timed(fn, args)
        except Cancelled:
            raise
        except Exception as err:
            return finish(kind, name, None, 0.0, err)
        finish(kind, name, value, seconds, None)

    def next_task():
        task = schedule.next_task(lambda name: passes.results[name].status == "failed")
        passes.release(schedule.releasable())
        return task

    # tasks in flight: a worker's next task queued behind its current one hides the hand-over (processes, Dask);
    # threads take theirs at once, and tasks queued ahead would only read tiles ahead into the scratch
    width = in_flight or (1 if pool is None else getattr(pool, "queued", 2) * max(getattr(pool, "workers", 1), 1))
    drive(pool, owned, width, next_task, start, pending, finish)
    return schedule.scratch_peak


@dataclass
class Stage:
    """A single-pass stage over tiles (the shrub chain's steps): ``fn(*args(name))`` per tile, ``on_done(name,
    value, seconds)`` per result, then ``then(tiles)`` once every tile of the stage is done (a barrier: a mosaic the
    next stage reads across tiles, class breaks over the whole block). ``tiles``: the tiles it runs on, None for
    those still ok when it starts."""

    verb: str
    fn: Callable
    args: Callable
    on_done: Callable
    then: Callable | None = None
    tiles: list | None = None


def run_stages(stages: list, results: dict, pool, tick, out=None) -> None:
    """Run ``stages`` in order over the tiles (``results``: name -> the tile's state; a tile that fails in a stage
    is marked failed there and left out of the next stages), inline or in ``pool`` (processes or Dask)."""
    for stage in stages:
        names = stage.tiles if stage.tiles is not None else [n for n, st in results.items() if st.status == "ok"]
        run_each(stage.fn, [stage.args(n) for n in names], pool, results, names, stage.on_done, tick, stage.verb, out)
        if stage.then is not None:
            stage.then([n for n in names if results[n].status == "ok"])
