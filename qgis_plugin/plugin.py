"""The plugin object QGIS loads: registers the gistools Processing provider, or explains what is missing."""

from __future__ import annotations

import importlib
from pathlib import Path

from qgis.core import QgsApplication, QgsMessageLog
from .compat import CRITICAL

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


_BOUND = {"rasterio", "pyogrio", "pyproj", "shapely"}  # linked to GDAL / PROJ / GEOS: built against QGIS's copies


def missing_message(missing: list[str]) -> str:
    pure = [m for m in missing if m.split(">")[0] not in _BOUND | {"numpy", "scipy", "geopandas", "gistools"}]
    bound = [m for m in missing if m.split(">")[0] in _BOUND]
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


def _major_minor(version: str) -> tuple[int, ...]:
    return tuple(int(p) for p in version.split("-")[0].split(".")[:2])


def library_mismatches() -> list[str]:
    """Where shapely / pyproj / rasterio / pyogrio use another GEOS / PROJ / GDAL than QGIS links: their own copy
    from a binary wheel (its folder of libraries beside the package) or another version. Two copies of one
    library in QGIS's process fail (GEOS: 'WKB output dimension must be 2 or 3') or crash QGIS on exit."""
    from qgis.core import Qgis, QgsProjUtils

    found = []
    try:
        import pyogrio
        import pyproj
        import rasterio
        import shapely
    except Exception:  # reported as missing instead
        return found
    qgis_geos = _major_minor(Qgis.geosVersion())
    qgis_proj = (QgsProjUtils.projVersionMajor(),)
    try:
        from osgeo import gdal

        qgis_gdal = _major_minor(gdal.__version__)
    except Exception:
        qgis_gdal = None
    # QGIS reports the PROJ it was built with (runtime minors differ under one soname): PROJ is compared by major only
    checks = [("shapely", "GEOS", shapely.geos_version_string, qgis_geos), ("pyproj", "PROJ", pyproj.proj_version_str, qgis_proj),
              ("rasterio", "GDAL", rasterio.__gdal_version__, qgis_gdal),
              ("pyogrio", "GDAL", pyogrio.__gdal_version_string__, qgis_gdal)]
    for package, lib, version, want in checks:
        if want is not None and _major_minor(version)[: 1 if lib == "PROJ" else 2] != tuple(want)[: 1 if lib == "PROJ" else 2]:
            found.append(f"{package} uses {lib} {version}, QGIS {'.'.join(map(str, want))}.x")
    for package in sorted(_BOUND):
        folder = bundled_libraries(importlib.import_module(package))
        if folder is not None:
            found.append(f"{package} carries its own libraries ({folder.name}, a binary wheel)")
    return found


def bundled_libraries(module) -> Path | None:
    """The folder of shared libraries a binary wheel brought with ``module``, None where it uses the system's.

    Read from the installed files, on every platform (no /proc): auditwheel (Linux) and delvewheel (Windows) put
    them in ``<site-packages>/<name>.libs``, delocate (macOS) in ``<package>/.dylibs``."""
    where = getattr(module, "__file__", None)
    return _bundled_folder(Path(where).parent) if where else None


def bundled_before_import() -> list[str]:
    """The GDAL / PROJ / GEOS bound packages that are binary wheels carrying their own libraries, found from their
    installed files before any of them is imported: importing one loads its copy of GEOS or GDAL into QGIS's process
    beside QGIS's own, which crashes QGIS (at the latest when it exits), so such a set-up is refused first."""
    import importlib.util

    found = []
    for package in sorted(_BOUND):
        try:
            spec = importlib.util.find_spec(package)
        except (ImportError, ValueError):
            continue
        folder = _bundled_folder(Path(spec.origin).parent) if spec is not None and spec.origin else None
        if folder is not None:
            found.append(f"{package} carries its own libraries ({folder.name}, a binary wheel)")
    return found


def _bundled_folder(package: Path) -> Path | None:
    for folder in (package.parent / f"{package.name}.libs", package / ".dylibs"):
        try:
            if folder.is_dir() and any(folder.iterdir()):
                return folder
        except OSError:
            continue
    return None


def mismatch_message(found: list[str]) -> str:
    return ("gistools: the Processing algorithms are not available: " + "; ".join(found) + ". Rebuild them against "
            "the libraries QGIS links, as the documentation's QGIS page (docs/qgis.md) shows (Debian: `PIP_NO_BINARY=rasterio,pyogrio,"
            "shapely,pyproj pip install --user --break-system-packages --force-reinstall --no-deps rasterio pyogrio "
            "shapely pyproj`, after the build packages it lists), or use Debian's python3-rasterio / python3-pyproj / "
            "python3-shapely / python3-pyogrio. Then restart QGIS.")


class GistoolsPlugin:
    def __init__(self, iface=None):
        self.iface = iface
        self.provider = None
        self.missing: list[str] = []
        self.mismatches: list[str] = []

    def initProcessing(self):  # noqa: N802 (QGIS's name)
        from .install import add_to_path, default_target

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
