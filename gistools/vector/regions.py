"""Raster regions to polygons."""

from __future__ import annotations

import numpy as np
import shapely
from rasterio.features import shapes

__all__ = ["class_polygons"]


def _polygon(geom: dict) -> shapely.Polygon:
    rings = [shapely.linearrings(np.asarray(r, np.float64)) for r in geom["coordinates"]]
    return shapely.polygons(rings[0], holes=rings[1:] or None)


def class_polygons(codes: np.ndarray, transform, mask: np.ndarray | None = None) -> dict[int, shapely.MultiPolygon]:
    """One MultiPolygon per code of an integer raster (cells under ``mask`` only), in the raster's CRS.

    ``rasterio.features.shapes`` gives the maximal 4-connected regions of each code, so two regions of one
    code meet at most at a corner: their MultiPolygon is already the dissolved, valid geometry (no union).
    """
    found: dict[int, list] = {}
    for geom, value in shapes(codes, mask=mask, transform=transform):
        found.setdefault(int(value), []).append(_polygon(geom))
    return {code: shapely.multipolygons(parts) for code, parts in sorted(found.items())}
