"""What observers see (``gistools viewshed``, ``gistools:viewshed``): a visibility raster of a surface (the DSM by
default: trees and buildings hide a person; or the DEM), from one or several observers, as GDAL's gdal_viewshed.

The algorithm is gdal_viewshed's (as in GDAL 3.6, its default "edge" mode; later GDAL versions count the cells next
to the observer as always seen, where here they are seen over the observer cell's own height): Wang, Robinson and
White (2000),
"Generating viewsheds without using sightlines" - each cell's horizon height is interpolated from the two cells
next to it on the side of the observer, in one sweep outward from the observer, so a cell is seen when it (plus the
target height) is not below the plane through the observer's eye and the horizon already passed. GDAL's Python
bindings (``gdal.ViewshedGenerate``) are not part of rasterio, so the sweep is written here in numpy: each of the
four wedges around the observer (east, west: |dx| >= |dy|; north, south: |dy| > |dx|) is swept ring by ring, a
whole ring at once.

Units: x, y in the CRS's unit; heights in the surface's vertical unit (its band unit, else its CRS's); the
observer and target heights are lengths with a unit ("6ft", "2m"). Earth curvature (optional) lowers a cell at
distance d by coefficient x d^2 / the ellipsoid's diameter, as gdal_viewshed -cc (with d and the diameter in one
unit: gdal_viewshed takes the diameter in metres whatever the CRS's unit, so the two agree on metre CRSs only).
"""

from __future__ import annotations

import math
import time

import numpy as np
from rasterio.windows import Window

from ..docstrings import shared_sections
from ..errors import InputError
from ..io.blocks import BLOCK, check_outputs_are_not_inputs, open_raster, raster_crs, run_blockwise
from ..io.outdir import claim_output, output_folder
from ..parameters import option
from ..progress import ProgressCallback, sub_progress
from ..units import length_to_crs_units
from ..terrain.viewshed import viewshed_array
from .terrain import elevation_units, resolve_dem

__all__ = ["viewshed_array", "viewshed_from_surface", "parse_observers", "VISIBLE", "HIDDEN", "VIS_NODATA",
           "COUNT_NODATA"]

VISIBLE, HIDDEN, VIS_NODATA = 1, 0, 255
COUNT_NODATA = 65535
def parse_observers(observers) -> list[tuple[float, float]]:
    """Observer positions from "X,Y" texts (several separated by ;), (x, y) pairs, or a mix."""
    if observers is None:
        return []
    if isinstance(observers, str):
        observers = [observers]
    found = []
    for item in observers:
        if isinstance(item, str):
            for part in item.split(";"):
                if not part.strip():
                    continue
                try:
                    x, y = (float(v) for v in part.replace(" ", "").split(","))
                except ValueError:
                    raise InputError(f"{option('observer', part)} is not a position X,Y",
                                     hint=f"e.g. {option('observer', '565300,654400')}") from None
                found.append((x, y))
        else:
            x, y = item
            found.append((float(x), float(y)))
    return found


def _layer_observers(layer, crs) -> list[tuple[float, float]]:
    from ..io.vector import check_crs, read_layer

    gdf = check_crs(read_layer(layer, ("point",), what="observers"), crs, str(layer), against="the surface's",
                    reproject=None)
    points = []
    for geom in gdf.geometry:
        if geom is None or geom.is_empty:
            continue
        for p in getattr(geom, "geoms", [geom]):
            points.append((float(p.x), float(p.y)))
    return points


