"""Slope classes of a DEM: ``gistools slope-classes`` (the slope of gdaldem, Horn's method, in degrees, cut at
given limits). The command line, the QGIS algorithm and the reference page are made from its declaration
(gistools.parameters.terrain, ``command("slope-classes", ...)``)."""

from __future__ import annotations

import numpy as np

from ..docstrings import shared_sections
from ..io.blocks import BLOCK
from ..parameters import check, option
from ..progress import ProgressCallback
from .terrain import dem_product, terrain_arrays

NODATA_CLASS = 0
MAX_LIMITS = 254  # classes 1-255 in a byte; 0 is nodata
# a colour a class, from flat to steep (ColorBrewer's YlOrRd, then a dark red for more classes)
COLOURS = ("#ffffb2", "#fed976", "#feb24c", "#fd8d3c", "#f03b20", "#bd0026", "#800026")


def slope_class_array(slope: np.ndarray, breaks) -> np.ndarray:
    """Classes (uint8) of slopes in degrees: 1 below ``breaks[0]``, k where ``breaks[k-2] <= slope < breaks[k-1]``,
    ``len(breaks) + 1`` at or above the last limit; 0 (nodata) where the slope is NaN."""
    slope = np.asarray(slope, np.float64)
    classes = np.searchsorted(np.asarray(breaks, np.float64), slope, side="right") + 1
    return np.where(np.isnan(slope), NODATA_CLASS, classes).astype(np.uint8)


def class_names(breaks) -> dict:
    """{class: (its name, its colour)}: "0-5 deg", "5-15 deg", ..., ">= 30 deg"."""
    limits = [0.0, *breaks]
    names = {k + 1: f"{limits[k]:g}-{limits[k + 1]:g} deg" for k in range(len(breaks))}
    names[len(breaks) + 1] = f">= {limits[-1]:g} deg"
    return {k: (name, COLOURS[min(k - 1, len(COLOURS) - 1)]) for k, name in names.items()}


def _limits(breaks) -> tuple[float, ...]:
    """The slope limits checked: 1 to 254 increasing numbers within 0-90 (the classes fit a byte beside nodata 0)."""
    from ..errors import InputError
    from ..validation import check_breaks

    try:
        count = len(tuple(breaks))
    except TypeError:
        count = 1
    if not 1 <= count <= MAX_LIMITS:
        raise InputError(f"{option('slope_breaks')} needs 1 to {MAX_LIMITS} limits, got {count}",
                         hint=f"Give e.g. {option('slope_breaks', '5,15,30')}")
    return check_breaks(breaks, "slope_breaks", count=count, low=0.0, high=90.0, example="5,15,30")


@shared_sections
def slope_classes_from_dem(dem, out, *, breaks=(5.0, 15.0, 30.0), z_unit: str | None = "raster",
                           overwrite: bool = False, block: int = BLOCK,
                           progress: ProgressCallback | None = None) -> dict:
    """Slope classes of a DEM: ``gistools slope-classes``.

    Writes ``out/slope_classes.tif`` (uint8: 1 for slopes below the first limit, up to ``len(breaks) + 1`` at or
    above the last; 0 nodata, with a colour table and the classes' names) and ``out/report.json``. The slope is
    gdaldem's (Horn's 3 x 3 gradient, degrees; cells on the raster's edge or beside nodata are nodata), read window
    by window, so a VRT mosaic of tiles gives the cells of one merged raster.

    Parameters
    ----------
    dem : str or path
        A DEM raster (GeoTIFF or VRT mosaic), or a folder written by ``gistools rasters`` (its ``dem.vrt``).
    out : str or path
        Output folder, made when missing.
    breaks : sequence of float
        Slope limits between the classes, degrees, increasing, within 0-90.
    z_unit : str
        The elevations' unit, ``"m"``, ``"ft"`` or ``"ftUS"``; or ``"raster"``: the band's unit, else the CRS's
        vertical unit, else the horizontal unit (gdaldem ``-s``).
    {dem_run}

    Returns
    -------
    dict
        The report, also written to ``out/report.json``: ``outputs`` ({"slope_classes": path}), ``classes``
        ({class: name}), ``kept``, ``settings``, ``units``, ``cells``, ``seconds``.

    Raises
    ------
    InputError
        A limit is not valid, the DEM is not found, has no CRS, is rotated or south-up.
    {raster_raise_rest}

    Examples
    --------
    >>> from gistools import rasters_from_tiles, slope_classes_from_dem
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> report = slope_classes_from_dem("rasters", "slopes", breaks=(5, 15, 30))  # doctest: +SKIP
    >>> report["classes"]  # doctest: +SKIP
    {'1': '0-5 deg', '2': '5-15 deg', '3': '15-30 deg', '4': '>= 30 deg'}
    """
    breaks = _limits(breaks)
    z_unit = check("dem_z_unit", z_unit) or "raster"
    categories = class_names(breaks)

    def compute(z, ewres, nsres, scale):
        slope = terrain_arrays(z, ewres, nsres, scale=scale, products=("slope",))["slope"]
        return {"slope_classes": slope_class_array(slope, breaks)}

    def outputs(_zu):
        return {"slope_classes": ("uint8", NODATA_CLASS, {"GISTOOLS_PRODUCT": "slope_classes",
                                                          "categories": categories})}

    settings = {"breaks": list(breaks), "z_unit": z_unit}
    report = dem_product(dem, out, "gistools slope-classes", settings, outputs, compute, z_unit=z_unit,
                         overwrite=overwrite, block=block, progress=progress, label="slope classes",
                         method="gdaldem's slope (Horn 1981, degrees), cut at the limits; edge and "
                                "nodata-adjacent cells nodata",
                         extra={"classes": {str(k): name for k, (name, _colour) in categories.items()}})
    return report
