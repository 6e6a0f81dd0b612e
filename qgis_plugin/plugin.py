"""The plugin object QGIS loads: registers the gistools Processing provider, or explains what is missing."""

from __future__ import annotations

from qgis.core import QgsApplication, QgsMessageLog

from .compat import CRITICAL

# what QGIS's Python has and lacks is install.py's (it installs what is missing); this module imports from it, never
# the reverse (no import cycle). The checks stay reachable here by their names for callers of gistools_qgis.plugin.
from .install import (  # noqa: F401
    BOUND,
    add_to_path,
    bundled_before_import,
    bundled_libraries,
    default_target,
    library_mismatches,
    mismatch_message,
    missing_requirements,
)


def missing_message(missing: list[str]) -> str:
    pure = [m for m in missing if m.split(">")[0] not in set(BOUND) | {"numpy", "scipy", "geopandas", "gistools"}]
    bound = [m for m in missing if m.split(">")[0] in BOUND]
    text = ("gistools: the Processing algorithms are not available because QGIS's Python cannot import "
            + ", ".join(missing) + ". On Debian / Ubuntu, follow the route of the documentation's QGIS page (docs/qgis.md): "
            "it builds rasterio, pyogrio, pyproj and shapely against the GDAL / PROJ / GEOS QGIS links (binary wheels "
            "carry their own copies, which crash QGIS) with `pip install --user --break-system-packages` "
            "(Debian's system pip is externally managed)")
    if pure:
        text += "; the pure-Python ones alone: `python3 -m pip install --user --break-system-packages " + " ".join(
            f"'{m}'" for m in pure) + "`, or from QGIS's Python console, into the profile: `from gistools_qgis.install " \
            "import install_dependencies; print(install_dependencies().message)`"
    if bound:
        text += ". Debian's own packages work too: `sudo apt-get install " + " ".join(
            f"python3-{m.split('>')[0]}" for m in bound) + "`"
    return text + (". On Windows (OSGeo4W Shell) or macOS (the QGIS bundle's python3) use QGIS's own builds of the "
                   "GDAL / PROJ bound packages and pip for the rest (untested there). Then restart QGIS.")



class GistoolsPlugin:
    def __init__(self, iface=None):
        self.iface = iface
        self.provider = None
        self.missing: list[str] = []
        self.mismatches: list[str] = []

    def initProcessing(self):  # noqa: N802 (QGIS's name)
        add_to_path(default_target())  # what install_dependencies() put in the profile, after QGIS's own packages
        self.mismatches = bundled_before_import()  # before any of them loads its own GDAL / GEOS into QGIS
        if self.mismatches:
            QgsMessageLog.logMessage(mismatch_message(self.mismatches), "gistools", CRITICAL)
            return
        self.missing = missing_requirements()
        if self.missing:
            QgsMessageLog.logMessage(missing_message(self.missing), "gistools", CRITICAL)
            return
        self.mismatches = library_mismatches()
        if self.mismatches:
            QgsMessageLog.logMessage(mismatch_message(self.mismatches), "gistools", CRITICAL)
            return
        from .provider import GistoolsProvider

        self.provider = GistoolsProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        self.initProcessing()
        if self.iface is not None and (self.missing or self.mismatches):
            text = missing_message(self.missing) if self.missing else mismatch_message(self.mismatches)
            self.iface.messageBar().pushMessage("gistools", text, level=CRITICAL, duration=0)

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
