"""The offline web map of gistools fuels (``OUT/fuels_map.html``): the canopy base height of the cells with canopy
as polygons in three classes, one HTML file with Leaflet inlined (as ``gistools webmap``'s shrub map), no request to
any network address.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .._version import __version__
from .webmap import GENERATOR, _leaflet, _rounded, _write_page

__all__ = ["fuels_web_map", "cbh_features", "CBH_CLASSES"]

# canopy base height classes (metres): code -> (name, colour, upper limit)
CBH_CLASSES = {1: ("canopy base below 4 m (crown fire starts easily)", "#d7301f", 4.0),
               2: ("canopy base 4-8 m", "#fdae61", 8.0),
               3: ("canopy base above 8 m", "#1a9641", np.inf)}


def cbh_class(cbh_m: np.ndarray) -> np.ndarray:
    """0 (no canopy fuel layer: CBH 0 or no data), 1, 2, 3 by :data:`CBH_CLASSES` of CBH in metres."""
    cbh = np.nan_to_num(np.asarray(cbh_m, np.float64), nan=0.0)
    return np.where(cbh > 0, 1 + (cbh >= 4.0) + (cbh >= 8.0), 0).astype(np.uint8)


def cbh_features(cbh_vrt, *, z_metres: float, xy_metres: float) -> list[dict]:
    """GeoJSON features (WGS84) of the canopy base height classes of a CBH mosaic (in the data's vertical unit);
    ``area`` in square metres."""
    import rasterio
    import rasterio.features
    import shapely
    from pyproj import Transformer

    with rasterio.open(cbh_vrt) as src:
        cls = cbh_class(src.read(1, masked=True).filled(np.nan) * z_metres)
        transform, crs = src.transform, src.crs
    to_wgs = Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True)
    features = []
    for geom, code in rasterio.features.shapes(cls, mask=cls > 0, transform=transform, connectivity=4):
        shape = shapely.geometry.shape(geom)
        area_m2 = shape.area * xy_metres ** 2
        wgs = shapely.transform(shape, lambda c: np.column_stack(to_wgs.transform(c[:, 0], c[:, 1]))).__geo_interface__
        name = CBH_CLASSES[int(code)][0]
        features.append({"type": "Feature", "geometry": {"type": wgs["type"], "coordinates": _rounded(wgs["coordinates"])},
                         "properties": {"tile": "all", "class_code": int(code), "class": name, "area": area_m2,
                                        "area_acres": area_m2 / 4046.8564224, "area_ha": area_m2 / 1e4}})
    return features


def fuels_web_map(out: Path, cbh_vrt, *, z_metres: float, xy_metres: float, parameters: dict) -> dict:
    """Write ``out/fuels_map.html`` from the CBH mosaic (in the data's vertical unit); returns {"html", "features"}."""
    from ..web.page import web_map_html

    features = cbh_features(cbh_vrt, z_metres=z_metres, xy_metres=xy_metres)
    js, css = _leaflet()
    classes = [{"code": c, "name": n, "colour": colour} for c, (n, colour, _top) in CBH_CLASSES.items()]
    params = {**parameters, "polygons": len(features), "made by": f"gistools {__version__}, {time.strftime('%Y-%m-%d')}"}
    page = web_map_html(title=f"Canopy base height - {Path(out).name}", geojson={"type": "FeatureCollection",
                        "features": features}, classes=classes, parameters=params, leaflet_js=js, leaflet_css=css,
                        legend_title="Canopy base height")
    text = page.replace("<head>\n", "<head>\n" + GENERATOR + "\n", 1)
    target = Path(out) / "fuels_map.html"
    _write_page(target, text)
    return {"html": str(target), "features": len(features)}
