"""Tiles to DSM, DEM and nDSM GeoTIFFs, one per tile, plus VRT mosaics and report.json.

Two passes, each tile decoded once:

1. *scan* (per tile, parallel): stream the tile in chunks; keep a partial DSM (max
   of first returns) and ground / water counts on the tile's snapped grid, and its
   ground points, in a scratch folder.
2. *grid* (per tile, parallel): merge the partial grids of the tiles that overlap
   this tile's grid (cells on a shared edge), take ground points of the tile and of
   its neighbours within a buffer, and compute DEM and nDSM.

So cells near tile edges get the same values as if the block were one file.
"""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from affine import Affine

from ..docstrings import shared_sections
from ..errors import Cancelled, DataFileError, GistoolsError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..grid import Grid, snapped_grid
from ..io.points import DEFAULT_CHUNK_SIZE, TileInfo, common_crs, crs_label, iter_chunks, parse_crs_text, read_tile_info, scaled
from ..io.atomic import raise_output_error
from ..io.outdir import SCRATCH_PREFIX, claim_output
from ..io.raster import NODATA, atomic_path, crs_from_wkt, write_raster, write_vrt
from ..io.tiles import find_tiles
from ..lidar.accumulate import ASPRS_STYLE, NOISE_CLASSES, TOPCLASS_NODATA, finish_surface, merge_top_class, surface_classes
from ..lidar.bands import add_nodata_causes, nodata_cause_shares
from ..lidar.scan import GROUND_CLASS, WATER_CLASS, ScanGrids, scan_chunk, surface_mask
from ..lidar.gridding import dem_from_ground_points, fill_voids, ndsm_from, tin_dem_with_halo
from ..progress import ProgressCallback, report, sub_progress
from ..engine.record import write_folder_report
from ..engine.batch import fail, make_pool
from ..engine.passes import Passes, TileState, run_two_passes, scan_order
from ..io.scratch import (FIRST_DTYPE, GROUND_DTYPE, HALO_SIDES, Extent, ground_file, ground_meta_file,
                          ground_sources, grids_folder, load_grid, read_ground, save_grids)
from .dsmfill import DsmFillScan, fill_tile_dsm
from .hydro import ShoreMinima, flatten_dem_tiles, water_bodies
from ..engine.resume import TILE_FIELDS, kept_tiles, run_settings, write_tile_report
from ..engine.schedule import neighbour_pairs
from ..units import length_to_crs_units
from ..parameters import check_all, choices, default_for, in_data_units, option, render, setting_default
from ..validation import check_jobs, check_scheduler, check_count, check_grid_size, check_length, grid_shape

__all__ = ["RasterSettings", "rasters_from_tiles", "PRODUCTS", "NOISE_CLASSES", "GROUND_CLASS", "WATER_CLASS"]

log = logging.getLogger(__name__)

PRODUCTS = choices("products")  # declared in gistools.parameters.rasters
DEFAULT_PRODUCTS = default_for("products")


@dataclass(frozen=True)
class RasterSettings:
    """Parameters of a DSM / DEM / nDSM run. Lengths take a unit: "5ft", "1.5m", or a bare number in CRS units.

    dsm_classes: None = every class but noise (7, 18); withheld points are always left out.
    The dissertation's set is (1, 2). products: any of dsm, dem, ndsm, topclass (the ASPRS
    class of each cell's highest first return, uint8; a DSM-only run keeps no ground points).
    tin_block_points: the DEM is built in strips of about this many ground points, bounding
    memory (about 110 bytes per point in the TIN kernel, docs/performance.md). dem_max_distance:
    cells farther than this from every ground point stay nodata (TIN, IDW). buffer: how far
    into neighbouring tiles ground points are read (default: 2 x dem_max_distance, at least 20
    cells). return_band_breaks: heights
    (with units) h0 <= h1 < h2 < h3; when given, each tile's first returns are counted by
    height above the DEM in bands (h <= h0, h0-h1, h1-h2, h2-h3, > h3; ground and water
    returns in the first): band areas that do not depend on the cell grid. hydro_flatten: a layer of water
    polygons (file.gpkg:LAYER); the DEM cells inside each take its lowest ground elevation within shore_width
    outside its edge (default 2 cells), filled where they had none (products.hydro). dem_fill: none, tin or idw: the
    DEM's voids (cells farther than dem_max_distance from ground, under big buildings) filled from the buffered
    ground points, water cells left (lidar.gridding.fill_voids); counted per tile. dsm_fill: none, tin (the DSM's
    empty cells inside the hull of the returns from a TIN of the cells' highest returns), nearest (the nearest
    cell's highest return within 3 cells) or subcircle (every first return also at 8 points of a circle of radius
    subcircle, default half a cell: lidR's p2r(subcircle)); counted per tile.
    """

    cell_size: str | float | None = setting_default("cell_size")  # None: 5ft on data in feet, 1.5m in metres
    dem_method: str = "tin"
    dsm_classes: tuple[int, ...] | None = None
    dem_max_distance: str | float = "15m"
    buffer: str | float | None = None
    crs: str | None = None
    chunk_size: int = DEFAULT_CHUNK_SIZE
    products: tuple[str, ...] = DEFAULT_PRODUCTS
    tin_block_points: int = 5_000_000
    return_band_breaks: tuple | None = None
    classify_ground: str | None = None
    hydro_flatten: str | None = None
    shore_width: str | float | None = None
    dem_fill: str = "none"
    dsm_fill: str = "none"
    subcircle: str | float | None = None

    def validate(self) -> None:
        """Every field checked against its declaration (gistools.parameters), then the rules between them."""
        check_all(self)  # every field with a declaration of its name
        check_count(self.tin_block_points, "tin_block_points", example="5000000")
        if self.return_band_breaks is not None:
            values = [check_length(b, "band break", allow_equal=True) for b in self.return_band_breaks]
            if len(values) < 2:
                raise InputError(f"return band breaks {self.return_band_breaks}: give at least two heights")
        if self.hydro_flatten is not None and "dem" not in self.products:
            raise InputError(f"{option('hydro_flatten')} flattens the DEM: add dem to {option('products')}",
                             hint=f"e.g. {option('products', ('dsm', 'dem', 'ndsm'))}")
        if self.hydro_flatten is not None and "ndsm" in self.products and "dsm" not in self.products:
            raise InputError(f"{option('hydro_flatten')} redoes the nDSM from the DSM: add dsm to {option('products')}, "
                             "or leave ndsm out", hint=f"e.g. {option('products', ('dsm', 'dem', 'ndsm'))}")


