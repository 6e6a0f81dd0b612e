"""Terrain derivatives of a DEM (``gistools terrain``, ``gistools:terrain``): slope in degrees and in percent, aspect,
hillshade and Riley's terrain ruggedness index, as gdaldem computes them (Horn 1981's 3 x 3 gradient).

The DEM (a GeoTIFF, or a VRT mosaic of tiles such as the ``dem.vrt`` of ``gistools rasters``) is read window by window
with a one-cell halo (``gistools.io.blocks``), so a mosaic of tiles gives the same cells as one merged raster, and
memory stays bounded whatever the extent. A cell whose 3 x 3 window holds a nodata cell, or lies on the raster's
outer ring, is nodata, as gdaldem without ``-compute_edges``.

Units: the horizontal unit is the CRS's; the vertical unit the band's (``units`` / ``GISTOOLS_Z_UNIT``, as gistools
writes them), else a compound CRS's vertical unit, else the horizontal unit. Where they differ, the elevations are
scaled as gdaldem's ``-s`` (horizontal metres per unit / vertical metres per unit).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..errors import InputError
from ..io.blocks import BLOCK, check_outputs_are_not_inputs, open_raster, raster_crs, read_window, run_blockwise
from ..io.outdir import claim_output, output_folder
from ..io.raster import NODATA
from ..parameters import option
from ..parameters.terrain import TERRAIN_PRODUCTS
from ..terrain.derivatives import terrain_arrays
from ..progress import ProgressCallback
from ..units import LinearUnit, horizontal_unit, unit_from_word, vertical_unit

__all__ = ["terrain_from_dem", "terrain_arrays", "resolve_dem", "elevation_units", "TERRAIN_PRODUCTS"]

PRODUCT_UNITS = {"slope": "degree", "slope_percent": "percent", "aspect": "degree", "hillshade": "", "tri": None}


def resolve_dem(source, name: str = "dem") -> Path:
    """The raster of ``source``: a raster file as given, or a folder of gistools rasters' ``<name>.vrt``."""
    path = Path(source)
    if path.is_dir():
        vrt = path / f"{name}.vrt"
        if not vrt.exists():
            raise InputError(f"the folder has no {name}.vrt", path=path,
                             hint=f"Give a {name.upper()} raster, or a folder written by gistools rasters")
        return vrt
    if not path.exists():
        raise InputError("no such raster", path=path, hint="Give a GeoTIFF or VRT, or a folder written by gistools rasters")
    return path


def elevation_units(src, path, z_unit: str | None = "raster") -> tuple[LinearUnit, LinearUnit, str]:
    """(horizontal unit, vertical unit, where the vertical unit was read) of an open raster."""
    crs = raster_crs(src, path)
    xy = horizontal_unit(crs)
    if z_unit and z_unit != "raster":
        return xy, unit_from_word(z_unit, name="z unit"), "given"
    word = (src.units or (None,))[0] or src.tags().get("GISTOOLS_Z_UNIT")
    if word:
        return xy, unit_from_word(word, name=f"{path}: vertical unit"), "band"
    if crs.is_compound:
        return xy, vertical_unit(crs), "crs"
    return xy, xy, "horizontal"


def _check(products, azimuth, altitude, z_unit) -> tuple:
    products = tuple(products)
    bad = [p for p in products if p not in TERRAIN_PRODUCTS]
    if bad or not products:
        raise InputError(f"{option('terrain_products', products)}: {', '.join(bad) or 'none given'} not among "
                         f"{', '.join(TERRAIN_PRODUCTS)}", hint=f"e.g. {option('terrain_products', ('slope', 'hillshade'))}")
    if not 0 <= float(azimuth) <= 360:
        raise InputError(f"{option('azimuth', azimuth)} is not between 0 and 360 degrees", hint=f"e.g. {option('azimuth', 315)}")
    if not 0 <= float(altitude) <= 90:
        raise InputError(f"{option('altitude', altitude)} is not between 0 and 90 degrees", hint=f"e.g. {option('altitude', 45)}")
    if z_unit not in (None, "raster", "m", "ft", "ftUS"):
        raise InputError(f"{option('dem_z_unit', z_unit)} is not m, ft or ftUS", hint=f"e.g. {option('dem_z_unit', 'm')}")
    return products


