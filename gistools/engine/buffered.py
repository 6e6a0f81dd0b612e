"""Tiles that see their neighbours' points: two passes over a folder of tiles, shared by ``gistools ground``,
``gistools normalize`` and ``gistools metrics``.

Pass 1 decodes each tile once and keeps the points within ``buffer`` of its edges (what its neighbours need)
in a scratch folder; pass 2 runs a function on each tile with its own points and its neighbours' strips, so a
tiled run gives what a run on the merged tiles gives. Tiles run inline, on local processes or on Dask; one
bad tile is reported and the others go on.
"""

from __future__ import annotations

from ..parameters import option, render

import logging
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.outdir import SCRATCH_PREFIX
from ..io import decoded
from ..io.points import parse_crs_text, points_in_box, read_all_points, read_tile_info
from ..progress import report
from .batch import ThreadPool, make_pool
from .passes import Passes, run_two_passes, scan_order
from .passes import TileState as EngineTileState
from .schedule import neighbour_pairs

log = logging.getLogger(__name__)

__all__ = ["TileState", "RasterTileState", "RASTER_FOUND", "PointTileState", "gridded_tile", "gridded_todo", "marked_todo", "STRIP_FIELDS", "neighbour_table", "points_around", "buffered_passes", "read_headers", "batch_inputs",
           "write_batch_report"]

STRIP_FIELDS = ("x", "y", "z", "return_number", "number_of_returns", "classification", "intensity")
EVERYWHERE = (-np.inf, -np.inf, np.inf, np.inf)


def batch_inputs(inputs, settings, jobs, scheduler) -> tuple[list, object]:
    """Every option checked (``settings.validate()``, the scheduler, --jobs) before anything is read or written; then
    (the tile paths of ``inputs``, the --crs override or None)."""
    from ..io.points import parse_crs_text
    from ..io.tiles import find_tiles
    from ..validation import check_jobs, check_scheduler

    settings.validate()
    check_scheduler(scheduler)
    check_jobs(jobs)
    override = parse_crs_text(settings.crs) if settings.crs else None
    return find_tiles(inputs), override


def write_batch_report(out: Path, tool: str, crs_label_text, settings, states: dict, started: float, **extra) -> dict:
    """report.json of a batch command (atomic): tool, crs, settings, ``extra``, the tiles, their counts and the time."""
    import time
    from dataclasses import asdict

    from .record import write_folder_report

    result = {"tool": tool, "crs": crs_label_text, "settings": asdict(settings), **extra,
              "tiles": [asdict(st) for st in states.values()],
              "counts": {k: sum(st.status == k for st in states.values()) for k in ("ok", "skipped", "failed")},
              "seconds": round(time.time() - started, 3)}
    return write_folder_report(out, result)  # the folder's earlier runs kept (of this command: others are refused)


def read_headers(paths, override, make_state, output_name=None, out: Path | None = None) -> tuple[dict, dict]:
    """({name: make_state(name, path)}, {name: TileInfo} of the headers that read); a tile that does not read, or
    whose output (``out / output_name(path)``) would be the input itself, is marked failed."""
    from ..errors import GistoolsError
    from ..projdata import ensure_proj_data

    ensure_proj_data()  # once, before any tile: a missing PROJ is the installation's, never a tile's error
    states, infos = {}, {}
    for p in paths:
        st = states[p.stem] = make_state(p.stem, str(p))
        if output_name is not None and Path(p).resolve().parent == Path(out).resolve() and output_name(p) == p.name:
            st.status, st.error = "failed", render(f"{p}: the output would overwrite this input; "
                                                    f"choose another {option('out')}")
            continue
        try:
            infos[p.stem] = read_tile_info(p, override)
        except GistoolsError as err:
            st.status, st.error = "failed", str(err)
    return states, infos