@dataclass
class TileResult(TileState):
    """One tile's line in report.json."""

    points: int = 0
    points_by_class: dict = field(default_factory=dict)
    points_by_return: dict = field(default_factory=dict)
    points_outside_header_bounds: int = 0
    outputs: dict = field(default_factory=dict)
    first_return_bands: list | None = None
    shore_minima: dict = field(default_factory=dict)  # water body -> lowest ground point of its shore (hydro_flatten)
    shore_profile: dict = field(default_factory=dict)  # river -> {"ix,iy": lowest shore point of that profile cell}
    dem_filled_cells: int = 0  # DEM voids filled (dem_fill)
    dsm_filled_cells: int = 0  # DSM pinholes filled (dsm_fill)
    grid: list | None = None  # the tile's grid: transform (a, b, c, d, e, f), width, height
    nodata_by_cause: dict | None = None  # why cells have no height band (lidar.bands), where dsm, dem, topclass are made
    stage_seconds: dict = field(default_factory=dict)  # the tile's time by stage: read (pass 1), merge, dem, write
    neighbours: list = field(default_factory=list)  # the neighbours whose points the tile's rasters used
    seconds: float = 0.0


@dataclass(frozen=True)
class _Run:
    """What both passes need (picklable)."""

    cell_size: float
    dem_method: str
    dsm_classes: tuple[int, ...] | None
    max_distance: float
    buffer: float
    chunk_size: int
    scratch: str
    out: str
    crs_wkt: str
    z_unit: str
    products: tuple[str, ...] = DEFAULT_PRODUCTS
    tin_block_points: int = 5_000_000
    return_breaks: tuple[float, ...] | None = None
    water: tuple = ()  # water bodies to flatten the DEM in (products.hydro.water_bodies)
    shore_width: float = 0.0
    water_key: str | None = None  # the layer and shore width, in the tile reports' settings
    dem_fill: str = "none"
    dsm_fill: str = "none"
    subcircle: float = 0.0


def _tile_grid(info: TileInfo, run: _Run, crs=None) -> Grid:
    return snapped_grid(info.bounds, run.cell_size, crs)


def _not_all_withheld(info: TileInfo, done: int, withheld: int) -> None:
    """Refuse a tile whose every point is withheld: nothing of it is used (not "no ground")."""
    if done and withheld == done:
        raise DataFileError(f"all {done:,} points carry the withheld flag, so nothing of the tile is gridded",
                            path=info.path, hint="Clear the flag if the points are good (PDAL filters.assign, las2las), "
                                                 "or leave the tile out")


def _scan_tile(info: TileInfo, run: _Run, progress: ProgressCallback | None = None) -> dict:
    """Pass 1: stream a tile; keep its partial grids, and append its ground points to a scratch file.

    Memory stays flat whatever the tile size: only the grids and one chunk are held.
    """
    grid = _tile_grid(info, run)
    need_dem = bool({"dem", "ndsm"} & set(run.products))
    grids = ScanGrids.empty(grid.width * grid.height, track_top="topclass" in run.products,
                            keep_first=run.return_breaks is not None, keep_ground=need_dem, nodata_class=TOPCLASS_NODATA)
    outside = 0
    done = withheld = 0
    first_path = Path(run.scratch) / f"{info.name}.first.f8"
    sides = {k: Extent() for k in ("ground", *HALO_SIDES)}
    out_box = Extent()
    scale_offset = None
    west, south, east, north = info.bounds
    halo_edges = (west + run.buffer, east - run.buffer, south + run.buffer, north - run.buffer)
    shore = ShoreMinima(run.water, info.bounds, run.shore_width) if run.water and need_dem else None
    fill = DsmFillScan(run, info, grid) if run.dsm_fill != "none" else None
    with contextlib.ExitStack() as files:
        ground_out = files.enter_context(open(ground_file(run.scratch, info.name), "wb"))
        halo_out = {k: files.enter_context(open(ground_file(run.scratch, info.name, k), "wb")) for k in HALO_SIDES}
        first_out = files.enter_context(open(first_path, "wb"))
        fields = _scan_fields(whole_xy=shore is not None or fill is not None)
        surface_class = surface_classes(run.dsm_classes)
        for chunk in iter_chunks(info, run.chunk_size, fields=fields, only_fields=True):
            raw = chunk.raw
            scan = scan_chunk(grids, grid, (raw.X, raw.Y, raw.Z), raw.scales, raw.offsets, chunk.classification,
                              chunk.return_number, chunk.withheld, surface=surface_class, halo_edges=halo_edges,
                              ground_index=shore is not None)
            cell = scan.cell  # -1 outside the grid, i.e. outside the header bounds
            if scan.outside:
                outside += scan.outside
                _add_outside(out_box, chunk, cell < 0)
            if grids.keep_first:  # (cell, z) pairs, 8 bytes each, for their height above the DEM in pass 2
                rec = np.empty(len(scan.first_cell), dtype=FIRST_DTYPE)
                rec["cell"], rec["z"] = scan.first_cell, scan.first_z
                rec.tofile(first_out)
            if fill is not None:
                surface = surface_mask(cell, chunk.classification, chunk.return_number, chunk.withheld, surface_class)
                fill.add(chunk.x[surface], chunk.y[surface], scaled(chunk, "z", surface), cell[surface])
            if need_dem:
                scale_offset = ([float(v) for v in raw.scales], [float(v) for v in raw.offsets])
                _write_ground(chunk, scan, ground_out, halo_out, sides, shore)
            done += len(chunk)
            withheld += int(np.count_nonzero(chunk.withheld))
            report(progress, done / max(info.point_count, 1), f"{info.name}: {done:,} points read")
    _not_all_withheld(info, done, withheld)
    warnings = _outside_bounds(info, outside, done, out_box)
    meta = {"scale_offset": scale_offset, "extents": {k: e.box for k, e in sides.items()}}
    with atomic_path(ground_meta_file(run.scratch, info.name), overwrite=True) as tmp:
        tmp.write_text(json.dumps(meta), encoding="utf-8")
    finish_surface(grids.dsm)
    save_grids(
        grids_folder(run.scratch, info.name),
        dsm=grids.dsm.reshape(grid.shape),
        top_class=grids.top_class.reshape(grid.shape),
        bare_first=grids.bare_first.reshape(grid.shape).astype(np.int32),
        ground_count=grids.ground_count.reshape(grid.shape).astype(np.int32),
        water_count=grids.water_count.reshape(grid.shape).astype(np.int32),
        **(fill.grids() if fill is not None else {}),
    )
    by_class, by_return = grids.by_class, grids.by_return
    return {
        "points": int(by_class.sum()),
        "points_by_class": {int(c): int(v) for c, v in enumerate(by_class) if v},
        "points_by_return": {int(r): int(v) for r, v in enumerate(by_return) if v},
        "points_outside_header_bounds": outside,
        **_shore_result(shore),
        "warnings": warnings,
    }


