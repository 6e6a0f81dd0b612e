"""GDAL / PROJ / GEOS bound packages (rasterio, pyogrio, pyproj, shapely) where QGIS's Python lacks them.

The order ``install_dependencies`` follows: the build QGIS's own installer offers (OSGeo4W's setup, run unattended,
where QGIS came from OSGeo4W); else, as a last resort, pip's binary wheels, each of which brings its own copy of GDAL,
PROJ or GEOS into QGIS's process. Whether two copies live together there depends on the platform and the versions
(Windows and macOS keep each library's symbols apart; Linux may bind a wheel's calls to QGIS's copy), so the wheels
are tried first, in a QGIS process of their own (:func:`trial`): QGIS started, each package's answer compared with
QGIS's on the same work (a buffer, a transformation, a GeoTIFF and a GeoPackage each side reads), QGIS ended. Only
when that process ends cleanly with equal answers are the wheels installed, and the plugin then loads what was tried
(:func:`checked`), nothing else.

This module imports nothing of the plugin and nothing of QGIS at import time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

CHECKED = "gistools_checked.json"  # in the profile's folder of packages: the wheels tried and passed
OSGEO4W_SITE = "https://download.osgeo.org/osgeo4w/v2/"
MARK = "GISTOOLS-TRIAL-OK"

_TRIAL = r'''
import json, os, sys, tempfile
folder, path, packages = os.path.realpath(sys.argv[1]), json.loads(sys.argv[2]), sys.argv[3].split(",")
prefix = sys.argv[4]
own = [p for p in sys.path if p not in ("", ".")]  # -c puts the working folder first: not the plugin's order
sys.path[:] = own + [p for p in path if p not in own and p != folder] + [folder]  # the profile's folder last
from qgis.core import (QgsApplication, QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry,
                       QgsPointXY, QgsProject, QgsRasterLayer, QgsVectorLayer)
if prefix:
    QgsApplication.setPrefixPath(prefix, True)  # where QGIS_PREFIX_PATH is not in the environment (macOS, Windows)
app = QgsApplication([], False)
app.initQgis()
tmp = tempfile.mkdtemp(prefix="gistools-trial-")
import numpy as np

def same(what, ours, theirs, tol):
    if abs(ours - theirs) > tol:
        raise SystemExit(f"{what}: QGIS {ours!r}, the wheel {theirs!r}")

for package in packages:
    __import__(package)
    where = os.path.realpath(os.path.dirname(sys.modules[package].__file__))
    if not where.startswith(folder):
        raise SystemExit(f"{package} came from {where}, not from the wheel tried")
    if package == "shapely":
        import shapely
        ours = QgsGeometry.fromWkt("POINT (3 4)").buffer(2.0, 16)
        same("a buffer's area", ours.area(), shapely.from_wkb(bytes(ours.asWkb())).area, 1e-9)
        same("a buffer's area", ours.area(), shapely.buffer(shapely.Point(3, 4), 2.0, quad_segs=16).area, 1e-9)
    elif package == "pyproj":
        import pyproj
        # a projection within one datum (NAD83): no choice of datum shift between two PROJ databases
        ours = QgsCoordinateTransform(QgsCoordinateReferenceSystem("EPSG:26910"),
                                      QgsCoordinateReferenceSystem("EPSG:4269"), QgsProject.instance())
        point = ours.transform(QgsPointXY(500000, 5000000))
        lon, lat = pyproj.Transformer.from_crs(26910, 4269, always_xy=True).transform(500000, 5000000)
        same("a longitude", point.x(), lon, 1e-8)
        same("a latitude", point.y(), lat, 1e-8)
    elif package == "rasterio":
        import rasterio
        from rasterio.transform import from_origin
        path = os.path.join(tmp, "trial.tif")
        values = np.arange(100, dtype="float32").reshape(1, 10, 10)
        with rasterio.open(path, "w", driver="GTiff", width=10, height=10, count=1, dtype="float32",
                           crs="EPSG:26910", transform=from_origin(0, 10, 1, 1)) as out:
            out.write(values)
        layer = QgsRasterLayer(path, "trial")
        if not layer.isValid() or layer.crs().authid() != "EPSG:26910":
            raise SystemExit("QGIS cannot read the GeoTIFF the wheel wrote")
        same("a raster's sum", layer.dataProvider().bandStatistics(1).sum, float(values.sum()), 1e-6)
    elif package == "pyogrio":
        import pyogrio
        import pyogrio.raw
        path = os.path.join(tmp, "trial.gpkg")
        wkb = bytes(QgsGeometry.fromWkt("POINT (1 2)").asWkb())
        pyogrio.raw.write(path, geometry=np.array([wkb], dtype=object), field_data=[np.array([5])], fields=["v"],
                          layer="points", driver="GPKG", geometry_type="Point", crs="EPSG:26910")
        layer = QgsVectorLayer(path + "|layername=points", "trial", "ogr")
        if not layer.isValid() or layer.featureCount() != 1 or layer.crs().authid() != "EPSG:26910":
            raise SystemExit("QGIS cannot read the GeoPackage the wheel wrote")
        same("a feature count", pyogrio.read_info(path, layer="points")["features"], 1, 0)
app.exitQgis()
import shutil
shutil.rmtree(tmp, ignore_errors=True)
print("''' + MARK + r'''", flush=True)
'''


def trial(python, folder, packages, timeout: float = 600, path=None) -> str | None:
    """Try the packages installed in ``folder`` (pip's ``--target``) in a QGIS process of ``python`` (QGIS's own
    interpreter), ``folder`` last on its path as the plugin puts the profile's packages, after ``path`` (default:
    this process's, QGIS's own folders among them): None when QGIS started, every answer equalled QGIS's, each
    package came from ``folder`` and the process ended cleanly; else why not (one line: the difference, the error,
    or the signal that ended the process)."""
    env = dict(os.environ)
    if sys.platform.startswith("linux") and not (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        env["QT_QPA_PLATFORM"] = "offscreen"
    path = [p for p in (sys.path if path is None else path) if p]
    try:
        run = subprocess.run([str(python), "-c", _TRIAL, str(folder), json.dumps(path), ",".join(packages),
                              _prefix()], capture_output=True, text=True, timeout=timeout, env=env, cwd=str(folder),
                             encoding="utf-8", errors="replace")
    except subprocess.TimeoutExpired:
        return f"QGIS's process with the wheels did not end within {timeout:.0f} s"
    except OSError as err:
        return f"QGIS's Python could not run ({err})"
    if run.returncode == 0 and MARK in run.stdout:
        return None
    if run.returncode < 0:
        return (f"QGIS's process with the wheel crashed (signal {-run.returncode}): the wheel's own GDAL / PROJ / GEOS "
                "do not live with QGIS's in one process")
    lines = [line for line in (run.stderr or run.stdout).splitlines() if line.strip()]
    return lines[-1] if lines else f"QGIS's process with the wheels ended with status {run.returncode}"


def _prefix() -> str:
    """The running QGIS's prefix path ("" outside QGIS)."""
    try:
        from qgis.core import QgsApplication

        return QgsApplication.prefixPath() or ""
    except Exception:  # noqa: BLE001 - no QGIS here
        return ""


