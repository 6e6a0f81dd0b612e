"""PROJ's data (proj.db), found where the system keeps it: checked once before any input is read.

pyproj finds PROJ's database through ``PROJ_DATA`` / ``PROJ_LIB``, its own wheel's copy, or the ``proj`` command's
prefix. A pyproj built against the system's PROJ in a virtual environment (Debian's route, a venv beside QGIS)
finds none of them when the ``proj`` command is not installed, although the system's PROJ package holds the data:
every CRS would then fail to parse, tile by tile. :func:`ensure_proj_data` looks where PROJ's packages and QGIS
keep it, tells pyproj, and where it is nowhere stops the run once with one line that names PROJ and the fix.
"""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

from .errors import GistoolsError

__all__ = ["ProjDataError", "ensure_proj_data", "proj_data_candidates"]


class ProjDataError(GistoolsError):
    """PROJ's database is not found: the installation's problem, not an input's."""


def proj_data_candidates() -> list[Path]:
    """Folders that may hold PROJ's proj.db, in the order they are tried: this Python's prefixes (conda, a venv
    beside a bundle), the system's PROJ packages (Debian / Fedora / Homebrew / MacPorts), QGIS's bundles (macOS,
    OSGeo4W and the standalone Windows installer)."""
    prefixes = {Path(sys.prefix), Path(sys.base_prefix), Path(sys.exec_prefix)}
    found = [p / "share" / "proj" for p in sorted(prefixes)] + [p / "Library" / "share" / "proj" for p in sorted(prefixes)]
    found += [Path(d) for d in ("/usr/share/proj", "/usr/local/share/proj", "/opt/homebrew/share/proj",
                                "/opt/local/lib/proj9/share/proj", "/opt/local/share/proj")]
    qgis = os.environ.get("QGIS_PREFIX_PATH")
    if qgis:
        found += [Path(qgis) / "share" / "proj", Path(qgis).parent.parent / "share" / "proj"]
    found += [Path("/Applications/QGIS.app/Contents/Resources/proj"),
              Path("/Applications/QGIS-LTR.app/Contents/Resources/proj")]
    for root in (os.environ.get("OSGEO4W_ROOT"), "C:/OSGeo4W", "C:/OSGeo4W64"):
        if root:
            found.append(Path(root) / "share" / "proj")
    program_files = os.environ.get("ProgramFiles")
    if program_files:
        found += sorted(Path(program_files).glob("QGIS */share/proj"), reverse=True)
    return found


def _works() -> bool:
    import pyproj

    try:
        pyproj.CRS.from_epsg(4326)
        return True
    except (pyproj.exceptions.CRSError, pyproj.exceptions.DataDirError):  # newer pyproj: DataDirError
        return False


def _has_db(value: str | None) -> bool:
    return any((Path(part) / "proj.db").is_file() for part in (value or "").split(os.pathsep) if part)


@functools.cache
def ensure_proj_data() -> str:
    """The folder pyproj takes PROJ's data from, found if need be (see the module); ``PROJ_DATA`` / ``PROJ_LIB``
    naming a folder without proj.db are dropped, so that GDAL's PROJ (rasterio, pyogrio) takes its own data; raises
    ProjDataError once where there is none."""
    import pyproj
    from pyproj import datadir

    folder = datadir.get_data_dir() if _works() else None
    if folder is None:
        for candidate in proj_data_candidates():
            if (candidate / "proj.db").is_file():
                datadir.set_data_dir(str(candidate))
                if _works():
                    folder = str(candidate)
                    break
    if folder is None:
        raise ProjDataError(
            f"PROJ's database (proj.db) is not found: pyproj {pyproj.__version__} uses PROJ "
            f"{pyproj.proj_version_str}, whose data is neither where PROJ_DATA points nor in its packages' folders",
            hint="Install PROJ's data (Debian / Ubuntu: sudo apt-get install proj-data proj-bin; conda: conda install "
                 "proj-data), or point PROJ_DATA at the folder holding proj.db")
    stale = [var for var in ("PROJ_DATA", "PROJ_LIB") if var in os.environ and not _has_db(os.environ[var])]
    for var in stale:  # a folder without proj.db: each library takes its own data instead (a binary wheel's
        del os.environ[var]  # copy matches its own PROJ, which another PROJ's proj.db would not)
    if stale and "rasterio" in sys.modules:  # rasterio took the variable when it started: its own data now
        from rasterio.env import PROJDataFinder, set_proj_data_search_path

        own = PROJDataFinder().search()
        set_proj_data_search_path(own or folder)
    return folder