def _scan_fields(whole_xy: bool) -> tuple:
    """The fields pass 1 has laspy extract: x and y only for the steps that use them whole (the scan scales x, y
    itself, as laspy would; z is scaled only where used)."""
    return ("classification", "return_number", "withheld") + (("x", "y") if whole_xy else ())


def _add_outside(out_box: Extent, chunk, off: np.ndarray) -> None:
    """Grow ``out_box`` by the chunk's points under ``off`` (those outside the grid), scaled only for them."""
    out_box.add(scaled(chunk, "x", off), scaled(chunk, "y", off), np.ones(int(np.count_nonzero(off)), bool))


def _shore_result(shore) -> dict:
    """What pass 1 found of the water bodies' shores (--hydro-flatten), for the tile's result."""
    return {"shore_minima": shore.result() if shore is not None else {},
            "shore_profile": shore.profiles() if shore is not None else {}}


def _write_ground(chunk, scan, ground_out, halo_out: dict, sides: dict, shore=None) -> None:
    """Append a chunk's ground points (the LAS integers) to the tile's ground file and to the halo strip of the
    edge within the buffer they lie near (each point in one strip at most: a tile narrower than two buffers has
    points near both edges); grow the files' extents."""
    scan.ground_xyz.view(GROUND_DTYPE).tofile(ground_out)
    sides["ground"].add_box(scan.boxes[0])
    halo = scan.halo_xyz.view(GROUND_DTYPE)
    for code, side in enumerate(HALO_SIDES, 1):
        halo[scan.halo_side == code].tofile(halo_out[side])  # what the neighbours read
        sides[side].add_box(scan.boxes[code])
    if shore is not None:  # --hydro-flatten: the lowest ground point of each water body's shore
        ground = np.zeros(len(chunk), bool)
        ground[scan.ground_index] = True
        shore.add(chunk.x, chunk.y, lambda mask: scaled(chunk, "z", mask), ground)


def _outside_bounds(info: TileInfo, outside: int, done: int, out_box) -> list[str]:
    """Points outside the header's bounds: a warning when the bounds were only rounded (3 scale steps), else the
    tile fails (its grid and its neighbours come from those bounds)."""
    if not outside:
        return []
    w0, s0, e0, n0 = info.bounds
    over = max(w0 - out_box.box[0], s0 - out_box.box[1], out_box.box[2] - e0, out_box.box[3] - n0)
    if over <= 3 * max(info.scales[0], info.scales[1]):
        return [f"{info.path}: {outside:,} points lie up to {over:.3g} outside the header's bounds (rounded "
                f"bounds) and are left out"]
    w, s_, e, n_ = (min(a, b) if i < 2 else max(a, b) for i, (a, b) in enumerate(zip(out_box.box, info.bounds)))
    raise DataFileError(
        f"{outside:,} of {done:,} points lie outside the header's bounds ({w0:.3f}, {s0:.3f}, {e0:.3f}, {n0:.3f}); "
        f"the points span ({w:.3f}, {s_:.3f}, {e:.3f}, {n_:.3f})",
        path=info.path, hint="Repair the header's bounds (lasinfo -repair_bb, or pdal translate) and run again")


def _first_return_bands(path: Path, dem_flat: np.ndarray, breaks, bare: int, chunk_points: int = 4_000_000) -> list[int]:
    """Counts of a tile's first returns by height above the DEM at their cell: [<= h0, h0-h1, h1-h2, h2-h3, > h3].

    ``bare``: ground and water first returns over DEM cells, counted in the first band. Returns over
    nodata DEM cells are left out. z is kept as float32 (about 1e-5 ft at 100 ft), far below any band limit.
    """
    counts = np.zeros(len(breaks) + 1, np.int64)
    counts[0] += bare
    edges = np.asarray(breaks)
    with open(path, "rb") as fh:
        while True:
            a = np.fromfile(fh, dtype=FIRST_DTYPE, count=chunk_points)
            if a.size == 0:
                break
            ground = dem_flat[a["cell"]]
            ok = np.isfinite(ground)
            h = a["z"][ok] - ground[ok]
            counts += np.bincount(np.searchsorted(edges, h, side="left"), minlength=len(counts))
    return [int(c) for c in counts]


def _neighbours(infos: list[TileInfo], distance: float) -> dict[str, list[TileInfo]]:
    """{tile: the other tiles within ``distance`` of its bounds}, in the order of ``infos`` (an R-tree: n log n)."""
    pairs = neighbour_pairs([i.bounds for i in infos], distance)
    return {info.name: [infos[j] for j in js if infos[j].path != info.path] for info, js in zip(infos, pairs)}


