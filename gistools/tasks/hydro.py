"""Hydro-flattening of the rasters' DEM (``gistools rasters --hydro-flatten LAYER``).

Pass 1 of the rasters (tasks.rasters._scan_tile) keeps, per water body near the tile, the lowest ground point within
the shore band (``shore_width`` outside the polygon's edge); after pass 2 the minima of all the tiles are merged (a
lake's shore crosses tiles) and every DEM cell whose centre lies inside the polygon takes that elevation, filled
where it had none; the nDSM follows. The tiles' DEM and nDSM GeoTIFFs are rewritten (atomically) where a water body
reaches them; a rerun does the same, so resumed runs stay flat.
"""

from __future__ import annotations

import numpy as np
import shapely

from ..grid import cell_centres
from ..io.raster import read_raster, write_raster
from ..lidar.gridding import ndsm_from
from ..lidar.hydro import flatten_cells, merge_minima

__all__ = ["water_bodies", "ShoreMinima", "flatten_dem_tiles"]


def water_bodies(polygons, shore_width: float) -> tuple:
    """(key, polygon WKB, shore band WKB) of each water polygon (the band: ``shore_width`` outside its edge, holes'
    islands included), picklable for the workers."""
    bodies = []
    for k, g in enumerate(polygons):
        if g is None or g.is_empty or g.area <= 0:
            continue
        band = g.buffer(shore_width).difference(g)
        bodies.append((str(k), shapely.to_wkb(g), shapely.to_wkb(band)))
    return tuple(bodies)


class ShoreMinima:
    """The lowest ground point of each water body's shore band among a tile's chunks."""

    def __init__(self, bodies, bounds, margin: float):
        w, s, e, n = bounds
        area = shapely.box(w - margin, s - margin, e + margin, n + margin)
        self.bands = []
        for key, _poly, band_wkb in bodies:
            band = shapely.from_wkb(band_wkb)
            if band.intersects(area):
                shapely.prepare(band)
                self.bands.append((key, band, band.bounds))
        self.low: dict = {}

    def add(self, x, y, z_of, ground) -> None:
        """Ground points of a chunk (mask ``ground``; ``z_of(mask)``: their z)."""
        for key, band, (bw, bs, be, bn) in self.bands:
            near = ground & (x >= bw) & (x <= be) & (y >= bs) & (y <= bn)
            if not near.any():
                continue
            idx = np.flatnonzero(near)
            on = shapely.contains_xy(band, x[idx], y[idx])
            if on.any():
                sel = np.zeros(len(x), bool)
                sel[idx[on]] = True
                low = float(z_of(sel).min())
                self.low[key] = min(low, self.low.get(key, np.inf))

    def result(self) -> dict:
        return dict(self.low)


def flatten_dem_tiles(results: dict, bodies, run) -> dict:
    """Every DEM tile a water body reaches flattened at the body's lowest shore elevation (and its nDSM redone);
    returns {"bodies": {key: {"elevation", "cells"}}, "tiles": {tile: cells changed}}. ``results``: the rasters'
    TileResults (their ``shore_minima`` from pass 1, their ``outputs``)."""
    lows = merge_minima(r.shore_minima for r in results.values() if r.status in ("ok", "skipped"))
    polys = {key: shapely.from_wkb(wkb) for key, wkb, _band in bodies}
    summary = {"bodies": {k: {"elevation": lows.get(k), "cells": 0} for k in polys}, "tiles": {}}
    for name, r in results.items():
        dem_path = (r.outputs or {}).get("dem")
        if r.status not in ("ok", "skipped") or not dem_path:
            continue
        changed = _flatten_tile(r, dem_path, polys, lows, run, summary["bodies"])
        if changed:
            summary["tiles"][name] = changed
    return summary


def _flatten_tile(r, dem_path, polys: dict, lows: dict, run, bodies_summary: dict) -> int:
    dem, grid, _ = read_raster(dem_path)
    frame = shapely.box(*grid.bounds)
    xs, ys = cell_centres(grid)
    changed = 0
    for key, poly in polys.items():
        if key not in lows or not poly.intersects(frame):
            continue
        rows, cols = _window(grid, poly.bounds)
        if rows.start >= rows.stop or cols.start >= cols.stop:
            continue
        X, Y = np.meshgrid(xs[cols], ys[rows])
        inside = shapely.contains_xy(poly, X, Y)
        part = dem[rows, cols]
        n = flatten_cells(part, inside, lows[key])
        dem[rows, cols] = part
        bodies_summary[key]["cells"] += int(inside.sum())
        changed += n
    if changed:
        tags = {"GISTOOLS_CELL_SIZE": run.cell_size, "GISTOOLS_Z_UNIT": run.z_unit, "GISTOOLS_DEM_METHOD": run.dem_method}
        write_raster(dem_path, dem, grid, overwrite=True, units=run.z_unit, tags={**tags, "GISTOOLS_PRODUCT": "dem",
                     "GISTOOLS_HYDRO_FLATTENED": "yes"}, description=f"DEM height ({run.z_unit})")
        ndsm_path = (r.outputs or {}).get("ndsm")
        dsm_path = (r.outputs or {}).get("dsm")
        if ndsm_path and dsm_path:
            dsm, _, _ = read_raster(dsm_path)
            write_raster(ndsm_path, ndsm_from(dsm, dem), grid, overwrite=True, units=run.z_unit,
                         tags={**tags, "GISTOOLS_PRODUCT": "ndsm"}, description=f"NDSM height ({run.z_unit})")
    return changed


def _window(grid, bounds) -> tuple[slice, slice]:
    """The rows and columns of ``grid`` whose cells meet ``bounds`` (west, south, east, north)."""
    w, s, e, n = bounds
    cs = grid.cell_size
    c0 = max(int(np.floor(w / cs)) - grid.col0, 0)
    c1 = min(int(np.floor(e / cs)) - grid.col0 + 1, grid.width)
    r0 = max(grid.row_top - int(np.floor(n / cs)) - 1, 0)
    r1 = min(grid.row_top - int(np.floor(s / cs)), grid.height)
    return slice(r0, r1), slice(c0, c1)
