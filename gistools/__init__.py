"""gistools: open tools for LiDAR shrub mapping, aquifer models, runway earthworks and structure meshes.

The library is small functions over numpy arrays (``gistools.lidar``, ``gistools.grid``, and the pure packages
``aquifer``, ``runway``, ``structure``, ``vector``), I/O at the edges (``gistools.io``), one read -> compute ->
write function per product (``gistools.products``), the field deliverables (``gistools.deliver``), all run tile by
tile by one engine (``gistools.engine``). The CLI and the QGIS plugin call the same functions, exported here::

    >>> import gistools
    >>> callable(gistools.rasters_from_tiles) and callable(gistools.shrub_from_tiles)
    True

The functions and settings are imported when first used (``import gistools`` stays quick).
"""

import importlib
import warnings

from ._version import __version__  # noqa: F401

# pyproj warns at import when it finds no PROJ data; gistools looks further and, where there is none, says so in
# one line before any input is read (gistools.projdata.ensure_proj_data)
warnings.filterwarnings("ignore", message="Valid PROJ data directory not found", category=UserWarning)

from .errors import *  # noqa: F401,F403
from .errors import __all__ as _errors
# name -> the module that defines it (imported on first use: ``gistools --help`` imports no numpy)
_PRODUCTS = {
    "grid": ("Grid", "cell_centres", "cell_index", "snapped_grid"),
    "lidar": ("dem_from_ground_points", "dsm_from_points", "ndsm_from", "tin_to_grid"),
    "products.rasters": ("RasterSettings", "rasters_from_tiles"),
    "products.ground": ("GroundSettings", "ground_from_tiles"),
    "products.normalize": ("NormalizeSettings", "normalize_from_tiles"),
    "products.metrics": ("MetricsSettings", "metrics_from_tiles"),
    "products.chm": ("ChmSettings", "chm_from_tiles"),
    "products.fuels": ("FuelsSettings", "fuels_from_tiles"),
    "products.points": ("points_from_tiles",),
    "products.info": ("tile_summary", "tiles_summary"),
    "products.shrub": ("ShrubSettings", "shrub_from_tiles", "map_from_classes"),
    "products.steps": ("ndsm_from_rasters", "bands_from_ndsm", "breakline_polygons", "clip_bands",
                       "density_from_vegetation", "classes_from_cover"),
    "products.aquifer": ("AquiferSettings", "aquifer_model", "aquifer_query"),
    "products.runway": ("RunwaySettings", "runway_earthworks"),
    "products.structure": ("structure_model", "reconstruct"),
    "products.terrain": ("terrain_from_dem",),
    "products.viewshed": ("viewshed_from_surface",),
    "products.travel": ("TravelSettings", "travel_from_dem", "travel_minutes"),
    "deliver.webmap": ("web_map",),
    "deliver.scene": ("scene_glb",),
    "deliver.mapbook": ("map_book",),
    "datasets.examples": ("write_examples",),
}
_LAZY = {name: module for module, names in _PRODUCTS.items() for name in names}


def _declared_functions() -> dict:
    """{function: module} of the commands declared whole (their library function is exported from here too)."""
    from .parameters import DECLARED, LIBRARY

    return {LIBRARY[c][0].split(":")[1]: LIBRARY[c][0].split(":")[0] for c in DECLARED}


_LAZY.update(_declared_functions())

__all__ = ["__version__", *_errors, *_LAZY]


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'gistools' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