@shared_sections
def viewshed_from_surface(surface, out, *, observers=None, observers_layer=None, observer_height=None,
                          target_height="0", surface_kind: str = "dsm", max_distance="0", curvature: bool = False,
                          curvature_coefficient: float = 0.85714, z_unit: str | None = "raster",
                          overwrite: bool = False, progress: ProgressCallback | None = None) -> dict:
    """Cells seen from one or several observers, as gdal_viewshed: ``gistools viewshed``.

    Writes ``out/viewshed.tif``, ``out/viewshed_count.tif`` and ``out/report.json``. The surface is the DSM by default
    (trees and buildings hide a person) or the DEM; a cell is seen when a point ``target_height`` above it is in
    sight of an eye ``observer_height`` above the observer's cell (gdal_viewshed's default mode).

    Parameters
    ----------
    surface : str or path
        A surface raster (GeoTIFF or VRT mosaic), or a folder written by ``gistools rasters`` (its ``dsm.vrt``, or
        its ``dem.vrt`` with ``surface_kind="dem"``). The part read is held in memory, 8 bytes a cell.
    out : str or path
        Output folder, made when missing: ``viewshed.tif`` (uint8: 1 seen by at least one observer, 0 hidden, 255
        where the surface has no value) and ``viewshed_count.tif`` (uint16: how many observers see each cell, 65535
        nodata).
    observers : str or sequence, optional
        Observer positions in the surface's CRS: ``"X,Y"`` (several separated by ``;``), or (x, y) pairs.
    observers_layer : str, optional
        A point layer of observers (a path or ``file.gpkg:LAYER``) in the surface's CRS, added to ``observers``.
    observer_height : str or float, optional
        The eye above the surface at the observer: a length with its unit (``"6ft"``, ``"2m"``) or a number in the
        surface's vertical unit. None: 6ft on data in feet, 2m on metre data.
    target_height : str or float
        Height above a cell that must be in sight for the cell to be seen, likewise (default 0).
    surface_kind : str
        With a folder: ``"dsm"`` (its ``dsm.vrt``) or ``"dem"`` (its ``dem.vrt``).
    max_distance : str or float
        Only cells within this distance of an observer are computed (gdal_viewshed ``-md``): a length with its unit,
        or a number in CRS units. The outputs then cover the observers' ranges only (cells beyond every range 0),
        and only that part of the surface is read. ``"0"``: no limit, the whole raster.
    curvature : bool
        Lower distant cells for the earth's curvature (gdal_viewshed ``-cc``).
    curvature_coefficient : float
        With ``curvature``: a cell at distance d is lowered by coefficient x d^2 / the ellipsoid's diameter; 0-1,
        1 minus the refraction coefficient (gdal_viewshed's 0.85714: a refraction of 1/7).
    z_unit : str
        The surface's vertical unit, ``"m"``, ``"ft"`` or ``"ftUS"``; or ``"raster"``: its band's unit, else its
        CRS's vertical unit, else the horizontal unit.
    overwrite : bool
        Replace existing outputs. Without it, the outputs of an earlier run with the same settings on the same
        surface are kept (its report is returned), and outputs of other settings are refused.
    progress : callable, optional
        ``progress(fraction, message)``, told as each observer's sweep goes; returning False cancels the run.

    Returns
    -------
    dict
        The report, also written to ``out/report.json``: ``observers`` (per observer ``x``, ``y``, ``row``, ``col``,
        ``eye_elevation`` in the vertical unit, ``cells_seen``), ``cells_seen`` and ``area_seen`` (in
        ``area_unit``, the CRS unit squared) seen by at least one observer, ``outputs``, ``settings``, ``units``
        (heights and distance as used, in the data's units), ``extent`` (the window of the surface written).

    Raises
    ------
    InputError
        An option is not valid, no observer is given, an observer is outside the surface or on a cell without a
        value, the surface is not found, has no CRS or is rotated, or an output would overwrite it.
    DataFileError
        The surface cannot be read.
    {raster_raise_rest}

    Examples
    --------
    >>> from gistools import rasters_from_tiles, viewshed_from_surface
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> report = viewshed_from_surface("rasters", "viewshed", observers="431000,1811000",
    ...                                observer_height="6ft")  # doctest: +SKIP
    >>> report["cells_seen"], report["area_seen"], report["area_unit"]  # doctest: +SKIP
    (42236, 1055900.0, 'square ftUS')
    """
    started = time.time()
    _check_options(surface_kind, curvature_coefficient)
    points = parse_observers(observers)
    path = resolve_dem(surface, surface_kind)
    out = output_folder(out)
    targets = {"visibility": out / "viewshed.tif", "count": out / "viewshed_count.tif"}
    check_outputs_are_not_inputs(targets, [path])
    with open_raster(path, "surface") as src:
        crs = raster_crs(src, path)
        xy, zu, source = elevation_units(src, path, z_unit)
        if observers_layer:
            points += _layer_observers(observers_layer, crs)
        if observer_height is None:
            from ..parameters import default_for

            observer_height = default_for("observer_height", zu.is_foot)
        eye_h, tgt_h = _heights(observer_height, target_height, zu)
        reach = length_to_crs_units(max_distance, xy, name="max distance")
        if reach < 0:
            raise InputError(f"{option('max_distance', max_distance)} is negative", hint=f"e.g. {option('max_distance', '3000ft')}")
        cells = _observer_cells(src, path, points)
        windows = [_range_window(src, row, col, reach) for row, col in cells]
        extent = Window(min(w.col_off for w in windows), min(w.row_off for w in windows), 0, 0)
        extent = Window(extent.col_off, extent.row_off,
                        max(w.col_off + w.width for w in windows) - extent.col_off,
                        max(w.row_off + w.height for w in windows) - extent.row_off)
        z = src.read(1, window=extent, masked=True).astype(np.float64).filled(np.nan)
        _on_data(path, points, [(r - extent.row_off, c - extent.col_off) for r, c in cells], z)
        factor = _curvature_factor(crs, xy, zu, curvature_coefficient) if curvature else 0.0
        settings = {"observers": [list(p) for p in points], "observer_height": str(observer_height),
                    "target_height": str(target_height), "surface": surface_kind, "max_distance": str(max_distance),
                    "curvature": bool(curvature),
                    "curvature_coefficient": curvature_coefficient, "z_unit": z_unit}
        with claim_output(out, "gistools viewshed"):
            from ..engine.record import add_run, read_folder_report, write_folder_report
            from ..engine.resume import made_record, rerun_plan

            previous = read_folder_report(out)
            if len(rerun_plan(previous, "gistools viewshed", str(path), settings, targets, overwrite, ignore=())) == len(targets):
                add_run(out, {**previous, "seconds": round(time.time() - started, 3),
                              "counts": {"ok": 0, "skipped": 1, "failed": 0}})
                return previous  # made before with these settings: kept
            t = src.transform
            count = np.zeros(z.shape, np.uint16 if len(cells) < COUNT_NODATA else np.uint32)  # never wraps
            seen = []
            for i, ((row, col), (x, y), w) in enumerate(zip(cells, points, windows)):
                share = _labelled(sub_progress(progress, 0.9 * i / len(cells), 0.9 * (i + 1) / len(cells)),
                                  f"viewshed: observer {i + 1} of {len(cells)}")
                r0, c0 = w.row_off - extent.row_off, w.col_off - extent.col_off
                part = (slice(r0, r0 + w.height), slice(c0, c0 + w.width))
                vis = viewshed_array(z[part], row - w.row_off, col - w.col_off, observer_height=eye_h,
                                     target_height=tgt_h, curvature=factor, cell=(abs(t.a), abs(t.e)),
                                     max_distance=reach, progress=share)
                vis &= np.isfinite(z[part])
                count[part] += vis
                seen.append({"x": x, "y": y, "row": row, "col": col, "eye_elevation": float(z[row - extent.row_off,
                             col - extent.col_off] + eye_h), "cells_seen": int(vis.sum())})
            paths = _write(_Extent(src, extent), targets, count, ~np.isfinite(z), True,  # rerun_plan refused the rest
                           sub_progress(progress, 0.9, 1.0))
            rep = {"tool": "gistools viewshed", "input": str(path),
                   "made": made_record(previous, "gistools viewshed", str(path), settings, paths), "crs": crs.name,
                   "outputs": {k: str(v) for k, v in paths.items()}, "observers": seen, "settings": settings,
                   "units": {"horizontal": xy.short, "vertical": zu.short, "vertical_from": source,
                             "observer_height": eye_h, "target_height": tgt_h, "max_distance": reach,
                             "curvature_per_unit2": factor},
                   "extent": {"col_off": int(extent.col_off), "row_off": int(extent.row_off), "width": int(extent.width),
                              "height": int(extent.height)},
                   "cells_seen": int((count > 0).sum()), "area_seen": float((count > 0).sum() * abs(t.a * t.e)),
                   "area_unit": f"square {xy.short}", "method": "gdal_viewshed's (Wang et al. 2000), edge mode",
                   "seconds": round(time.time() - started, 3)}
            if source == "horizontal":
                rep["warnings"] = [f"the surface carries no vertical unit: its heights are taken in {xy.short}"]
            return write_folder_report(out, rep)


