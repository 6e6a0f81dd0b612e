"""The FlamMap landscape of gistools fuels: the eight LANDFIRE bands (elevation, slope, aspect, fuel model, canopy
cover, canopy height, canopy base height, canopy bulk density) from the fuel layers' mosaics, as a multiband int16
GeoTIFF (landscape.tif) and FlamMap's landscape file (landscape.lcp, GDAL's LCP driver).

Encodings are LANDFIRE's and metric whatever the data's unit: elevation m, slope degrees, aspect degrees clockwise
from north (-1 flat), fuel model the Scott and Burgan 40 code, cover percent, canopy height and base height m x 10,
bulk density kg/m3 x 100. Cells without data are -9999 in every band.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pyproj
import rasterio
import rasterio.shutil
import rasterio.windows

from ..errors import InputError
from ..io.atomic import atomic_path
from ..io.raster import crs_from_wkt
from ..lidar.fuels import fuel_model_codes, horn_slope_aspect
from ..parameters import option

__all__ = ["write_landscape", "landscape_arrays", "sample_fuel_raster", "centre_latitude", "LANDSCAPE_BANDS",
           "LCP_OPTIONS", "INT16_RANGE"]

NODATA16 = -9999
INT16_RANGE = (-32768, 32767)  # every band of an LCP is int16
# LANDFIRE / FlamMap order: name, encoding (what one unit of the int16 is), GDAL's LCP creation option
LANDSCAPE_BANDS = (("elevation", "m"), ("slope", "degrees"), ("aspect", "degrees clockwise from north, -1 flat"),
                   ("fuel_model", "Scott and Burgan 40 code"), ("canopy_cover", "percent"),
                   ("canopy_height", "m x 10"), ("canopy_base_height", "m x 10"),
                   ("canopy_bulk_density", "kg/m3 x 100"))
LCP_OPTIONS = {"ELEVATION_UNIT": "METERS", "SLOPE_UNIT": "DEGREES", "ASPECT_UNIT": "AZIMUTH_DEGREES",
               "FUEL_MODEL_OPTION": "NO_CUSTOM_AND_NO_FILE", "CANOPY_COV_UNIT": "PERCENT",
               "CANOPY_HT_UNIT": "METERS_X_10",
               "CBH_UNIT": "METERS_X_10", "CBD_UNIT": "KG_PER_CUBIC_METER_X_100",
               # the header's lists of each band's values: GDAL's driver writes past its buffer when a band has many
               # (a crash on a 30 m landscape of one forest plot); FlamMap reads the bands without them
               "CLASSIFY_DATA": "NO"}


def _read(path) -> tuple[np.ndarray, object, object]:
    with rasterio.open(path) as src:
        return src.read(1, masked=True).filled(np.nan).astype(np.float64), src.transform, src.crs


def sample_fuel_raster(path, transform, shape, crs_wkt) -> np.ndarray:
    """The raster's band 1 at the centres of the grid's cells (nearest cell; reprojected from the grid's CRS to the
    raster's), NaN outside it or at its nodata."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    x, y = rasterio.transform.xy(transform, rows.ravel(), cols.ravel(), offset="center")
    x, y = np.asarray(x, float), np.asarray(y, float)
    try:
        src = rasterio.open(path)
    except rasterio.errors.RasterioError as err:
        raise InputError(f"cannot read the fuel-model raster {path} ({err})",
                         hint="Give a GeoTIFF of fuel-model codes") from None
    with src:
        if src.crs is None:
            raise InputError(f"the fuel-model raster {path} has no CRS", hint="Give it a CRS (gdal_edit.py -a_srs)")
        if not crs_from_wkt(crs_wkt).equals(pyproj.CRS.from_wkt(src.crs.to_wkt())):
            x, y = pyproj.Transformer.from_crs(crs_from_wkt(crs_wkt), pyproj.CRS.from_wkt(src.crs.to_wkt()),
                                               always_xy=True).transform(x, y)
        r, c = rasterio.transform.rowcol(src.transform, x, y)
        r, c = np.asarray(r), np.asarray(c)
        ok = (r >= 0) & (r < src.height) & (c >= 0) & (c < src.width)
        out = np.full(len(x), np.nan)
        if ok.any():  # only the window under the cells (a national fuel-model raster is read in part)
            r0, c0 = int(r[ok].min()), int(c[ok].min())
            window = rasterio.windows.Window(c0, r0, int(c[ok].max()) - c0 + 1, int(r[ok].max()) - r0 + 1)
            band = src.read(1, window=window)
            out[ok] = band[r[ok] - r0, c[ok] - c0]
        if src.nodata is not None:
            out[out == src.nodata] = np.nan
    return out.reshape(shape)


def landscape_arrays(layers: dict, *, cell: float, z_metres: float, xy_metres: float, fuel=None,
                     class_breaks=(0.3, 0.7), fuel_codes=(121, 142, 145), transform=None) -> np.ndarray:
    """(8, rows, cols) int16 in LANDFIRE's order and encodings from the fuel layers (float arrays in the data's
    units: elevation, cover, height, cbh, cbd, shrub_share). ``fuel``: fuel-model codes per cell, or None for the
    shrub-class mapping of :func:`lidar.fuels.fuel_model_codes`. InputError when no cell has data, or a value
    does not fit the int16 of the LCP format (named with its cell's centre where ``transform`` is given)."""
    elev = layers["elevation"]
    slope, aspect = horn_slope_aspect(elev, cell, z_per_xy=z_metres / xy_metres)
    if fuel is None:
        fuel = fuel_model_codes(layers["shrub_share"], class_breaks, fuel_codes)
    scale = {"height": 10.0 * z_metres, "cbh": 10.0 * z_metres, "cbd": 100.0}
    bands = [elev * z_metres, slope, aspect, np.asarray(fuel, np.float64), layers["cover"]]
    bands += [layers[k] * scale[k] for k in ("height", "cbh", "cbd")]
    stack = np.stack(bands)
    valid = np.isfinite(elev) & np.isfinite(layers["cover"])
    if not valid.any():
        raise InputError("no cell of the landscape has both a ground elevation and a canopy cover (every band "
                         "would be nodata)", hint="Check the tiles' ground class and return numbers (gistools info)")
    stack = np.where(valid & np.isfinite(stack) & (stack != -9999.0), np.rint(stack), NODATA16)
    _check_int16(stack, transform)
    return stack.astype(np.int16)


def _check_int16(stack: np.ndarray, transform) -> None:
    """InputError naming the first band (LANDFIRE's order) with a value beyond int16, its extreme and where."""
    lo, hi = INT16_RANGE
    for i, (name, unit) in enumerate(LANDSCAPE_BANDS):
        band = stack[i]
        out = (band < lo) | (band > hi)
        if not out.any():
            continue
        worst = np.unravel_index(np.argmax(np.where(out, np.abs(band), -1.0)), band.shape)
        where = ""
        if transform is not None:
            x, y = rasterio.transform.xy(transform, worst[0], worst[1])
            where = f" (the cell at x {x:.10g}, y {y:.10g})"
        raise InputError(f"the landscape's {name} reaches {band[worst]:,.0f} {unit}{where} in "
                         f"{int(np.count_nonzero(out)):,} cells, beyond the {lo:,} to {hi:,} that the LCP format "
                         "stores (int16): the landscape is not written",
                         hint=("Check the fuel-model raster's codes and nodata" if name == "fuel_model" else
                               "Check the tiles' z values and vertical unit (gistools info)")
                         + "; the fuel layers' rasters are written")


def centre_latitude(transform, shape, crs_wkt: str) -> float:
    """The latitude (degrees) of the centre of a grid (``shape`` rows, cols); NaN where it is not on the Earth."""
    x, y = rasterio.transform.xy(transform, shape[0] / 2, shape[1] / 2)
    try:
        _lon, lat = pyproj.Transformer.from_crs(pyproj.CRS.from_wkt(crs_wkt), "EPSG:4326",
                                                always_xy=True).transform(x, y)
    except pyproj.exceptions.ProjError:
        return math.nan
    return float(lat) if math.isfinite(lat) and abs(lat) <= 90 else math.nan


def _latitude(transform, shape, crs) -> int:
    lat = centre_latitude(transform, shape, crs.to_wkt())
    if not math.isfinite(lat):
        raise InputError("the landscape's centre is off the Earth in its CRS (no latitude for the .lcp header)",
                         hint=f"Give a smaller {option('cell_size')}, or {option('latitude')}")
    return int(round(lat))


def write_landscape(out: Path, mosaics: dict, run, settings) -> dict:
    """landscape.tif and landscape.lcp (with landscape.prj) in ``out`` from the mosaics; returns their paths and the
    bands' names and encodings."""
    layers, transform, crs = {}, None, None
    for name in ("elevation", "cover", "height", "cbh", "cbd", "shrub_share"):
        layers[name], transform, crs = _read(mosaics[name])
    shape = layers["elevation"].shape
    fuel = None
    if settings.fuel_raster:
        fuel = sample_fuel_raster(settings.fuel_raster, transform, shape, run.crs_wkt)
    try:
        stack = landscape_arrays(layers, cell=run.cell_size, z_metres=run.z_metres, xy_metres=run.xy_metres,
                                 fuel=fuel, class_breaks=tuple(settings.class_breaks),
                                 fuel_codes=tuple(settings.fuel_codes), transform=transform)
    except InputError as err:
        raise InputError(str(err), path=out / "landscape.lcp") from None
    profile = dict(driver="GTiff", width=shape[1], height=shape[0], count=8, dtype="int16", crs=crs,
                   transform=transform, nodata=NODATA16, compress="deflate", interleave="band")
    tif = out / "landscape.tif"
    with atomic_path(tif, overwrite=True) as tmp:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(stack)
            for i, (name, unit) in enumerate(LANDSCAPE_BANDS, 1):
                dst.set_band_description(i, name)
            dst.units = tuple(unit for _n, unit in LANDSCAPE_BANDS)
            dst.update_tags(GISTOOLS_PRODUCT="fuels_landscape", FUEL_MODELS="user raster" if fuel is not None else
                            "shrub classes -> " + ",".join(f"{c:g}" for c in settings.fuel_codes))
    latitude = int(round(settings.latitude)) if settings.latitude is not None else _latitude(transform, shape, crs)
    # GDAL takes only a metre or an international foot from the CRS: the unit is set here (a US survey foot is a
    # foot to 2 parts per million; landscape.prj keeps the exact CRS)
    linear = "METER" if abs(run.xy_metres - 1.0) < 1e-9 else "FOOT"
    options = {**LCP_OPTIONS, "LATITUDE": str(latitude), "LINEAR_UNIT": linear,
               "DESCRIPTION": "gistools fuels"}
    lcp = out / "landscape.lcp"
    with atomic_path(lcp, overwrite=True, keep_suffix=True) as tmp:
        with rasterio.Env(GDAL_PAM_ENABLED="NO"):  # no .aux.xml beside landscape.tif
            rasterio.shutil.copy(tif, tmp, driver="LCP", **options)
        for side in (tmp.with_suffix(".prj"), Path(str(tmp) + ".aux.xml")):
            if side.exists():
                os.remove(side)
    with atomic_path(out / "landscape.prj", overwrite=True) as tmp:
        tmp.write_text(pyproj.CRS.from_wkt(crs.to_wkt()).to_wkt("WKT1_ESRI"), encoding="utf-8")
    return {"tif": str(tif), "lcp": str(lcp), "latitude": latitude,
            "bands": [{"name": n, "encoding": u} for n, u in LANDSCAPE_BANDS]}
