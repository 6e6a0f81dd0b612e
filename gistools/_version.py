"""The version of gistools: written here only (pyproject.toml and the QGIS plugin read it from here)."""

__version__ = "0.1.0"
