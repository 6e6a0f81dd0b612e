"""The one blockwise runner of the shrub steps: rasters read and written window by window.

A step is a function of a window (arrays in, arrays out, from ``gistools.lidar``); this module opens its
inputs (a tile's GeoTIFF, a county's VRT mosaic, any single-band raster on the lattice), reads each window
(with a halo where the step needs neighbours), and writes the outputs block by block into tiled GeoTIFFs,
atomically and checked. The chain runs it over each tile, the step commands and QGIS over a tile or a
mosaic: one implementation of each step (``gistools.products.steps``).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import pyproj
import rasterio
import shapely
from rasterio.features import rasterize
from rasterio.windows import Window, from_bounds

from ..errors import CRSMismatchError, DataFileError, InputError
from ..grid import affine_apply
from ..progress import report
from .raster import (DEFLATE_LEVEL, atomic_path, crs_from_wkt, predictor_for, set_colour_table, verify_raster,
                     write_category_names)

BLOCK = 2048  # cells a side of the windows a step reads at once (32 MB of float64)


def open_raster(path, what: str):
    """A rasterio dataset, or a DataFileError naming the file."""
    try:
        return rasterio.open(path)
    except Exception as err:  # rasterio raises RasterioIOError, CPLE_* for unreadable files
        raise DataFileError(f"cannot open the {what} raster ({err})", path=path,
                            hint="Give a GeoTIFF or VRT written by gistools (or any single-band raster on the same grid)") from None


def raster_crs(src, path) -> pyproj.CRS:
    if src.crs is None:
        raise InputError("raster has no CRS", path=path, hint="Assign one (gdal_edit.py -a_srs) or rerun the step that wrote it")
    return crs_from_wkt(src.crs.to_wkt())


def same_grid(base, base_path, other, other_path) -> None:
    """Refuse ``other`` unless it shares ``base``'s CRS and cell lattice."""
    a, b = raster_crs(base, base_path), raster_crs(other, other_path)
    if not a.equals(b, ignore_axis_order=True):
        raise CRSMismatchError(f"CRS {b.name!r} differs from {a.name!r} of {base_path}", path=other_path,
                               hint="Give rasters of one run (same CRS), or reproject one with gdalwarp")
    ta, tb = base.transform, other.transform
    cs = ta.a
    offx, offy = (tb.c - ta.c) / cs, (tb.f - ta.f) / cs
    if abs(tb.a - cs) > 1e-9 * cs or abs(offx - round(offx)) > 1e-6 or abs(offy - round(offy)) > 1e-6:
        raise InputError(f"raster is not on the cell lattice of {base_path} (cell {tb.a} vs {cs})", path=other_path,
                         hint="Give rasters of one run, or align it with gdalwarp -tr CELL CELL -tap")


def read_window(src, base, win: Window, *, halo: int = 0, fill=None) -> np.ndarray:
    """Window ``win`` of ``base``'s grid (grown by ``halo`` cells) read from ``src`` (same lattice); float nodata -> NaN.

    Cells outside ``src`` are ``fill`` (default: its nodata, NaN for floats).
    """
    west, north = affine_apply(base.transform, (win.col_off - halo, win.row_off - halo))
    cs = base.transform.a
    east, south = west + (win.width + 2 * halo) * cs, north - (win.height + 2 * halo) * cs
    w = from_bounds(west, south, east, north, src.transform).round_offsets().round_lengths()
    nodata = src.nodata
    if fill is None:
        fill = nodata if nodata is not None else 0
    # the part inside src read as is, the rest filled: what a boundless read gives, without the warped VRT rasterio
    # builds for one (4-5 times slower on a tile)
    r0, c0, h, wd = int(w.row_off), int(w.col_off), int(w.height), int(w.width)
    data = np.full((h, wd), fill, dtype=src.dtypes[0])
    rr0, rr1, cc0, cc1 = max(r0, 0), min(r0 + h, src.height), max(c0, 0), min(c0 + wd, src.width)
    if rr1 > rr0 and cc1 > cc0:
        data[rr0 - r0:rr1 - r0, cc0 - c0:cc1 - c0] = src.read(1, window=Window(cc0, rr0, cc1 - cc0, rr1 - rr0), masked=False)
    if np.issubdtype(data.dtype, np.floating):
        data = data.astype(np.float64)
        if nodata is not None:
            data[data == nodata] = np.nan
    return data