def _task_bytes(infos, run: _Run) -> int:
    """About the most memory one tile's task takes: its grids (about 40 bytes a cell, with the neighbours' edges),
    a chunk of points (about 60 bytes a point) and a TIN strip (about 110 bytes a ground point)."""
    most = 0
    for info in infos:
        cols, rows = grid_shape(info.bounds, run.cell_size)
        points = min(int(info.point_count), int(run.chunk_size))
        most = max(most, 40 * (cols + 2) * (rows + 2) + 60 * points + 110 * min(int(info.point_count), TIN_STRIP_POINTS))
    return most


def _rows(grid: Grid, r0: int, r1: int) -> Grid:
    """The grid of rows r0 to r1 (exclusive) of ``grid``."""
    return grid.part(0, r0, grid.width, r1 - r0)


def _strips(counts_per_row: np.ndarray, max_points: int) -> list[tuple[int, int]]:
    """Row ranges holding at most about ``max_points`` ground points each."""
    strips, start, acc = [], 0, 0
    for r, c in enumerate(counts_per_row):
        if acc and acc + c > max_points:
            strips.append((start, r))
            start, acc = r, 0
        acc += int(c)
    strips.append((start, len(counts_per_row)))
    return strips


def _grid_tile(info: TileInfo, neighbours: list[TileInfo], run: _Run) -> dict:
    """Pass 2: merge partial grids with neighbours, DEM from buffered ground points, write rasters.

    The DEM is computed in strips of at most ``run.tin_block_points`` ground points (plus
    the buffer), so memory stays bounded whatever the tile size.
    """
    t0 = time.perf_counter()
    crs = crs_from_wkt(run.crs_wkt)
    grid = _tile_grid(info, run, crs)
    own = grids_folder(run.scratch, info.name)
    dsm, top_class, bare_first = (load_grid(own, k) for k in ("dsm", "top_class", "bare_first"))
    ground_count, water_count = (load_grid(own, k).astype(np.int64) for k in ("ground_count", "water_count"))
    own_ground, own_water = int(ground_count.sum()), int(water_count.sum())
    used, warnings = _merge_neighbours(info, neighbours, run, grid, dsm, top_class, ground_count, water_count)
    dsm_filled = 0
    if run.dsm_fill != "none":
        dsm, dsm_filled = fill_tile_dsm(info, neighbours, run, grid, dsm, lambda i: _tile_grid(i, run))
    _refuse_empty_dsm(info, run, dsm)
    arrays = {"dsm": dsm, "topclass": top_class}
    t1 = time.perf_counter()
    return_bands = None
    if run.products != ("dsm",):
        dem, filled = _tile_dem(info, neighbours, run, grid, ground_count, (water_count > 0) & (ground_count == 0))
        warnings += _dem_warnings(info, run, dem, own_ground, own_water)
        arrays["dem"] = dem
        arrays["ndsm"] = ndsm_from(dsm, dem)
        if run.return_breaks is not None:
            return_bands = {
                "counts": _first_return_bands(Path(run.scratch) / f"{info.name}.first.f8", dem.reshape(-1), run.return_breaks,
                                              int(bare_first[np.isfinite(dem)].sum())),
                "dem_cells": int(np.isfinite(dem).sum()),
                "cell_area": grid.cell_size ** 2,
                "breaks": list(run.return_breaks),
            }
    else:
        filled = 0
    t2 = time.perf_counter()
    outputs = _write_tile_rasters(info, run, grid, arrays)
    stages = {"merge": t1 - t0, "dem": t2 - t1, "write": time.perf_counter() - t2}
    causes = _nodata_causes(arrays) if {"dsm", "dem", "topclass"} <= set(run.products) else None
    return {"outputs": outputs, "first_return_bands": return_bands, "warnings": warnings, "neighbours": sorted(used),
            "dem_filled_cells": filled, "dsm_filled_cells": dsm_filled, "stages": stages, "nodata_by_cause": causes,
            "grid": [*grid.transform[:6], grid.width, grid.height]}


def _nodata_causes(arrays: dict) -> dict:
    """Why the tile's cells have no height band (lidar.bands.add_nodata_causes), from its DSM, DEM and top class as
    their rasters store them (float32, NODATA for NaN): what the shrub chain's clip step reports, without reading
    the three rasters back."""
    counts: dict = {}
    no_dsm, no_dem = ((np.isnan(a) | (np.asarray(a, np.float32) == np.float32(NODATA))) for a in (arrays["dsm"], arrays["dem"]))
    add_nodata_causes(counts, no_dsm, no_dem, arrays["topclass"])
    return nodata_cause_shares(counts)


def _merge_neighbours(info, neighbours, run: _Run, grid: Grid, dsm, top_class, ground_count, water_count):
    """Take the neighbours' partial grids on the cells they share with this tile (in place); (names of the
    neighbours read, warnings for those whose pass 1 failed)."""
    used, warnings = [], []
    for other in neighbours:
        folder = grids_folder(run.scratch, other.name)
        if not folder.is_dir():  # the neighbour failed in pass 1: this tile's edge lacks its points
            warnings.append(f"{info.path}: neighbour {other.name} could not be read, so the cells near it lack its "
                            "points; a rerun recomputes this tile once the neighbour reads")
            continue
        used.append(other.name)
        window = grid.window_in(_tile_grid(other, run))
        if window is not None:
            rs, cs_, ro, co = window
            nb = {k: load_grid(folder, k, mmap=True)[ro, co] for k in ("dsm", "top_class", "ground_count", "water_count")}
            merge_top_class(top_class[rs, cs_], dsm[rs, cs_], nb["top_class"], nb["dsm"])
            dsm[rs, cs_] = np.fmax(dsm[rs, cs_], nb["dsm"])
            ground_count[rs, cs_] += nb["ground_count"]
            water_count[rs, cs_] += nb["water_count"]
    return used, warnings