def _labelled(progress, text: str):
    """``progress`` with its messages replaced by ``text``."""
    if progress is None:
        return None
    return lambda fraction, message="": progress(fraction, text)


def _check_options(surface_kind, curvature_coefficient) -> None:
    from ..parameters.terrain import SURFACES

    if surface_kind not in SURFACES:
        raise InputError(f"{option('hiding_surface', surface_kind)} is not dsm or dem",
                         hint=f"e.g. {option('hiding_surface', 'dsm')}")
    if not 0 <= float(curvature_coefficient) <= 1:
        raise InputError(f"{option('curvature_coefficient', curvature_coefficient)} is not between 0 and 1",
                         hint=f"e.g. {option('curvature_coefficient', 0.85714)}")


def _heights(observer_height, target_height, zu) -> tuple[float, float]:
    eye_h = length_to_crs_units(observer_height, zu, name="observer height")
    tgt_h = length_to_crs_units(target_height, zu, name="target height")
    if eye_h < 0 or tgt_h < 0:
        raise InputError(f"{option('observer_height', observer_height)} and {option('target_height', target_height)} "
                         "must not be negative", hint=f"e.g. {option('observer_height', '6ft')}")
    return eye_h, tgt_h


def _observer_cells(src, path, points) -> list[tuple[int, int]]:
    """The (row, col) of each observer (gdal_viewshed's: the cell its position falls in), refused outside the
    raster."""
    if not points:
        raise InputError(f"no observer: give {option('observer', '565300,654400')} or {option('observers')}",
                         hint="Positions are in the surface's CRS")
    t = src.transform
    if t.b != 0 or t.d != 0:
        raise InputError("the surface is rotated", path=path, hint="Warp it north-up first (gdalwarp)")
    if t.e > 0:
        raise InputError("the surface is south-up (its rows run from south to north)", path=path,
                         hint="Warp it north-up first (gdalwarp in.tif north_up.tif)")
    cells = []
    for x, y in points:
        col, row = (x - t.c) / t.a, (y - t.f) / t.e
        if not (0 <= col < src.width and 0 <= row < src.height):
            raise InputError(f"observer {x:.10g},{y:.10g} is outside the surface raster", path=path,
                             hint=f"Give a position within {src.bounds.left:.10g}..{src.bounds.right:.10g}, "
                                  f"{src.bounds.bottom:.10g}..{src.bounds.top:.10g}")
        cells.append((int(row), int(col)))
    return cells