def neighbour_table(infos: dict, buffer: float, reach: dict | None = None) -> dict[str, list[str]]:
    """{tile: paths of the tiles of ``infos`` (name -> TileInfo) whose bounds come within ``buffer`` of it, or meet
    its box in ``reach`` (name -> box) where given} (an R-tree: n log n)."""
    names = list(infos)
    pairs = neighbour_pairs([infos[n].bounds for n in names], buffer,
                            None if reach is None else [reach[n] for n in names])
    return {name: [str(infos[names[j]].path) for j in js] for name, js in zip(names, pairs)}


STRIP_BINS = 16  # a strip's points are kept in the order of a 16 x 16 grid of its tile: a neighbour reads its side only


def _strip_tile(name: str, path: str, crs_text, buffer: float, scratch: str, rule=None, keep: bool = False) -> dict:
    """Pass 1: the points of a tile within ``buffer`` of its edges (or those ``rule(x, y)`` keeps), saved in the
    scratch folder (so each tile is decoded twice in a run, not once per neighbour), ordered by the cells of a
    STRIP_BINS x STRIP_BINS grid of the tile (file order within a cell) so that ``_strip_in_box`` reads only the
    cells that reach a box. ``keep``: pass 2 runs in this process; a compressed tile is kept decoded for it
    (io.decoded), where it fits."""
    info = read_tile_info(path, parse_crs_text(crs_text) if crs_text else None)
    if keep and decoded.worth_keeping(info):
        las = read_all_points(path)
        pts = points_in_box(info, EVERYWHERE, fields=STRIP_FIELDS, decoded=las)
        decoded.keep(path, las)
    else:
        pts = points_in_box(info, EVERYWHERE, fields=STRIP_FIELDS)
    w, s, e, n = info.bounds
    if rule is None:
        inner = (w + buffer, s + buffer, e - buffer, n - buffer)
        deep = (pts["x"] > inner[0]) & (pts["x"] < inner[2]) & (pts["y"] > inner[1]) & (pts["y"] < inner[3])
        keep = np.flatnonzero(~deep)
    else:  # every point the rule keeps, wherever in the tile: an empty inner box (_sources never reads the tile)
        inner = (w, s, w, s)
        keep = np.flatnonzero(rule(pts["x"], pts["y"]))
    grid = _strip_grid(info.bounds)
    key = _strip_bin(pts["x"][keep], grid[0], grid[2]) + STRIP_BINS * _strip_bin(pts["y"][keep], grid[1], grid[3])
    order = keep[np.argsort(key.astype(np.uint16), kind="stable")]  # 16-bit keys: numpy's radix sort
    starts = np.concatenate([[0], np.cumsum(np.bincount(key, minlength=STRIP_BINS * STRIP_BINS))]).astype(np.int64)
    records = np.empty(len(order), np.dtype([(k, pts[k].dtype) for k in STRIP_FIELDS]))
    for k in STRIP_FIELDS:
        records[k] = pts[k][order]
    target = Path(scratch) / f"{name}.strip"
    with open(target, "wb") as f:  # the grid, each cell's first record, the records (three .npy arrays, no zip)
        np.save(f, np.asarray(grid, np.float64))
        np.save(f, starts)
        np.save(f, records)
    return {"strip": str(target), "inner": inner}


def _strip_grid(bounds) -> tuple[float, float, float, float]:
    """(west, south, cell width, cell height) of the STRIP_BINS x STRIP_BINS grid of a tile's bounds."""
    w, s, e, n = (float(v) for v in bounds)
    return w, s, (e - w) / STRIP_BINS if e > w else 1.0, (n - s) / STRIP_BINS if n > s else 1.0


def _strip_bin(v, origin: float, size: float):
    """The grid column (row) of coordinates ``v``, points beyond the tile's bounds in the edge cells. Monotonic in
    ``v``: a box's first and last cells hold every point of the box."""
    return np.clip(np.floor((np.asarray(v, np.float64) - origin) / size), 0, STRIP_BINS - 1).astype(np.int64)


def _no_strip(bounds) -> dict:
    """Pass 1 of a tile whose points no other tile needs: nothing to read."""
    return {"strip": None, "inner": list(bounds)}