def _tile_dem(info, neighbours, run: _Run, grid: Grid, ground_count, water) -> tuple[np.ndarray, int]:
    """(the DEM of a tile from its ground points and its neighbours' within the buffer, in strips of rows; the voids
    filled by run.dem_fill)."""
    b = run.buffer
    gw, gs, ge, gn = grid.bounds
    # a neighbour's halo strips hold its points within the buffer of its edges; its other points can lie
    # within the buffer of this tile only when the two tiles overlap (overlapping deliveries): read it whole
    deep = {o.name: o.bounds[0] < ge and o.bounds[2] > gw and o.bounds[1] < gn and o.bounds[3] > gs for o in neighbours}
    dem = np.full(grid.shape, np.nan)
    filled = 0
    for r0, r1 in _strips(ground_count.sum(axis=1), run.tin_block_points):
        strip = _rows(grid, r0, r1)
        w, s, e, n = strip.bounds
        box = (w - b, s - b, e + b, n + b)
        sources = ground_sources(run.scratch, info.name, box)
        for o in neighbours:
            sources += ground_sources(run.scratch, o.name, box, deep=deep[o.name])
        x, y, z = read_ground(sources, box)
        if run.dem_method == "tin":  # the same values as one TIN of all the points, on fewer of them
            dem[r0:r1] = _tin_dem_in_strips(x, y, z, strip, ground_count[r0:r1].sum(axis=1), run, water[r0:r1])
        else:
            dem[r0:r1] = dem_from_ground_points(x, y, z, strip, method=run.dem_method,
                                                max_distance=run.max_distance, water=water[r0:r1])
        part = dem[r0:r1]
        filled += fill_voids(part, strip, x, y, z, method=run.dem_fill, keep=water[r0:r1])
        del x, y, z
    return dem, filled


# Ground points one TIN is built on at most: the sweep's time a point grows with the points (0.34 µs at 250,000,
# 0.42 at 1 M, 0.52 at 4.5 M on this project's machine: its arrays outgrow the caches), so a tile's DEM in strips of
# 1 M (each with its halo) takes a tenth less time than in one piece, the same values (docs/performance.md).
TIN_STRIP_POINTS = 1_000_000


def _tin_dem_in_strips(x, y, z, grid: Grid, counts_per_row, run: _Run, water) -> np.ndarray:
    """The TIN DEM of ``grid`` from the ground points read for it (all those within the buffer), in strips of rows of
    at most about TIN_STRIP_POINTS points: each strip from the points within the buffer of it, in their order (what
    reading the strip alone gives)."""
    b = run.buffer
    parts = _strips(counts_per_row, TIN_STRIP_POINTS)
    if len(parts) == 1:
        return tin_dem_with_halo(x, y, z, grid, halo=b, max_distance=run.max_distance, water=water)
    dem = np.empty(grid.shape)
    for r0, r1 in parts:
        strip = _rows(grid, r0, r1)
        _, south, _, north = strip.bounds
        near = (y >= south - b) & (y <= north + b)  # x lies within the buffer already
        dem[r0:r1] = tin_dem_with_halo(x[near], y[near], z[near], strip, halo=b, max_distance=run.max_distance,
                                       water=water[r0:r1])
    return dem


def _refuse_empty_dsm(info, run: _Run, dsm) -> None:
    """A tile without one first return of the DSM's classes fails: its DSM would be empty, not "ok"."""
    if "dsm" in run.products and not np.isfinite(dsm).any():
        raise DataFileError("no first return of the DSM's classes in the tile, so its DSM would be empty",
                            path=info.path, hint=f"Check the tile's classes and returns (gistools info), and "
                                                 f"{option('dsm_classes')}")


def _dem_warnings(info, run: _Run, dem, own_ground: int, own_water: int) -> list[str]:
    """The warning of a tile without ground points (its DEM from the neighbours'), or its failure when its DEM
    would be empty: no ground and no water, or ground points spanning no area (one, or all at one spot)."""
    if not {"dem", "ndsm"} & set(run.products):
        return []
    if own_ground == 0:
        return [_no_ground(info, dem, own_water)]
    if own_water == 0 and not np.isfinite(dem).any():
        raise DataFileError(f"its {own_ground:,} ground (class 2) points span no area (all at one spot or on one "
                            f"line), so its {run.dem_method} DEM and its nDSM would be empty", path=info.path,
                            hint=f"Classify ground again, or grid the points one by one: {option('dem_method', 'max')}")
    return []


def _no_ground(info, dem, own_water: int) -> str:
    """The warning for a tile without ground points, or the error when its DEM is empty and it is not water."""
    filled = int(np.isfinite(dem).sum())
    if filled == 0 and own_water == 0:
        raise DataFileError("the tile has no ground (class 2) points, so its DEM and nDSM would be empty",
                            path=info.path, hint="Classify ground first (e.g. PDAL filters.smrf or lasground), "
                                                 "or leave the tile out")
    return (f"{info.path}: no ground (class 2) points in the tile; its DEM has {filled:,} of "
            f"{dem.size:,} cells, from the neighbours' ground" + (" (the rest is water)" if own_water else ""))


def _write_tile_rasters(info, run: _Run, grid: Grid, arrays: dict) -> dict:
    """Every product of a tile (a tile reaches pass 2 only when its outputs are incomplete, or --overwrite)."""
    outputs = {}
    tags = {"GISTOOLS_CELL_SIZE": run.cell_size, "GISTOOLS_Z_UNIT": run.z_unit, "GISTOOLS_DEM_METHOD": run.dem_method}
    for product in run.products:
        path = Path(run.out) / product / f"{info.name}.tif"
        if product == "topclass":
            write_raster(path, arrays[product], grid, overwrite=True, nodata=TOPCLASS_NODATA, dtype="uint8",
                         tags={**tags, "GISTOOLS_PRODUCT": product}, description="class of the highest first return",
                         categories=ASPRS_STYLE)
        else:
            write_raster(path, arrays[product], grid, overwrite=True, units=run.z_unit,
                         tags={**tags, "GISTOOLS_PRODUCT": product},
                         description=f"{product.upper()} height ({run.z_unit})")  # QGIS's legend shows the unit
        outputs[product] = str(path)
    return outputs


