"""Terrain derivatives of a DEM's cells as gdaldem computes them (Horn 1981's 3 x 3 gradient): slope in degrees and
in percent, aspect, hillshade and Riley's terrain ruggedness index; arrays in, arrays out (``gistools terrain`` reads
and writes them window by window: gistools.products.terrain)."""

from __future__ import annotations

import math

import numpy as np

from ..parameters.terrain import TERRAIN_PRODUCTS

__all__ = ["terrain_arrays"]


def _horn_sums(z):
    """gdaldem's four weighted sums of a 3 x 3 window (cells a b c / d e f / g h i), in the DEM's own precision and
    order of addition: left a+2d+g, right c+2f+i, top a+2b+c, bottom g+2h+i, for every inner cell of ``z``."""
    a, b, c = z[:-2, :-2], z[:-2, 1:-1], z[:-2, 2:]
    d, f = z[1:-1, :-2], z[1:-1, 2:]
    g, h, i = z[2:, :-2], z[2:, 1:-1], z[2:, 2:]
    return ((a + d) + d) + g, ((c + f) + f) + i, ((a + b) + b) + c, ((g + h) + h) + i


def terrain_arrays(z: np.ndarray, ewres: float, nsres: float, *, scale: float = 1.0, products=tuple(TERRAIN_PRODUCTS),
                   azimuth: float = 315.0, altitude: float = 45.0) -> dict:
    """The terrain derivatives of the inner cells of ``z`` (a window with a one-cell halo; NaN = nodata).

    ``ewres``, ``nsres``: the cell's width and height (positive, horizontal units); ``scale``: horizontal metres per
    unit / vertical metres per unit (gdaldem ``-s``). Returns {product: float array of shape z.shape - 2}, NaN where
    the 3 x 3 window has a nodata cell or (aspect) the cell is flat. Slope and aspect in degrees (aspect clockwise
    from north), slope_percent in percent, hillshade 1-255 (gdaldem's), tri in z's unit (Riley et al. 1999: the
    square root of the sum of the squared differences to the 8 neighbours).
    """
    z = np.asarray(z)
    if z.dtype != np.float64:
        z = z.astype(np.float32, copy=False)  # gdaldem sums a float raster's window in single precision
    ft = z.dtype.type
    left, right, top, bottom = _horn_sums(z)
    we = np.subtract(left, right, out=left)  # west minus east (a NaN anywhere in the window stays NaN)
    sn = np.subtract(bottom, top, out=bottom)  # south minus north
    del right, top
    centre_nodata = np.isnan(z[1:-1, 1:-1])  # the one cell of the window the sums leave out
    out = {}
    wanted = set(products)
    if wanted & {"slope", "slope_percent", "hillshade"}:
        gx = we * ft(1.0 / (8.0 * ewres * scale))
        gy = sn * ft(1.0 / (8.0 * nsres * scale))
        rise2 = gx * gx
        rise2 += gy * gy
        if wanted & {"slope", "slope_percent"}:
            rise = np.sqrt(rise2)
            if "slope_percent" in wanted:
                out["slope_percent"] = rise * ft(100.0)
            if "slope" in wanted:
                out["slope"] = np.degrees(np.arctan(rise, out=rise), out=rise)
        if "hillshade" in wanted:
            # gdaldem: x = (west - east) / (8 ewres), y = (south - north) / (8 x the geotransform's negative nsres)
            az, alt = math.radians(azimuth), math.radians(altitude)
            cang = gx * ft(math.sin(az) * math.cos(alt))
            cang += gy * ft(math.cos(az) * math.cos(alt))
            cang += ft(math.sin(alt))
            rise2 += ft(1.0)
            cang /= np.sqrt(rise2, out=rise2)
            cang *= ft(254.0)
            cang += ft(1.0)
            cang[cang <= 1.0] = 1.0
            out["hillshade"] = cang
    if "aspect" in wanted:
        deg = np.degrees(np.arctan2(sn, we))  # atan2(dy, -dx), dx = east minus west
        aspect = np.where(deg > 90.0, ft(450.0) - deg, ft(90.0) - deg)
        aspect[aspect == 360.0] = 0.0
        aspect[(we == 0) & (sn == 0)] = np.nan  # flat: gdaldem's nodata
        out["aspect"] = aspect
    if "tri" in wanted:
        e = z[1:-1, 1:-1]
        h, w = e.shape
        acc = np.zeros(e.shape, z.dtype)
        for r in range(3):
            for c in range(3):
                if r != 1 or c != 1:
                    diff = z[r:r + h, c:c + w] - e
                    diff *= diff
                    acc += diff
        out["tri"] = np.sqrt(acc, out=acc)
    if centre_nodata.any():
        for k in out:
            out[k][centre_nodata] = np.nan
    return out
