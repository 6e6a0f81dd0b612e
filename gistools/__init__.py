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
# name -> the module that defines it (imported on first use: ``gistools --help`` imports no numpy): the functions
# on arrays and the steps; every command's library function and settings class come from its declaration
# (gistools.parameters, ``command(..., library=, settings=)``)
_FUNCTIONS = {
    "grid": ("Grid", "cell_centres", "cell_index", "snapped_grid"),
    "lidar": ("dem_from_ground_points", "dsm_from_points", "ndsm_from", "tin_to_grid"),
    "products.info": ("tile_summary",),
    "products.steps": ("ndsm_from_rasters", "bands_from_ndsm", "breakline_polygons", "clip_bands",
                       "density_from_vegetation", "classes_from_cover"),
    "products.structure": ("reconstruct",),
    "terrain.travel": ("travel_minutes",),
    "products.fetch": ("Area", "fetch_area"),
    "datasets.examples": ("write_examples",),
}


def _library_exports() -> dict:
    """{name: module} of every declared command's library function and settings class."""
    from .parameters import LIBRARY

    found = {}
    for function, settings, _command_line in LIBRARY.values():
        for path in filter(None, (function, settings)):
            module, name = path.split(":")
            found[name] = module
    return found


_LAZY = {name: module for module, names in _FUNCTIONS.items() for name in names}
_LAZY.update(_library_exports())

__all__ = ["__version__", *_errors, *_LAZY]


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'gistools' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    if callable(value):  # a misnamed argument is refused naming the real ones (gistools.arguments)
        from .arguments import checked

        value = checked(value, _settings_of(name), exported_as=(__name__, name))
    return globals().setdefault(name, value)  # one object a name, also when two threads ask at once


def _settings_of(function: str):
    """The settings class of the command whose library function is ``function``, or None."""
    from .parameters import LIBRARY

    for path, settings, _cli in LIBRARY.values():
        if path.split(":")[1] == function and settings:
            module, cls = settings.split(":")
            return getattr(importlib.import_module(f".{module}", __name__), cls)
    return None


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
