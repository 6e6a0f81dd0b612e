"""The offline web map of gistools fuels (``OUT/fuels_map.html``): the canopy base height of the cells with canopy
as polygons in three classes, one HTML file with Leaflet inlined (as ``gistools webmap``'s shrub map), no request to
any network address.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .._version import __version__
from .layers import CBH_CLASSES, cbh_class, cbh_features  # noqa: F401 (cbh_class: still importable from here)
from .webmap import GENERATOR, _leaflet, _write_page

__all__ = ["fuels_web_map", "cbh_features", "CBH_CLASSES"]

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