@shared_sections
def rasters_from_tiles(
    inputs,
    out,
    settings: RasterSettings | None = None,
    *,
    jobs: int | str = "auto",
    scheduler: str | None = None,
    overwrite: bool = False,
    progress: ProgressCallback | None = None,
    pool=None,
    water=None,
) -> dict:
    """DSM, DEM and nDSM GeoTIFFs of every tile of ``inputs``: ``gistools rasters``.

    Writes ``out/{dsm,dem,ndsm}/<tile>.tif``, the mosaics ``out/{dsm,dem,ndsm}.vrt`` and ``out/report.json``. A tile that
    fails is reported (status ``failed``, with its error) and the others complete; tiles whose outputs exist are kept
    (status ``skipped``) unless ``overwrite``.

    Parameters
    ----------
    {tiles_in}
    settings : RasterSettings, optional
        The options (``cell_size``, ``dem_method``, ``dem_max_distance``, ...; lengths as text with their unit, e.g.
        ``"5ft"``, ``"1.5m"``, or a number in CRS units). None: the defaults (5 ft cells on data in feet, 1.5 m in
        metres).
    {tiles_run}
    pool : gistools.engine.batch.ProcessPool, optional
        A worker pool to use instead of starting one (``gistools.engine.batch.make_pool``; the caller closes it).
    water : list of shapely geometries, optional
        With ``settings.classify_ground``: water polygons (shapely geometries, in CRS units) whose points become water
        (class 9) before the ground filter.

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, failed, skipped), each tile's entry
        in ``tiles``, the settings, units and timings.

    Raises
    ------
    InputError
        An option is not valid, ``inputs`` holds no tile, or ``out`` holds tiles made with other settings (without
        ``overwrite``).
    OutputExistsError
        ``out`` holds another command's outputs.
    {tiles_raise_rest}

    Examples
    --------
    >>> from gistools import RasterSettings, rasters_from_tiles
    >>> report = rasters_from_tiles("sample_tiles", "rasters", RasterSettings(cell_size="5ft"))  # doctest: +SKIP
    >>> report["counts"]  # doctest: +SKIP
    {'ok': 4, 'failed': 0, 'skipped': 0}
    """
    settings = settings or RasterSettings()
    settings.validate()
    check_scheduler(scheduler)
    jobs = check_jobs(jobs)
    started = time.time()
    out = output_folder(out)
    paths = find_tiles(inputs)
    override = parse_crs_text(settings.crs) if settings.crs else None
    with claim_output(out, "gistools rasters"):
        failed = {}
        if settings.classify_ground:
            paths, failed = _classified(paths, out, settings, jobs, overwrite, scheduler, progress, water)
            progress = sub_progress(progress, 0.3, 1.0)
        return raise_if_every_tile_failed(_rasters_in(paths, override, out, settings, started, jobs, overwrite, progress,
                                                      scheduler, pool, failed))


CLASSIFIED = "classified"  # the folder of the tiles classified by --classify-ground


def _classified(paths, out: Path, settings: RasterSettings, jobs, overwrite, scheduler, progress, water=None):
    """--classify-ground: the tiles classified first (gistools ground, into out/classified/); (their paths,
    {tile: error} of those that failed)."""
    from .ground import GroundSettings, ground_from_tiles

    report_ = ground_from_tiles(paths, out / CLASSIFIED, GroundSettings(method=settings.classify_ground, crs=settings.crs),
                                jobs=jobs, scheduler=scheduler, overwrite=overwrite, progress=sub_progress(progress, 0, 0.3),
                                water=water)
    done = [Path(t["output"]) for t in report_["tiles"] if t["status"] != "failed" and t["output"]]
    return done, {t["name"]: f"ground classification: {t['error']}" for t in report_["tiles"] if t["status"] == "failed"}


def _rasters_in(paths, override, out: Path, settings: RasterSettings, started, jobs, overwrite, progress, scheduler,
                pool, failed=None) -> dict:
    results = {p.stem: TileResult(name=p.stem, path=str(p)) for p in paths}
    for name, error in (failed or {}).items():
        results[name] = TileResult(name=name, path=name, status="failed", error=error)
    infos = _readable_tiles(paths, override, results)
    run, flattened = None, None
    scratch_peak = 0
    if infos:
        crs = common_crs(infos)
        settings = in_data_units(settings, infos[0].unit.is_foot)  # 5ft cells on data in feet, 1.5m in metres
        scratch = Path(tempfile.mkdtemp(prefix=SCRATCH_PREFIX, dir=out))
        try:
            run = _run_parameters(infos[0], crs, settings, out, scratch)
            infos = _griddable(infos, run, results, settings)
            scratch_peak = _passes_over_tiles(infos, results, run, jobs, overwrite, progress, scheduler, pool)
            flattened = (flatten_dem_tiles(results, run.water, run, sub_progress(progress, 1.0, 1.0), out)
                         if run.water else None)  # the bar stays full: its messages name the tiles flattened
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
    summary = _summary(infos, run, settings, results, _mosaics(out, settings.products, results), scratch_peak, started)
    if run is not None and run.water:
        summary["hydro_flatten"] = {"layer": settings.hydro_flatten, "shore_width": run.shore_width, **flattened}
    write_folder_report(out, summary, partial=True)
    return summary


_AREAS: dict = {}  # CRS WKT -> (its area of use in degrees, a transformer to degrees), worked out once


def _area_box(crs) -> tuple:
    """(the CRS's area of use, that area in the CRS's own coordinates grown by a tenth of its size, or None)."""
    import pyproj

    area = crs.area_of_use
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if area is None:
        return None, None
    try:
        to_crs = pyproj.Transformer.from_crs(horizontal.geodetic_crs, horizontal, always_xy=True)
        x0, y0, x1, y1 = to_crs.transform_bounds(area.west, area.south, area.east, area.north)
    except pyproj.exceptions.ProjError:
        return area, None
    if not all(map(np.isfinite, (x0, y0, x1, y1))):
        return area, None
    mx, my = 0.1 * (x1 - x0), 0.1 * (y1 - y0)
    return area, (x0 - mx, y0 - my, x1 + mx, y1 + my)


_AREAS_BY_OBJECT: dict = {}  # id(crs) -> (crs, area, box): the tiles' shared CRS object, its WKT written once