def record(target, versions: dict) -> None:
    """Write ``<target>/gistools_checked.json``: the packages (name: version) that passed the trial, with the QGIS and
    Python they passed it in."""
    from qgis.core import Qgis

    Path(target).mkdir(parents=True, exist_ok=True)
    text = json.dumps({"qgis": Qgis.QGIS_VERSION, "python": "%d.%d" % sys.version_info[:2],
                       "packages": dict(sorted(versions.items()))}, indent=1)
    part = Path(target) / (CHECKED + ".part")
    part.write_text(text, encoding="utf-8")
    os.replace(part, Path(target) / CHECKED)


def checked(target) -> dict:
    """{package: version} that passed the trial in this QGIS and Python ({} when none did, or when QGIS or Python
    changed since: the trial then runs again)."""
    from qgis.core import Qgis

    try:
        data = json.loads((Path(target) / CHECKED).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if data.get("qgis") != Qgis.QGIS_VERSION or data.get("python") != "%d.%d" % sys.version_info[:2]:
        return {}
    return dict(data.get("packages") or {})


def version_beside(origin) -> str | None:
    """The version of the distribution whose package folder holds ``origin`` (its ``*.dist-info`` beside the package
    folder), read from the files: nothing is imported. Of several (an older copy left in the folder), the one
    whose RECORD lists the package; None where none tells."""
    package = Path(origin).parent
    head = package.name.lower() + "-"
    try:
        infos = sorted(p for p in package.parent.iterdir() if p.name.lower().startswith(head)
                       and p.name.endswith(".dist-info") and p.is_dir())
    except OSError:
        return None
    if len(infos) > 1:
        infos = [p for p in infos if _lists(p / "RECORD", package.name)] or infos[-1:]
    return infos[0].name[len(head):-len(".dist-info")] if len(infos) == 1 else None


def _lists(record_file: Path, package: str) -> bool:
    try:
        text = record_file.read_text(encoding="utf-8")
    except OSError:
        return False
    return f"{package}/__init__.py" in text.replace("\\", "/")


def osgeo4w_setup() -> tuple[Path, Path] | None:
    """(OSGeo4W's setup program, OSGeo4W's root) where QGIS came from OSGeo4W (its root holds ``etc/setup``) and
    OSGeo4W's own copy of its setup program is there (the root or its ``bin``); None elsewhere (the standalone
    installer, macOS, Linux)."""
    root = Path(sys.prefix).parent.parent  # <root>/apps/Python3x
    if not (root / "etc" / "setup").is_dir():
        return None
    folders = [root, root / "bin"]  # OSGeo4W's own copy only: never a program found elsewhere
    for folder in folders:
        found = sorted(folder.glob("osgeo4w-setup*.exe")) if folder.is_dir() else []
        if found:
            return found[-1], root
    return None


def osgeo4w_command(setup: Path, root: Path, packages) -> list:
    """OSGeo4W's setup, unattended (``--quiet-mode``, licences accepted), adding ``python3-<package>`` to ``root``."""
    return [str(setup), "--quiet-mode", "--autoaccept", "--advanced", "--root", str(root), "--site", OSGEO4W_SITE,
            "--local-package-dir", str(root / "var" / "cache" / "setup"), "--packages",
            ",".join(f"python3-{name}" for name in packages)]