def _strip_in_box(path: str, box) -> dict:
    """The points of a strip inside ``box``: only the records of the grid cells that reach it are read."""
    w, s, e, n = box
    with open(path, "rb") as f:
        gw, gs, dx, dy = np.load(f)
        starts = np.load(f)
        version = np.lib.format.read_magic(f)
        _shape, _fortran, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                                  else np.lib.format.read_array_header_2_0(f))
        base = f.tell()
        c0, c1 = (int(v) for v in _strip_bin([w, e], gw, dx))
        r0, r1 = (int(v) for v in _strip_bin([s, n], gs, dy))
        spans = []
        for r in range(r0, r1 + 1):
            a, b = int(starts[r * STRIP_BINS + c0]), int(starts[r * STRIP_BINS + c1 + 1])
            if spans and spans[-1][1] == a:
                spans[-1][1] = b
            elif b > a:
                spans.append([a, b])
        parts = []
        for a, b in spans:
            f.seek(base + a * dtype.itemsize)
            data = f.read((b - a) * dtype.itemsize)
            if len(data) != (b - a) * dtype.itemsize:
                raise OSError(f"{path}: the neighbour's strip is cut short (the scratch disk filled?)")
            parts.append(np.frombuffer(data, dtype))
    records = np.concatenate(parts) if parts else np.empty(0, dtype)
    x, y = records["x"], records["y"]
    records = records[(x >= w) & (x <= e) & (y >= s) & (y <= n)]
    return {k: np.ascontiguousarray(records[k]) for k in STRIP_FIELDS}


def gridded_tile(path: str, sources: list, crs_text, cell_size: float, crs_wkt: str, buffer: float, compute) -> tuple:
    """A tile of a product gridded over its neighbours' points: (its TileInfo, its grid on the lattice of
    ``cell_size``, ``own``, ``compute(own, around, grid)``), where ``own`` are the tile's points and ``around`` the points of
    ``sources`` within ``buffer`` (CRS units) of the grid; a DataFileError of ``compute`` names the tile."""
    from ..errors import DataFileError
    from ..grid import snapped_grid
    from ..io.raster import crs_from_wkt

    info = read_tile_info(path, parse_crs_text(crs_text) if crs_text else None)
    grid = snapped_grid(info.bounds, cell_size, crs_from_wkt(crs_wkt))
    own = points_in_box(info, EVERYWHERE, fields=STRIP_FIELDS, decoded=decoded.take(path))
    w, s, e, n = grid.bounds
    try:
        return info, grid, own, compute(own, points_around(sources, (w - buffer, s - buffer, e + buffer,
                                                                     n + buffer), crs_text), grid)
    except DataFileError as err:
        raise DataFileError(str(err), path=path) from None


def points_around(sources: list, box, crs_text=None) -> list[dict]:
    """The neighbours' points inside ``box`` (west, south, east, north), one dict of STRIP_FIELDS per source given
    to the tile function by buffered_passes (withheld points left out)."""
    override = parse_crs_text(crs_text) if crs_text else None
    parts = []
    for kind, _name, source in sources:
        if kind == "strip":
            parts.append(_strip_in_box(source, box))
        else:
            parts.append(points_in_box(read_tile_info(source, override), box, fields=STRIP_FIELDS))
    return parts


@dataclass
class TileState(EngineTileState):
    """A tile's line in a buffered command's report.json (each command adds its own fields)."""

    neighbours: list | None = None  # the neighbours whose points it read
    seconds: float = 0.0


@dataclass
class RasterTileState(TileState):
    """A tile's line of a command that grids its points into rasters (``gistools metrics``, ``gistools fuels``)."""

    outputs: dict = field(default_factory=dict)
    points: int = 0
    points_used: int = 0
    cells_with_points: int = 0
    heights_outside_tin: int | None = None


# what a gridded tile's run found, kept in its mark (tile_reports/) and reported again when a rerun keeps the tile
RASTER_FOUND = ("points", "points_used", "cells_with_points", "heights_outside_tin", "neighbours")


