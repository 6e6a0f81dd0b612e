"""The plugin object QGIS loads: registers the gistools Processing provider, or explains what is missing."""

from __future__ import annotations

import importlib

from qgis.core import Qgis, QgsApplication, QgsMessageLog

# what the provider needs in QGIS's Python: (module, what to install)
REQUIREMENTS = (
    ("numpy", "numpy"),
    ("scipy", "scipy"),
    ("rasterio", "rasterio"),
    ("laspy", "laspy"),
    ("lazrs", "lazrs"),
    ("pyproj", "pyproj"),
    ("shapely", "shapely>=2"),
    ("geopandas", "geopandas"),
    ("pyogrio", "pyogrio"),
    ("triangle", "triangle"),
)


def missing_requirements() -> list[str]:
    """The pip names of the packages QGIS's Python cannot import (empty when all are there).

    gistools itself is named only when its dependencies are all there (else it fails because of them).
    """
    missing = []
    for module, pip_name in REQUIREMENTS + (("gistools", "gistools"),):
        if module == "gistools" and missing:
            break
        try:
            importlib.import_module(module)
        except Exception:  # ImportError, or a broken binary wheel raising something else
            missing.append(pip_name)
    try:
        import shapely

        if int(shapely.__version__.split(".")[0]) < 2:
            missing.append("shapely>=2")
    except Exception:
        pass
    return sorted(set(missing))


def missing_message(missing: list[str]) -> str:
    return ("gistools: the Processing algorithms are not available because QGIS's Python cannot import "
            + ", ".join(missing) + ". Install them into the Python QGIS runs: on Debian/Ubuntu "
            "`/usr/bin/python3 -m pip install " + " ".join(f"'{m}'" for m in missing) + "` (or a venv made with "
            "--system-site-packages on QGIS's PYTHONPATH); on Windows the OSGeo4W Shell, on macOS the QGIS bundle's "
            "python3: `python3 -m pip install " + " ".join(f"'{m}'" for m in missing) + "`. Then restart QGIS. "
            "The gistools README, section QGIS, has the details.")


class GistoolsPlugin:
    def __init__(self, iface=None):
        self.iface = iface
        self.provider = None
        self.missing: list[str] = []

    def initProcessing(self):  # noqa: N802 (QGIS's name)
        self.missing = missing_requirements()
        if self.missing:
            QgsMessageLog.logMessage(missing_message(self.missing), "gistools", Qgis.Critical)
            return
        from .provider import GistoolsProvider

        self.provider = GistoolsProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        self.initProcessing()
        if self.missing and self.iface is not None:
            self.iface.messageBar().pushMessage("gistools", missing_message(self.missing), level=Qgis.Critical, duration=0)

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