def _on_data(path, points, cells, z) -> None:
    for (x, y), (row, col) in zip(points, cells):
        if not np.isfinite(z[row, col]):
            raise InputError(f"observer {x:.10g},{y:.10g} stands on a cell without a height (nodata)", path=path,
                             hint="Move the observer onto data")


def _range_window(src, row: int, col: int, reach: float) -> Window:
    """The cells gdal_viewshed computes for an observer at (row, col) within ``reach`` (0: the whole raster)."""
    if not reach:
        return Window(0, 0, src.width, src.height)
    cw, ch = abs(src.transform.a), abs(src.transform.e)
    x0, x1 = max(0, math.floor(col - reach / cw)), min(src.width, math.ceil(col + reach / cw) + 1)
    y0, y1 = max(0, math.floor(row - reach / ch)), min(src.height, math.ceil(row + reach / ch) + 1)
    return Window(x0, y0, x1 - x0, y1 - y0)


class _Extent:
    """The part ``window`` of raster ``src`` as the grid the outputs are written on."""

    def __init__(self, src, window: Window):
        self.width, self.height, self.crs = int(window.width), int(window.height), src.crs
        self.transform = src.window_transform(window)


def _curvature_factor(crs, xy, zu, coefficient: float) -> float:
    """gdal_viewshed's coefficient / (2 x semi-major axis), with the axis in the CRS's horizontal unit, as a lowering
    in the vertical unit per squared horizontal unit."""
    semi_major = (crs.ellipsoid.semi_major_metre if crs.ellipsoid else 6378137.0) / xy.metres
    return coefficient / (2 * semi_major) * xy.metres / zu.metres


def _write(src, targets, count, nodata, overwrite, progress) -> dict:
    wide = count.dtype == np.uint32  # 65,535 observers or more: a 32-bit count, its own nodata
    count_nodata = np.iinfo(np.uint32).max if wide else COUNT_NODATA
    outputs = {"visibility": (targets["visibility"], "uint8", VIS_NODATA, {"GISTOOLS_PRODUCT": "viewshed"}),
               "count": (targets["count"], str(count.dtype), count_nodata, {"GISTOOLS_PRODUCT": "viewshed_count"})}

    def compute(win):
        sl = (slice(win.row_off, win.row_off + win.height), slice(win.col_off, win.col_off + win.width))
        c, nd = count[sl], nodata[sl]
        return {"visibility": np.where(nd, VIS_NODATA, (c > 0).astype(np.uint8)), "count": np.where(nd, count_nodata, c)}

    return run_blockwise(src, outputs, compute, progress=progress, label="viewshed", overwrite=overwrite, block=BLOCK)