@dataclass
class PointTileState(TileState):
    """A tile's line of a command that writes a point file per tile (``gistools ground``, ``gistools normalize``)."""

    output: str | None = None
    points: int = 0


def gridded_todo(infos: dict, states: dict, cell_size: float, outputs_of, overwrite: bool, keep,
                 marks=None) -> list[str]:
    """The tiles to do of a command that grids them: a tile whose grid at ``cell_size`` would not fit in memory fails,
    one whose outputs (``outputs_of(name)``: {key: Path}) are complete is kept (``keep(state, outputs, found)``, with
    what its earlier run found) unless ``overwrite``. ``marks`` (engine.resume.TileMarks) decides what is complete:
    made with this run's settings (other settings are refused) and whole (a damaged tile is made again); an output
    gistools did not write is refused before any work."""
    from ..errors import GistoolsError
    from ..validation import check_grid_size

    todo = []
    for name, info in infos.items():
        try:
            check_grid_size(info.bounds, cell_size, str(info.path), unit=info.unit.short)
        except GistoolsError as err:
            states[name].status, states[name].error = "failed", str(err)
            continue
        targets = outputs_of(name)
        found = marks.kept(name, targets, overwrite) if marks is not None else (
            None if overwrite or not all(Path(t).exists() for t in targets.values()) else {})
        if found is not None:
            states[name].status = "skipped"
            keep(states[name], targets, found)
        else:
            todo.append(name)
    return todo


def marked_todo(infos: dict, states: dict, run, out: Path, command: str, outputs_of, found: tuple, overwrite: bool,
                single: str | None = None):
    """(the tiles to make, the ``on_done`` that records a made tile) of a command whose tiles are marked in
    ``tile_reports/`` (engine.resume.TileMarks, settings from the resolved ``run``): a kept tile's state gets its
    outputs and the ``found`` fields its earlier run recorded; a made tile's state gets them from its result, and
    its mark is written. ``single``: the output key of a command with one output per tile (state.output)."""
    from .resume import TileMarks, run_fingerprint

    first = next(iter(infos.values()), None)
    marks = TileMarks(out, command, run_fingerprint(run), unit=first.unit.short if first is not None else "")

    def keep(state, targets, earlier):
        if single:
            state.output = str(targets[single])
        else:
            state.outputs = {k: str(v) for k, v in targets.items()}
        for k in found:
            if k in earlier:
                setattr(state, k, earlier[k])

    def on_done(name, value, seconds):
        st = states[name]
        for k in ("output" if single else "outputs", *found):
            setattr(st, k, value[k])
        st.seconds = round(seconds, 3)
        marks.write(name, {single: value["output"]} if single else value["outputs"], {k: value[k] for k in found})

    return gridded_todo(infos, states, run.cell_size, outputs_of, overwrite, keep, marks), on_done


@dataclass
class _StripState:
    name: str
    path: str = ""
    status: str = "ok"
    error: str | None = None
    strip: str | None = None
    inner: tuple | None = None


def _sources(infos: dict, name: str, strips: dict, buffer: float, table: dict, reach=None,
             own_strip: bool = False) -> tuple[list, list]:
    """(what to read of each neighbour: ("strip", name, file) or ("tile", name, file), the tile's own strip first
    if ``own_strip``; warnings)."""
    w, s, e, n = infos[name].bounds
    grown = reach[name] if reach is not None else (w - buffer, s - buffer, e + buffer, n + buffer)
    sources, warnings = [], []
    if own_strip:
        sources.append(("strip", name, strips[name].strip))
    for path in table[name]:
        nb = Path(path).stem
        st = strips.get(nb)
        if st is None or st.status != "ok":
            warnings.append(f"neighbour {nb} could not be read ({st.error if st else 'no strip'}); "
                            "the tile is done without its points")
            continue
        iw, is_, ie, in_ = st.inner
        overlaps_inner = iw < ie and is_ < in_ and grown[0] < ie and grown[2] > iw and grown[1] < in_ and grown[3] > is_
        # overlapping tiles reach past a neighbour's edge strip: read that neighbour itself
        sources.append(("tile", nb, path) if overlaps_inner else ("strip", nb, st.strip))
    return sources, warnings