def windows(width: int, height: int, block: int = BLOCK):
    """The windows of a ``width`` x ``height`` grid, ``block`` cells a side (0: the whole grid at once)."""
    if block <= 0:
        block = max(width, height, 1)
    for row in range(0, height, block):
        for col in range(0, width, block):
            yield Window(col, row, min(block, width - col), min(block, height - row))


def window_bounds(base, win: Window) -> tuple[float, float, float, float]:
    west, north = affine_apply(base.transform, (win.col_off, win.row_off))
    east, south = affine_apply(base.transform, (win.col_off + win.width, win.row_off + win.height))
    return west, south, east, north


def _profile(base, dtype: str, nodata, product: str | None = None) -> dict:
    return dict(driver="GTiff", width=base.width, height=base.height, count=1, dtype=dtype, crs=base.crs,
                transform=base.transform, nodata=nodata, compress="deflate", zlevel=DEFLATE_LEVEL,
                predictor=predictor_for(dtype, product),
                tiled=True, blockxsize=256, blockysize=256, BIGTIFF="IF_SAFER")


def check_outputs_are_not_inputs(outputs: dict, inputs) -> None:
    ins = {Path(p).resolve() for p in inputs if p is not None}
    for path in outputs.values():
        if path is not None and Path(path).resolve() in ins:
            raise InputError("the output would overwrite an input", path=path, hint="Choose another output file")


def run_blockwise(base, outputs: dict, compute, *, progress=None, label: str = "", overwrite: bool = True,
                  block: int = BLOCK) -> dict:
    """Write each product of ``outputs`` {name: (path | None, dtype, nodata, tags)} on ``base``'s grid, window by window.

    ``compute(window) -> {name: array}`` (float NaN -> nodata). Every file is written under a partial name
    and renamed only when all windows are done and it reads back, so a cancelled or failed run leaves no
    output at all. With no outputs it only runs ``compute`` over the windows (a summary of rasters).
    Returns {name: path}.
    """
    wins = list(windows(base.width, base.height, block))
    wanted = {k: v for k, v in outputs.items() if v[0] is not None}
    with contextlib.ExitStack() as stack:
        dsts = {}
        styled = {}
        for name, (path, dtype, nodata, tags) in wanted.items():
            tags = dict(tags or {})
            categories = tags.pop("categories", None)  # {code: (name, colour)}: colour table and category names
            tmp = stack.enter_context(atomic_path(path, overwrite=overwrite, verify=verify_raster))
            dst = stack.enter_context(rasterio.open(tmp, "w", **_profile(base, dtype, nodata, tags.get("GISTOOLS_PRODUCT"))))
            dst.update_tags(**{k: str(v) for k, v in tags.items()})
            if tags.get("units"):
                dst.units = (tags["units"],)
            if categories:
                set_colour_table(dst, categories)
                styled[path] = categories
            dsts[name] = (dst, dtype, nodata)
        for i, win in enumerate(wins):
            if label:
                report(progress, i / max(len(wins), 1), f"{label}: block {i + 1} of {len(wins)}")
            arrays = compute(win)
            for name, (dst, dtype, nodata) in dsts.items():
                a = np.asarray(arrays[name])
                if np.issubdtype(a.dtype, np.floating) and not np.issubdtype(np.dtype(dtype), np.floating):
                    raise AssertionError("float block for an integer raster")
                if np.issubdtype(a.dtype, np.floating):
                    a = np.where(np.isnan(a), nodata, a)
                dst.write(a.astype(dtype), 1, window=win)
        # the rasterio datasets close before the atomic renames (ExitStack unwinds in reverse)
    for path, categories in styled.items():
        write_category_names(path, categories)
    if label:
        report(progress, 1.0, f"{label}: done")
    return {name: Path(v[0]) for name, v in wanted.items()}


class PolygonMask:
    """Cells of a window whose centre lies in any of ``geoms`` (the Clip of the dissertation's Raster To Point
    centres: rasterize with all_touched=False)."""

    def __init__(self, geoms):
        self.geoms = [g for g in (geoms or []) if g is not None and not g.is_empty]
        self.tree = shapely.STRtree(self.geoms) if self.geoms else None

    def __call__(self, base, win: Window) -> np.ndarray:
        shape = (int(win.height), int(win.width))
        if self.tree is None:
            return np.zeros(shape, bool)
        hits = [self.geoms[i] for i in self.tree.query(shapely.box(*window_bounds(base, win)))]
        if not hits:
            return np.zeros(shape, bool)
        return rasterize(hits, out_shape=shape, transform=base.window_transform(win), fill=0, default_value=1,
                         all_touched=False, dtype="uint8").astype(bool)