def _area_of(crs):
    """(the CRS's area of use, the box in its coordinates that counts as inside it, or None), worked out once."""
    known = _AREAS_BY_OBJECT.get(id(crs))
    if known is not None and known[0] is crs:
        return known[1:]
    key = crs.to_wkt()
    if key not in _AREAS:
        _AREAS[key] = _area_box(crs)
    if len(_AREAS_BY_OBJECT) >= 256:
        _AREAS_BY_OBJECT.clear()
    _AREAS_BY_OBJECT[id(crs)] = (crs, *_AREAS[key])  # the CRS kept: its id is not reused while here
    return _AREAS[key]


def outside_area_of_use(info: TileInfo) -> str | None:
    """A warning when a tile lies far outside its CRS's area of use (coordinates in degrees read as feet, a wrong
    --crs): the grid would come out, wrong, without a word."""
    area, box = _area_of(info.crs)
    if box is None:
        return None
    w, s, e, n = info.bounds
    if e < box[0] or w > box[2] or n < box[1] or s > box[3]:
        return render(f"{info.path}: the tile lies far outside the area of use of its CRS {crs_label(info.crs)} "
                      f"({area.name[:70].rstrip(' .;')}): are its coordinates in another CRS (degrees?), or is "
                      f"{option('crs')} wrong?")
    return None


def _readable_tiles(paths, override, results) -> list[TileInfo]:
    """The headers that read; the others are marked failed."""
    infos, far = [], []
    for p in paths:
        try:
            infos.append(read_tile_info(p, override))
        except GistoolsError as err:
            fail(results[p.stem], err)
            continue
        where = outside_area_of_use(infos[-1])
        if where:
            results[p.stem].warnings.append(where)
            far.append(where)
    if far:  # once on the console (a county in the wrong CRS is thousands of tiles); each tile's in report.json
        log.warning("%s", far[0] if len(far) == 1 else f"{far[0]} (and {len(far) - 1} more tiles alike, each named "
                                                          "in report.json)")
    return infos


def _run_parameters(first: TileInfo, crs, settings: RasterSettings, out: Path, scratch: Path) -> _Run:
    """The run's parameters in the tiles' units (lengths converted through the CRS)."""
    unit, z_unit = first.unit, first.z_unit
    cell_size = length_to_crs_units(settings.cell_size, unit, name="cell size")
    max_distance = length_to_crs_units(settings.dem_max_distance, unit, name="DEM max distance")
    buffer = (length_to_crs_units(settings.buffer, unit, name="buffer") if settings.buffer is not None
              else max(2 * max_distance, 20 * cell_size))
    water, shore, water_key = _water(settings, crs, unit, cell_size)
    return _Run(
        water=water, shore_width=shore, water_key=water_key,
        cell_size=cell_size, dem_method=settings.dem_method,
        dsm_classes=tuple(settings.dsm_classes) if settings.dsm_classes is not None else None,
        max_distance=max_distance, buffer=buffer, chunk_size=settings.chunk_size, scratch=str(scratch),
        out=str(out), crs_wkt=crs.to_wkt(), z_unit=z_unit.short,
        products=tuple(p for p in PRODUCTS if p in settings.products),
        tin_block_points=settings.tin_block_points, dem_fill=settings.dem_fill, dsm_fill=settings.dsm_fill,
        subcircle=(length_to_crs_units(settings.subcircle, unit, name="subcircle") if settings.subcircle is not None
                   else cell_size / 2),
        return_breaks=None if settings.return_band_breaks is None else tuple(
            length_to_crs_units(b, z_unit, name="band break") for b in settings.return_band_breaks),
    )


def _water(settings: RasterSettings, crs, unit, cell_size: float) -> tuple:
    """(water bodies, shore width in CRS units, the key recorded in tile reports) of --hydro-flatten, or empty."""
    if settings.hydro_flatten is None:
        return (), 0.0, None
    from ..io.vector import absolute_spec, check_crs, read_layer

    layer = check_crs(read_layer(settings.hydro_flatten, ("polygon",), option("hydro_flatten")), crs,
                      str(settings.hydro_flatten), reproject=None)
    shore = (length_to_crs_units(settings.shore_width, unit, name="shore width") if settings.shore_width is not None
             else 2 * cell_size)
    return water_bodies(list(layer.geometry), shore), shore, f"{absolute_spec(settings.hydro_flatten)} {shore:.6g}"


def _griddable(infos: list[TileInfo], run: _Run, results, settings: RasterSettings) -> list[TileInfo]:
    """The tiles whose grid fits in memory (a cell size far too small, or bogus header bounds, are refused)."""
    sized = []
    for info in infos:
        try:
            check_grid_size(info.bounds, run.cell_size, str(info.path), unit=info.unit.short)
            sized.append(info)
        except GistoolsError as err:
            fail(results[info.name], err)
    if not sized:
        raise InputError(f"no tile can be gridded at cell size {settings.cell_size}: {results[infos[0].name].error}")
    return sized


def _mosaics(out: Path, products, results) -> dict:
    """A VRT of each product over the tiles that are ok or kept."""
    vrts = {}
    for product in products:
        tifs = sorted((out / product).glob("*.tif")) if (out / product).is_dir() else []
        mine = [t for t in tifs if t.stem in results and results[t.stem].status in ("ok", "skipped")]
        if mine:
            vrts[product] = str(write_vrt(out / f"{product}.vrt", mine, categories=ASPRS_STYLE if product == "topclass" else None,
                                          geometry=_known_grids(mine, results)))
    return vrts


def _known_grids(tifs, results) -> dict:
    """{raster: (transform, width, height)} of the tiles whose report gives their grid (the mosaic need not open
    them)."""
    known = {}
    for t in tifs:
        grid = results[t.stem].grid
        if isinstance(grid, list) and len(grid) == 8:
            known[str(t)] = (Affine(*grid[:6]), int(grid[6]), int(grid[7]))
    return known


