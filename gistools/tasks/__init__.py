"""One read -> compute -> write function per product; the CLI and QGIS call only these."""

from .rasters import RasterSettings, rasters_from_tiles

__all__ = ["RasterSettings", "rasters_from_tiles"]
