"""Hydro-flattening of the rasters' DEM (``gistools rasters --hydro-flatten LAYER``).

Pass 1 of the rasters (products.rasters._scan_tile) keeps, per water body near the tile, the lowest ground point within
the shore band (``shore_width`` outside the polygon's edge); after pass 2 the minima of all the tiles are merged (a
lake's shore crosses tiles) and every DEM cell whose centre lies inside the polygon takes that elevation, filled
where it had none; the nDSM follows. The tiles' DEM and nDSM GeoTIFFs are rewritten (atomically) where a water body
reaches them; a rerun does the same, so resumed runs stay flat.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import cell_centres
from ..io.raster import read_raster, write_raster
from ..lidar.gridding import ndsm_from
from ..lidar.hydro import flatten_cells, is_river, merge_minima, river_levels

__all__ = ["water_bodies", "ShoreMinima", "flatten_dem_tiles"]


def water_bodies(polygons, shore_width: float) -> tuple:
    """(key, polygon WKB, shore band WKB, profile cell) of each water polygon (the band: ``shore_width`` outside its
    edge, holes' islands included), picklable for the workers. The profile cell is 0 for a lake (one level) and, for
    a river (lidar.hydro.is_river), the size of the cells in which pass 1 keeps its shore's lowest point (half its
    width, at least the shore width), the stations of its stepped levels."""
    import shapely  # here: a run without water features starts 0.02 s sooner
    bodies = []
    for k, g in enumerate(polygons):
        if g is None or g.is_empty or g.area <= 0:
            continue
        band = g.buffer(shore_width).difference(g)
        cell = max(shore_width, g.area / g.length) if is_river(g.area, g.length) else 0.0
        bodies.append((str(k), shapely.to_wkb(g), shapely.to_wkb(band), cell))
    return tuple(bodies)


class ShoreMinima:
    """The lowest ground point of each water body's shore band among a tile's chunks."""

    def __init__(self, bodies, bounds, margin: float):
        import shapely
        w, s, e, n = bounds
        area = shapely.box(w - margin, s - margin, e + margin, n + margin)
        self.bands = []
        for key, _poly, band_wkb, cell in bodies:
            band = shapely.from_wkb(band_wkb)
            if band.intersects(area):
                shapely.prepare(band)
                self.bands.append((key, band, band.bounds, cell))
        self.low: dict = {}
        self.profile: dict = {}  # rivers: {key: {"ix,iy": lowest shore z of that profile cell}}

    def add(self, x, y, z_of, ground) -> None:
        """Ground points of a chunk (mask ``ground``; ``z_of(mask)``: their z)."""
        import shapely
        for key, band, (bw, bs, be, bn), cell in self.bands:
            near = ground & (x >= bw) & (x <= be) & (y >= bs) & (y <= bn)
            if not near.any():
                continue
            idx = np.flatnonzero(near)
            on = shapely.contains_xy(band, x[idx], y[idx])
            if on.any():
                sel = np.zeros(len(x), bool)
                sel[idx[on]] = True
                z = z_of(sel)
                self.low[key] = min(float(z.min()), self.low.get(key, np.inf))
                if cell:
                    self._add_profile(key, x[idx[on]], y[idx[on]], z, cell)

    def _add_profile(self, key, x, y, z, cell) -> None:
        ix, iy = np.floor(x / cell).astype(np.int64), np.floor(y / cell).astype(np.int64)
        prof = self.profile.setdefault(key, {})
        for a, b, v in zip(ix, iy, z):
            k = f"{a},{b}"
            if v < prof.get(k, np.inf):
                prof[k] = float(v)

    def result(self) -> dict:
        return dict(self.low)

    def profiles(self) -> dict:
        return {k: dict(v) for k, v in self.profile.items()}


def flatten_dem_tiles(results: dict, bodies, run, progress=None, out=None) -> dict:
    """Every DEM tile a water body reaches flattened: a lake at its lowest shore elevation, a river at levels
    stepping down along its flow (river_surface); the nDSM redone. Returns {"bodies": {key: {"kind", "elevation"
    (a lake's; a river's lowest), "highest" (a river's), "cells"}}, "tiles": {tile: cells changed}}. ``results``: the
    rasters' TileResults (their ``shore_minima`` and ``shore_profile`` from pass 1, their ``outputs``). The tiles go
    through the engine's task loop: ``progress`` told after each (and may cancel), a tile that fails is marked failed
    with its error and the others go on, a failed write to the folder ``out`` (a full disk) stops the run."""
    import shapely
    from ..engine.batch import run_each
    from ..progress import report

    kept = [r for r in results.values() if r.status in ("ok", "skipped")]
    lows = merge_minima(r.shore_minima for r in kept)
    polys = {key: shapely.from_wkb(wkb) for key, wkb, _band, _cell in bodies}
    surfaces = _surfaces(bodies, kept, lows, polys)
    summary = {"bodies": {}, "tiles": {}}
    for key, surface in surfaces.items():
        levels = getattr(surface, "levels", None)
        kind, levels = ("river", levels) if levels is not None else ("lake", [lows[key]])
        summary["bodies"][key] = {"kind": kind, "elevation": float(min(levels)), "highest": float(max(levels)), "cells": 0}
    names = [n for n, r in results.items() if r.status in ("ok", "skipped") and (r.outputs or {}).get("dem")]
    done = []

    def on_done(name, changed, _seconds):
        if changed:
            summary["tiles"][name] = changed

    def tick(message):
        done.append(message)
        report(progress, len(done) / len(names), message)

    run_each(lambda name: _flatten_tile(results[name], results[name].outputs["dem"], polys, surfaces, run,
                                        summary["bodies"]),
             [(n,) for n in names], None, results, names, on_done, tick, "flattened", out)
    return summary


def _surfaces(bodies, kept, lows: dict, polys: dict) -> dict:
    """{body: a function (x, y) -> water level} for the bodies with a shore: a river's steps, a lake's one level."""
    surfaces = {}
    for key, _wkb, _band, cell in bodies:
        if key not in lows:
            continue
        profile: dict = {}
        for r in kept:
            for k, v in (r.shore_profile or {}).get(key, {}).items():
                profile[k] = min(v, profile.get(k, np.inf))
        river = river_surface(polys[key], profile, cell) if cell and profile else None
        surfaces[key] = river if river is not None else (lambda x, y, z=lows[key]: np.full(len(x), z))
    return surfaces


def river_surface(poly, profile: dict, cell: float):
    """The water levels of a river polygon: a function (x, y) -> level of points inside it, with ``.levels``. The
    distance along the river is the geodesic distance inside the polygon (on a grid of ``cell``, coarser for a
    long river) from one of its two ends (the two cells farthest apart by a double sweep); the shore's lowest
    points (``profile``: {"ix,iy": z} on the ``cell`` lattice) go to the nearest inside cell, and the levels come
    from lidar.hydro.river_levels over bins of 4 cells. None when the polygon is too small for it."""
    import shapely
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    w, s, e, n = poly.bounds
    g = max(cell, math.sqrt((e - w) * (n - s) / 2e6))
    X, Y = np.meshgrid(np.arange(w + g / 2, e, g), np.arange(n - g / 2, s, -g))
    inside = shapely.contains_xy(poly, X, Y)
    if inside.sum() < 4:
        return None
    index = np.full(inside.shape, -1, np.int64)
    index[inside] = np.arange(int(inside.sum()))
    pairs = [np.column_stack([index[:, :-1][inside[:, :-1] & inside[:, 1:]], index[:, 1:][inside[:, :-1] & inside[:, 1:]]]),
             np.column_stack([index[:-1][inside[:-1] & inside[1:]], index[1:][inside[:-1] & inside[1:]]])]
    ij = np.concatenate(pairs)
    m = int(inside.sum())
    graph = coo_matrix((np.full(len(ij), g), (ij[:, 0], ij[:, 1])), shape=(m, m)).tocsr()
    d = dijkstra(graph, directed=False, indices=0)
    end = int(np.argmax(np.where(np.isfinite(d), d, -1)))
    along = dijkstra(graph, directed=False, indices=end)
    ok = np.isfinite(along)
    centres = np.column_stack([X[inside], Y[inside]])[ok]
    along = along[ok]
    tree = cKDTree(centres)
    keys = np.array([[int(v) for v in k.split(",")] for k in profile], np.float64)
    shore_xy = (keys + 0.5) * cell
    s_shore = along[tree.query(shore_xy)[1]]
    step = 4 * g
    _edges, levels, _forward = river_levels(s_shore, np.array(list(profile.values())), step)

    def level(x, y):
        s_at = along[tree.query(np.column_stack([x, y]))[1]]
        return levels[np.minimum((s_at / step).astype(np.int64), len(levels) - 1)]

    level.levels = levels
    return level


def _flatten_tile(r, dem_path, polys: dict, surfaces: dict, run, bodies_summary: dict) -> int:
    import shapely
    dem, grid, _ = read_raster(dem_path)
    frame = shapely.box(*grid.bounds)
    xs, ys = cell_centres(grid)
    changed = 0
    for key, poly in polys.items():
        if key not in surfaces or not poly.intersects(frame):
            continue
        rows, cols = _window(grid, poly.bounds)
        if rows.start >= rows.stop or cols.start >= cols.stop:
            continue
        X, Y = np.meshgrid(xs[cols], ys[rows])
        inside = shapely.contains_xy(poly, X, Y)
        if not inside.any():
            continue
        part = dem[rows, cols]
        n = flatten_cells(part, inside, surfaces[key](X[inside], Y[inside]))
        dem[rows, cols] = part
        bodies_summary[key]["cells"] += int(inside.sum())
        changed += n
    if changed:
        _rewrite(r, dem_path, dem, grid, run)
    return changed


def _rewrite(r, dem_path, dem, grid, run) -> None:
    """The flattened DEM, and the nDSM from it, written over the tile's (atomically)."""
    tags = {"GISTOOLS_CELL_SIZE": run.cell_size, "GISTOOLS_Z_UNIT": run.z_unit, "GISTOOLS_DEM_METHOD": run.dem_method}
    write_raster(dem_path, dem, grid, overwrite=True, units=run.z_unit, tags={**tags, "GISTOOLS_PRODUCT": "dem",
                 "GISTOOLS_HYDRO_FLATTENED": "yes"}, description=f"DEM height ({run.z_unit})")
    ndsm_path = (r.outputs or {}).get("ndsm")
    dsm_path = (r.outputs or {}).get("dsm")
    if ndsm_path and dsm_path:
        dsm, _, _ = read_raster(dsm_path)
        write_raster(ndsm_path, ndsm_from(dsm, dem), grid, overwrite=True, units=run.z_unit,
                     tags={**tags, "GISTOOLS_PRODUCT": "ndsm"}, description=f"NDSM height ({run.z_unit})")


def _window(grid, bounds) -> tuple[slice, slice]:
    """The rows and columns of ``grid`` whose cells meet ``bounds`` (west, south, east, north)."""
    w, s, e, n = bounds
    cs = grid.cell_size
    c0 = max(int(np.floor(w / cs)) - grid.col0, 0)
    c1 = min(int(np.floor(e / cs)) - grid.col0 + 1, grid.width)
    r0 = max(grid.row_top - int(np.floor(n / cs)) - 1, 0)
    r1 = min(grid.row_top - int(np.floor(s / cs)), grid.height)
    return slice(r0, r1), slice(c0, c1)