def _summary(infos, run, settings: RasterSettings, results, vrts: dict, scratch_peak: int, started: float) -> dict:
    """report.json of a rasters run."""
    first = infos[0] if infos else None
    return {
        "tool": "gistools rasters",
        "crs": crs_label(first.crs) if first else None,
        "crs_wkt": run.crs_wkt if run else None,
        "horizontal_unit": first.unit.name if first else None,
        "vertical_unit": first.z_unit.name if first else None,
        "horizontal_unit_m": first.unit.metres if first else None,
        "vertical_unit_m": first.z_unit.metres if first else None,
        "cell_size": run.cell_size if run else None,
        "cell_size_m": run.cell_size * first.unit.metres if run else None,
        "dem_method": settings.dem_method,
        "dem_max_distance": run.max_distance if run else None,
        "buffer": run.buffer if run else None,
        "dsm_classes": list(settings.dsm_classes) if settings.dsm_classes is not None else f"all but {list(NOISE_CLASSES)}",
        "tiles": [asdict(r) for r in results.values()],
        "counts": {s: sum(r.status == s for r in results.values()) for s in ("ok", "failed", "skipped")},
        "mosaics": vrts,
        "scratch_peak_tiles": scratch_peak if run else 0,
        "stage_seconds": _stage_totals(results),
        "seconds": round(time.time() - started, 3),
    }


def _stage_totals(results) -> dict:
    """Seconds by stage summed over the tiles done in this run (in the workers: with --jobs N they overlap)."""
    totals: dict = {}
    for r in results.values():
        if r.status == "ok":
            for k, v in (r.stage_seconds or {}).items():
                totals[k] = round(totals.get(k, 0.0) + v, 3)
    return totals


def _passes_over_tiles(infos, results, run: _Run, jobs, overwrite: bool, progress, scheduler: str | None = None,
                       shared_pool=None) -> int:
    """The rasters' two passes, declared for the tile engine (engine.passes.run_two_passes: pass 1 _scan_tile, pass
    2 _grid_tile; kept tiles of an earlier run skipped); returns the scratch's peak in tiles."""
    out = Path(run.out)
    settings = run_settings(run)
    neighbours = _neighbours(infos, run.buffer + run.cell_size)
    kept = {} if overwrite else kept_tiles(out, infos, neighbours, run, settings)
    todo = {i.name for i in infos if kept.get(i.name) is None}
    for name, rep in kept.items():
        if rep is not None:
            _take_kept(results[name], rep)
    needed = set(todo).union(*({n.name for n in neighbours[name]} for name in todo))
    by_name = {i.name: i for i in infos}
    order = scan_order({i.name: i.bounds for i in infos if i.name in needed})
    ticker = _Ticker(progress, max(len(order) + len(todo), 1), results, len(todo))

    def read(name, inline):
        return _scan_tile, (by_name[name], run, *((ticker.within_tile,) if inline and progress else ()))

    def made(name, value, seconds):
        _grid_done(results[name], value, seconds)
        write_tile_report(out, results[name], settings)

    passes = Passes(read=read, make=lambda name: (_grid_tile, (by_name[name], neighbours[name], run)),
                    on_read=lambda name, value, seconds: _scan_done(results[name], value, seconds), on_made=made,
                    results=results, release=lambda names: _release(run.scratch, names), tick=ticker.tick,
                    verbs=("read", "gridded"))
    pool = shared_pool if shared_pool is not None else make_pool(
        jobs, scheduler, len(order), _task_bytes([by_name[n] for n in order], run),
        points=sum(int(by_name[n].point_count) for n in order))
    return run_two_passes(order, todo, {n: ({n} | {m.name for m in neighbours[n]}) & needed for n in todo}, passes,
                          pool, owned=pool is not shared_pool, out=out)


class _Ticker:
    """Progress over the tiles' steps (reads and griddings), and within a tile's read for inline runs."""

    def __init__(self, progress, total: int, results: dict, tiles: int):
        self.progress, self.total, self.results, self.tiles, self.done = progress, total, results, tiles, 0

    def tick(self, message: str) -> None:
        self.done += 1
        failed = sum(r.status == "failed" for r in self.results.values())
        report(self.progress, self.done / self.total, f"{message} | {self.tiles} tiles, {failed} failed")

    def within_tile(self, fraction, message):
        return None if self.progress is None else self.progress((self.done + fraction) / self.total, message)


def _take_kept(result: TileResult, rep: dict) -> None:
    """A tile kept from an earlier run: status skipped, with what that run found (not the time it took)."""
    result.status = "skipped"
    for k in TILE_FIELDS:
        if k in rep and k != "seconds":
            setattr(result, k, rep[k])


def _scan_done(r: TileResult, value: dict, seconds: float) -> None:
    r.points, r.points_by_class = value["points"], value["points_by_class"]
    r.points_by_return = value["points_by_return"]
    r.stage_seconds = {**r.stage_seconds, "read": round(seconds, 3)}
    r.points_outside_header_bounds = value["points_outside_header_bounds"]
    r.shore_minima = value.get("shore_minima", {})
    r.shore_profile = value.get("shore_profile", {})
    new = list(value.get("warnings", []))
    r.warnings = [*r.warnings, *new]  # after the header's (a tile outside its CRS's area of use)
    for w in new:
        log.warning("%s", w)
    r.seconds += seconds


def _grid_done(r: TileResult, value: dict, seconds: float) -> None:
    r.outputs = value["outputs"]
    r.grid = value.get("grid")
    r.first_return_bands = value["first_return_bands"]
    r.dem_filled_cells = value.get("dem_filled_cells", 0)
    r.dsm_filled_cells = value.get("dsm_filled_cells", 0)
    r.nodata_by_cause = value.get("nodata_by_cause")
    r.stage_seconds = {**r.stage_seconds, **{k: round(v, 3) for k, v in value.get("stages", {}).items()}}
    r.neighbours = value["neighbours"]
    new = list(value.get("warnings", []))
    r.warnings = r.warnings + new
    for w in new:
        log.warning("%s", w)
    r.seconds += seconds


def _release(scratch, names) -> None:
    """Delete the scratch files of tiles no tile still needs."""
    for v in names:
        for f in Path(scratch).glob(f"{v}.*"):
            if f.is_dir():
                shutil.rmtree(f, ignore_errors=True)
            else:
                f.unlink(missing_ok=True)