def buffered_passes(todo: list, infos: dict, states: dict, *, buffer: float, crs_text, out: Path, jobs,
                    scheduler, progress, tile_fn, tile_args, on_done, verb: str, tag: str, reach: dict | None = None,
                    strip_rule=None) -> None:
    """The tiles of ``todo`` through the tile engine (engine.passes): pass 1 keeps the edge strips of each tile and
    its neighbours in a scratch folder, pass 2 runs ``tile_fn(name, *tile_args(name, sources))`` per tile as soon
    as its neighbours' strips are there, ``sources`` being what ``points_around`` reads; a strip no tile still
    needs is deleted. ``states``: name -> an object with ``status`` / ``error`` / ``warnings`` (failures are marked
    there); ``on_done(name, value, seconds)`` takes each result. A failed write to ``out`` stops the run; a failed
    tile does not. ``reach`` (name -> box, within ``buffer`` of the tile): where a tile needs its neighbours' points,
    if less than its bounds grown by ``buffer``; a tile whose points no other tile needs is not read in pass 1.
    ``strip_rule`` (a picklable ``rule(x, y)`` -> mask): the strips hold the points it keeps, anywhere in a tile,
    and each tile's own strip comes first in its ``sources`` (the tile function reads no tile: each tile is decoded
    once)."""
    if not todo:
        return
    table = neighbour_table(infos, buffer, reach)
    wanted = {Path(q).stem for n in todo for q in table[n]}  # the tiles whose edge strips another tile reads
    if strip_rule is not None:
        wanted |= set(todo)
    need = set(todo) | wanted
    strips = {n: _StripState(n, str(infos[n].path)) for n in need}
    order = scan_order({n: infos[n].bounds for n in infos if n in need})
    done = [0]
    total = len(need) + len(todo)

    def tick(message):
        done[0] += 1
        report(progress, done[0] / max(total, 1), message)

    def read_done(name, value, seconds):
        strips[name].strip, strips[name].inner = value["strip"], tuple(value["inner"])

    def make(name):
        sources, warnings = _sources(infos, name, strips, buffer, table, reach, own_strip=strip_rule is not None)
        states[name].warnings = warnings
        for w in warnings:  # on the console and in QGIS as they happen, as gistools rasters does; also in the record
            log.warning("%s: %s", infos[name].path, w)
        return _named, (name, tile_fn, *tile_args(name, sources))

    def release(names):
        for n in names:
            if strips[n].strip:
                Path(strips[n].strip).unlink(missing_ok=True)

    scratch = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{tag}-", dir=out))
    pool = make_pool(jobs, scheduler, len(todo), points=sum(int(infos[n].point_count) for n in todo))
    # both passes of a tile in this process (inline or on its threads): pass 1 keeps a compressed tile decoded for
    # pass 2, which then reads no file (a tile with its strip_rule reads none either way)
    keep = strip_rule is None and (pool is None or isinstance(pool, ThreadPool))
    passes = Passes(read=lambda name, inline: ((_strip_tile, (name, str(infos[name].path), crs_text, buffer,
                                                              str(scratch), strip_rule, keep and name in todo))
                                               if name in wanted else (_no_strip, (infos[name].bounds,))),
                    make=make, on_read=read_done, on_made=on_done, results=states, read_results=strips, release=release,
                    tick=tick,
                    verbs=("read", verb))
    try:
        run_two_passes(order, set(todo), {n: {n} | {Path(q).stem for q in table[n]} for n in todo}, passes, pool,
                       owned=True, out=out)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
        decoded.discard(str(infos[n].path) for n in need)


def _named(name, fn, *args):
    return fn(*args)