@shared_sections
def terrain_from_dem(dem, out, *, products=tuple(TERRAIN_PRODUCTS), azimuth: float = 315.0, altitude: float = 45.0,
                     z_unit: str | None = "raster", overwrite: bool = False, block: int = BLOCK,
                     progress: ProgressCallback | None = None) -> dict:
    """Slope, aspect, hillshade and ruggedness of a DEM, as gdaldem: ``gistools terrain``.

    Writes ``out/<product>.tif`` (float32, nodata -9999) for each of ``products`` and ``out/report.json``. The DEM is
    read window by window, so a VRT mosaic of tiles gives the same cells as one merged raster. Cells on the raster's
    outer ring, and cells whose 3 x 3 window holds a nodata cell, are nodata (gdaldem without ``-compute_edges``).

    Parameters
    ----------
    dem : str or path
        A DEM raster (GeoTIFF or VRT mosaic), or a folder written by ``gistools rasters`` (its ``dem.vrt``).
    out : str or path
        Output folder, made when missing: ``slope.tif`` (degrees), ``slope_percent.tif`` (percent), ``aspect.tif``
        (degrees clockwise from north; flat cells nodata), ``hillshade.tif`` (1-255), ``tri.tif`` (Riley's terrain
        ruggedness index, in the DEM's vertical unit).
    products : sequence of str
        Which of ``"slope"``, ``"slope_percent"``, ``"aspect"``, ``"hillshade"``, ``"tri"`` to write (default: all).
    azimuth : float
        Direction the hillshade's light comes from, degrees clockwise from north, 0-360 (gdaldem's 315).
    altitude : float
        Height of the hillshade's light above the horizon, degrees, 0-90 (gdaldem's 45).
    z_unit : str
        The elevations' unit, ``"m"``, ``"ft"`` or ``"ftUS"``; or ``"raster"``: the band's unit, else the CRS's
        vertical unit, else the horizontal unit. Elevations in another unit than x and y are scaled (gdaldem ``-s``).
    {dem_run}

    Returns
    -------
    dict
        The report, also written to ``out/report.json``: ``outputs`` ({product: path}), ``kept``, ``settings``,
        ``units`` (``horizontal``, ``vertical``, ``vertical_from``: where the vertical unit was read, and
        ``scale``: the gdaldem ``-s`` applied), ``cells`` ([width, height]), ``seconds``, ``warnings`` (one when
        the DEM carries no vertical unit).

    Raises
    ------
    InputError
        An option is not valid, the DEM is not found (or the folder has no ``dem.vrt``), has no CRS, is rotated,
        or an output would overwrite it.
    DataFileError
        The DEM cannot be read.
    {raster_raise_rest}

    Examples
    --------
    >>> from gistools import rasters_from_tiles, terrain_from_dem
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> report = terrain_from_dem("rasters", "terrain", products=("slope", "hillshade"))  # doctest: +SKIP
    >>> report["outputs"]  # doctest: +SKIP
    {'slope': 'terrain/slope.tif', 'hillshade': 'terrain/hillshade.tif'}
    >>> report["units"]  # doctest: +SKIP
    {'horizontal': 'ftUS', 'vertical': 'ftUS', 'vertical_from': 'band', 'scale': 1.0}
    """
    products = _check(products, azimuth, altitude, z_unit)

    def compute(z, ewres, nsres, scale):
        return terrain_arrays(z, ewres, nsres, scale=scale, products=products, azimuth=azimuth, altitude=altitude)

    def outputs(zu):
        made = {}
        for p in products:
            unit = PRODUCT_UNITS[p] if PRODUCT_UNITS[p] is not None else zu.short
            made[p] = ("float32", NODATA, {"GISTOOLS_PRODUCT": p, **({"units": unit} if unit else {})})
        return made

    settings = {"products": list(products), "azimuth": azimuth, "altitude": altitude, "z_unit": z_unit}
    return dem_product(dem, out, "gistools terrain", settings, outputs, compute, z_unit=z_unit, overwrite=overwrite,
                       block=block, progress=progress, label="terrain",
                       method="Horn (1981) 3 x 3 gradient, as gdaldem; edge and nodata-adjacent cells nodata; "
                              "tri: Riley et al. (1999)")


