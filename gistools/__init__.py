"""gistools: open tools for LiDAR shrub mapping, aquifer models, runway earthworks and structure meshes.

The library is a set of small functions over numpy arrays (``gistools.lidar``,
``gistools.grid``), I/O at the edges (``gistools.io``) and one task per product
(``gistools.tasks``) that the CLI and the QGIS plugin both call.
"""

from ._version import __version__  # noqa: F401

from .errors import *  # noqa: F401,F403
from .grid import Grid, cell_centres, cell_index, snapped_grid  # noqa: F401
from .lidar import dem_from_ground_points, dsm_from_points, ndsm_from, tin_to_grid  # noqa: F401
from .tasks import RasterSettings, rasters_from_tiles  # noqa: F401