def dem_product(dem, out, tool: str, settings: dict, outputs, compute, *, z_unit: str | None = "raster",
                overwrite: bool = False, block: int = BLOCK, progress: ProgressCallback | None = None,
                label: str = "terrain", method: str = "", extra: dict | None = None) -> dict:
    """The run of a product of a DEM's 3 x 3 windows (terrain, slope classes): the DEM resolved and checked
    (north-up, its units), read window by window with a one-cell halo, ``compute(z, ewres, nsres, scale)`` ->
    {name: array} on each window, written as ``out/<name>.tif``, kept on a rerun of the same settings, and the
    report (``tool``, ``settings``, ``method``, and ``extra``) written to ``out/report.json``. ``outputs(vertical unit)`` ->
    {name: (dtype, nodata, tags)}."""
    started = time.time()
    dem = resolve_dem(dem)
    out = output_folder(out)
    with open_raster(dem, "DEM") as src:
        xy, zu, source = elevation_units(src, dem, z_unit)
        made = outputs(zu)
        targets = {p: out / f"{p}.tif" for p in made}
        check_outputs_are_not_inputs(targets, [dem])
        t = src.transform
        if t.b != 0 or t.d != 0:
            raise InputError("the DEM is rotated", path=dem, hint="Warp it north-up first (gdalwarp)")
        if t.e > 0:  # rows from south to north: the blocks, the halo and the aspect all assume north-up
            raise InputError("the DEM is south-up (its rows run from south to north)", path=dem,
                             hint="Warp it north-up first (gdalwarp in.tif north_up.tif)")
        ewres, nsres = abs(t.a), abs(t.e)
        scale = xy.metres / zu.metres
        if abs(scale - 1.0) < 1e-12:
            scale = 1.0
        with claim_output(out, tool):
            def window(win):
                z = read_window(src, src, win, halo=1, fill=np.nan)
                if src.dtypes[0] != "float64":
                    z = z.astype(np.float32)
                return compute(z, ewres, nsres, scale)

            from ..engine.record import read_folder_report, write_folder_report
            from ..engine.resume import made_record, rerun_plan

            previous = read_folder_report(out)
            kept = rerun_plan(previous, tool, str(dem), settings, targets, overwrite)
            todo = {p: (None if p in kept else targets[p], *made[p]) for p in made}
            paths = {p: targets[p] for p in kept}
            if len(kept) < len(made):
                paths.update(run_blockwise(src, todo, window, progress=progress, label=label,
                                           overwrite=True, block=block))  # rerun_plan refused what it may not replace

            report = {"tool": tool, "input": str(dem),
                      "made": made_record(previous, tool, str(dem), settings, {k: paths[k] for k in made}),
                      "crs": raster_crs(src, dem).name, "outputs": {k: str(paths[k]) for k in made}, "kept": kept,
                      "settings": settings,
                      "units": {"horizontal": xy.short, "vertical": zu.short, "vertical_from": source, "scale": scale},
                      "method": method, **(extra or {}), "cells": [src.width, src.height],
                      "seconds": round(time.time() - started, 3)}
            if source == "horizontal":
                report["warnings"] = [f"the DEM carries no vertical unit: its elevations are taken in {xy.short}, the "
                                      f"horizontal unit (give the unit with {option('dem_z_unit', 'm')} otherwise)"]
            return write_folder_report(out, report)
