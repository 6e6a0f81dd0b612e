"""Installing what the plugin needs into QGIS's Python, without a prompt: ``install_dependencies()``.

In the QGIS Python console (Plugins > Python Console)::

    from gistools_qgis.install import install_dependencies
    print(install_dependencies(gistools="C:/Downloads/gistools-0.1.0-cp312-cp312-win_amd64.whl").message)

It runs pip with QGIS's own Python in two steps: a dry run resolves what the missing packages need against what
QGIS's Python already has (a constraints file pins every package it has to the version it has, so nothing QGIS uses
changes under it), then ``python -m pip install --no-deps --prefix <profile>/python/gistools_deps ...`` installs only
what QGIS's Python lacks, each at most once. The prefix's site-packages folder is added at the end of ``sys.path``
(the plugin adds it at every start), then the GDAL / PROJ / GEOS check runs before the algorithms are enabled.

rasterio, pyogrio, pyproj and shapely are linked to GDAL / PROJ / GEOS. Where QGIS's Python lacks one, it is taken
from QGIS's own installer where that can run unattended (OSGeo4W's setup), else, as a last resort, from pip's binary
wheel, which brings its own copy of the library into QGIS's process: only after that wheel passed a trial in a QGIS
process of its own (bound.py) and in the version tried. While one of them is still missing it installs nothing (pip
would fetch their wheels as dependencies of geopandas or gistools) and names the one command that installs QGIS's
(or the system's) builds. When it cannot install (no pip, no network), its message holds the one command to run by
hand. The message says which route each package took.

The checks of what QGIS's Python has (``missing_requirements``, ``library_mismatches``, ``bundled_before_import``)
are this module's too: the plugin's start (plugin.py) imports them from here, and this module imports nothing of the
plugin, so the two never import each other.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from .bound import checked, osgeo4w_command, osgeo4w_setup, record, trial, version_beside

__all__ = ["DEPS_FOLDER", "InstallResult", "default_target", "qgis_python", "install_dependencies", "add_to_path",
           "site_folders", "missing_requirements", "library_mismatches", "bundled_libraries", "bundled_before_import",
           "untried_wheels", "mismatch_message"]

DEPS_FOLDER = "gistools_deps"
# pip run by an isolated interpreter (-I: neither the current folder, nor PYTHONPATH / PYTHONHOME, nor the user's
# site-packages on its path), so that a ``pip`` package planted in the folder QGIS was started from, or on a
# variable, never runs in its place; the run's own folder is a fresh empty one (``_pip``)
PIP = ("-I", "-m", "pip")
BOUND = ("rasterio", "pyogrio", "pyproj", "shapely")  # built against GDAL / PROJ / GEOS: QGIS's builds only
WHEELS = Path(__file__).resolve().parent / "wheels"  # gistools' own wheels in the plugin's zip (tools/build_plugin.py)

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


def missing_requirements(skip=()) -> list[str]:
    """The pip names of the packages QGIS's Python cannot import (empty when all are there); the modules in
    ``skip`` are taken as there without being imported (wheels not to load before their trial).

    gistools itself is named only when its dependencies are all there (else it fails because of them).
    """
    missing = []
    for module, pip_name in REQUIREMENTS + (("gistools", "gistools"),):
        if module == "gistools" and missing:
            break
        if module in skip:
            continue
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


def _major_minor(version: str) -> tuple[int, ...]:
    return tuple(int(p) for p in version.split("-")[0].split(".")[:2])


def library_mismatches(target=None) -> list[str]:
    """Where shapely / pyproj / rasterio / pyogrio use another GEOS / PROJ / GDAL than QGIS links: their own copy
    from a binary wheel (its folder of libraries beside the package) or another version. Two copies of one
    library in QGIS's process may fail (GEOS: 'WKB output dimension must be 2 or 3') or crash QGIS on exit, so
    only the wheels that passed the trial in a QGIS process of their own (bound.py; recorded in ``target``, the
    profile's folder by default) are let through."""
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
    checks = [("shapely", "GEOS", shapely.geos_version_string, qgis_geos),
              ("pyproj", "PROJ", pyproj.proj_version_str, qgis_proj),
              ("rasterio", "GDAL", rasterio.__gdal_version__, qgis_gdal),
              ("pyogrio", "GDAL", pyogrio.__gdal_version_string__, qgis_gdal)]
    passed = _passed(target)
    for package, lib, version, want in checks:
        if _tried_and_passed(passed, package, _version_of_module(package)):
            continue
        parts = 1 if lib == "PROJ" else 2
        if want is not None and _major_minor(version)[:parts] != tuple(want)[:parts]:
            found.append(f"{package} uses {lib} {version}, QGIS {'.'.join(map(str, want))}.x")
    for package in sorted(BOUND):
        folder = bundled_libraries(importlib.import_module(package))
        if folder is not None and not _tried_and_passed(passed, package, _version_of_module(package)):
            found.append(f"{package} carries its own libraries ({folder.name}, a binary wheel)")
    return found


def bundled_libraries(module) -> Path | None:
    """The folder of shared libraries a binary wheel brought with ``module``, None where it uses the system's.

    Read from the installed files, on every platform (no /proc): auditwheel (Linux) and delvewheel (Windows) put
    them in ``<site-packages>/<name>.libs``, delocate (macOS) in ``<package>/.dylibs``."""
    where = getattr(module, "__file__", None)
    return _bundled_folder(Path(where).parent) if where else None


def untried_wheels(target=None) -> dict:
    """{package: installed version} of the GDAL / PROJ / GEOS bound packages that are binary wheels carrying their
    own libraries and did not pass the trial in this QGIS in that version (bound.py), found from their installed
    files: nothing is imported."""
    found = {}
    passed = _passed(target)
    for package in sorted(BOUND):
        try:
            spec = importlib.util.find_spec(package)
        except (ImportError, ValueError):
            continue
        folder = _bundled_folder(Path(spec.origin).parent) if spec is not None and spec.origin else None
        version = version_beside(spec.origin) if folder is not None else None
        if folder is not None and not _tried_and_passed(passed, package, version):
            found[package] = version
    return found


def bundled_before_import(target=None) -> list[str]:
    """The GDAL / PROJ / GEOS bound packages that are binary wheels carrying their own libraries, found from their
    installed files before any of them is imported: importing one loads its copy of GEOS or GDAL into QGIS's process
    beside QGIS's own, which may crash QGIS (at the latest when it exits), so such a set-up is refused first, but
    for the wheels that passed the trial in a QGIS process of their own (bound.py; recorded in ``target``, the
    profile's folder by default), in the version tried."""
    found = []
    for package in untried_wheels(target):
        folder = _bundled_folder(Path(importlib.util.find_spec(package).origin).parent)
        found.append(f"{package} carries its own libraries ({folder.name}, a binary wheel)")
    return found


def _passed(target) -> dict:
    """{package: version} of the wheels that passed the trial in this QGIS (bound.checked), {} where none did."""
    try:
        return checked(default_target() if target is None else target)
    except Exception:  # noqa: BLE001 - no QGIS settings yet: nothing passed
        return {}


def _tried_and_passed(passed: dict, package: str, version: str | None) -> bool:
    return version is not None and passed.get(package) == version


def _version_of_module(package: str) -> str | None:
    module = sys.modules.get(package) or importlib.import_module(package)
    return version_beside(module.__file__) if getattr(module, "__file__", None) else None


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
            "the libraries QGIS links, as the documentation's QGIS page (docs/qgis.md) shows (Debian: "
            "`PIP_NO_BINARY=rasterio,pyogrio,shapely,pyproj pip install --user --break-system-packages "
            "--force-reinstall --no-deps rasterio pyogrio "
            "shapely pyproj`, after the build packages it lists), or use Debian's python3-rasterio / python3-pyproj / "
            "python3-shapely / python3-pyogrio; or, from the QGIS Python console, install_dependencies() from "
            "gistools_qgis.install tries pip's wheels in a QGIS process of their own and keeps those that pass. Then "
            "restart QGIS.")


@dataclass
class InstallResult:
    """What ``install_dependencies`` did: ``ok`` when every requirement imports and matches QGIS's libraries."""

    target: Path
    installed: list = field(default_factory=list)  # pip names given to pip
    command: list = field(default_factory=list)  # the pip command run (empty: nothing to run)
    missing: list = field(default_factory=list)  # still missing afterwards
    mismatches: list = field(default_factory=list)  # GDAL / PROJ / GEOS differences afterwards
    message: str = ""

    @property
    def ok(self) -> bool:
        return not self.missing and not self.mismatches


def default_target() -> Path:
    """``<QGIS profile>/python/gistools_deps`` of the running QGIS."""
    from qgis.core import QgsApplication

    return Path(QgsApplication.qgisSettingsDirPath()) / "python" / DEPS_FOLDER


def site_folders(target: Path) -> list[Path]:
    """The site-packages folders of this Python's version under the prefix ``target`` (``lib/python3.X/site-packages``,
    Debian's ``local/lib/python3.X/dist-packages``, Windows' ``Lib/site-packages``)."""
    target = Path(target)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    found = []
    for pattern in (f"lib/{version}/*-packages", f"local/lib/{version}/*-packages", f"lib64/{version}/*-packages",
                    "Lib/site-packages"):
        found += [p for p in sorted(target.glob(pattern)) if p.is_dir() and p not in found]
    return found


def add_to_path(target: Path) -> bool:
    """Put the site-packages folders of the prefix ``target`` at the end of ``sys.path`` (QGIS's own packages keep
    precedence); False when there is none."""
    folders = site_folders(target)
    for folder in folders:
        if str(folder) not in sys.path:
            sys.path.append(str(folder))
            importlib.invalidate_caches()
    return bool(folders)


def qgis_python() -> Path | None:
    """The Python interpreter of this QGIS, found without starting QGIS: inside QGIS ``sys.executable`` is QGIS
    itself on Windows (``qgis-bin.exe``) and macOS (``QGIS.app/Contents/MacOS/QGIS``), and running it would open a
    second QGIS, so only files named ``python*`` are run (to ask their version), in the places the installers put
    them: ``sys.prefix`` (OSGeo4W's and the standalone installer's ``apps/Python3x/python.exe``), its ``bin``, the
    macOS bundle's ``Contents/MacOS/bin/python3`` beside QGIS's binary, and Linux's ``/usr/bin/python3.X``.
    The first of this process's version; None where none is found."""
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    names = ("python.exe", "python3.exe") if os.name == "nt" else (f"python{version}", "python3", "python")
    here = Path(sys.executable).parent
    prefixes = [Path(sys.prefix), Path(sys.base_prefix), Path(sys.exec_prefix), here]
    candidates = [Path(sys.executable)] + [p / sub / n for p in prefixes for sub in ("", "bin") for n in names]
    seen = set()
    for exe in candidates:
        if exe in seen or not exe.name.lower().startswith("python"):
            continue  # QGIS's own binary (or a copy seen already): never run
        seen.add(exe)
        if exe.is_file() and _version_of(exe) == version:
            return exe
    return None


def _version_of(exe: Path) -> str | None:
    try:
        run = subprocess.run([str(exe), "-c", "import sys; print('%d.%d' % sys.version_info[:2])"], capture_output=True,
                             text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return run.stdout.strip() if run.returncode == 0 else None


def _name(name: str) -> str:
    """A distribution's name as pip compares names (PEP 503)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _installed() -> dict:
    """{name: version} of every distribution this Python has (Debian's builds may say ``0+unknown``)."""
    from importlib.metadata import distributions

    return {_name(d.metadata.get("Name")): d.version for d in distributions() if d.metadata.get("Name")}


def _constraints(have: dict) -> str:
    """``name==version`` of every distribution this Python has and pip could match: pip keeps those versions. A
    version without a release number (``0+unknown``) is left out, as are the GDAL / PROJ / GEOS bound packages."""
    keep = {n: v for n, v in have.items() if v and n not in BOUND and re.fullmatch(r"[1-9]\d*(\.\d+)*\S*|0\.\d+\S*", v)}
    return "".join(f"{name}=={version}\n" for name, version in sorted(keep.items()))


def _local(url: str) -> str:
    """A file:// URL of pip's report as a path."""
    from urllib.parse import unquote, urlparse
    from urllib.request import url2pathname

    return url2pathname(unquote(urlparse(url).path))


def _quoted(parts) -> str:
    """``parts`` as one command line to paste into this platform's shell: each part quoted by its rules (POSIX
    shells: ``shlex.quote``, so a file named ``$(...)`` or with quotes stays one word and runs nothing; Windows:
    ``subprocess.list2cmdline``, as cmd.exe and CreateProcess split)."""
    import shlex

    parts = [str(p) for p in parts]
    if os.name == "nt":
        return subprocess.list2cmdline(parts)
    return " ".join(shlex.quote(p) for p in parts)


def _bound_command(bound: list) -> str:
    """The one command that installs QGIS's / the system's builds of the GDAL / PROJ / GEOS bound packages."""
    if sys.platform.startswith("linux"):
        return "sudo apt-get install " + " ".join(f"python3-{name}" for name in bound)
    if os.name == "nt":
        return ("OSGeo4W Setup (Advanced Install): " + ", ".join(f"python3-{name}" for name in bound)
                + " (QGIS's own builds)")
    return "the QGIS bundle's own " + ", ".join(bound) + " (QGIS's builds; pip's wheels carry other libraries)"


def install_dependencies(target=None, *, gistools=None, python=None, requirements=None, timeout: float = 1800
                         ) -> InstallResult:
    """Install the packages QGIS's Python lacks into ``target`` with QGIS's own Python, non-interactively.

    Parameters
    ----------
    target : path, optional
        The folder to install into (default ``<QGIS profile>/python/gistools_deps``).
    gistools : str or path, optional
        Where gistools itself comes from when QGIS's Python lacks it (a wheel, an sdist or a source folder; it is
        not on PyPI); its own dependencies come with it.
    python : path, optional
        The interpreter to run pip with (default: this QGIS's, :func:`qgis_python`).
    requirements : list of str, optional
        pip requirements to install instead of the missing ones (tests, or a chosen set).
    timeout : float
        Seconds pip may take.

    Returns
    -------
    InstallResult
        ``ok`` when every requirement imports and uses QGIS's GDAL / PROJ / GEOS; else ``message`` says what is
        missing and the one command that installs it.
    """
    target = Path(target).expanduser().absolute() if target is not None else default_target()
    result = InstallResult(target=target)
    untried, bound, wanted, notes = _what_to_install(target, gistools, requirements)
    exe = Path(python) if python is not None else qgis_python()
    failure, engine, tried = None, "", {}
    if bound:
        bound, tried = _bound_builds(bound, exe, timeout, notes, pins=untried)
        wanted += [f"{name}=={version}" for name, version in tried.items()]
    if "gistools" in wanted and not bound:
        _take_zip_wheel(wanted, exe, timeout, notes)
    if wanted and not bound:
        failure = _install(exe, wanted, target, timeout, result, tried, notes)
    elif tried and not bound:  # wheels installed already, tried now in their version
        _record(target, tried, notes)
    add_to_path(target)
    if requirements is None:
        result.missing = missing_requirements()
        result.mismatches = [] if result.missing else library_mismatches(target)
        engine = _engine_note() if not failure and _takes_gistools(wanted) and not result.missing else ""
    elif failure:
        result.missing = wanted
    if bound:
        notes.append(f"{', '.join(bound)} should be QGIS's own builds (pip's wheels bring other GDAL / PROJ / GEOS "
                     f"libraries into QGIS's process); install them with: {_bound_command(bound)}; then run "
                     "install_dependencies() again" + (f" (it installs {', '.join(wanted)})" if wanted else ""))
    result.message = _message(result, notes) + (f"; {engine}" if engine else "")
    return result


def _what_to_install(target: Path, gistools, requirements) -> tuple[dict, list, list, list]:
    """(the bound wheels installed but never tried {package: version}, the bound packages to bring, what pip
    installs, notes): ``requirements`` when given, else what QGIS's Python lacks; an untried wheel is never
    imported here (missing_requirements skips it) and is tried again."""
    if requirements is not None:
        return {}, [], list(requirements), []
    untried = untried_wheels(target)
    bound, wanted, notes = _plan(missing_requirements(skip=untried), gistools)
    return untried, sorted(set(bound) | set(untried)), wanted, notes


def _install(exe, wanted: list, target: Path, timeout: float, result: InstallResult, tried: dict, notes: list
             ) -> str | None:
    """pip installs ``wanted`` into the prefix ``target`` (the bound wheels in ``tried`` among them, recorded as
    passed once installed): why it failed (the command to run by hand in ``notes``), None when it worked."""
    cmd = [str(exe or "python"), *PIP, "install", "--disable-pip-version-check", "--no-input",
           "--prefix", str(target), *wanted]
    result.installed = wanted
    failure = _run_pip(exe, cmd, target, timeout, result, allow=set(tried))
    if failure:
        notes.insert(0, f"{failure}. Run this once, then restart QGIS: {_quoted(cmd)}")
    elif tried:
        _record(target, tried, notes)
    return failure


def _record(target: Path, tried: dict, notes: list) -> None:
    """The wheels that passed the trial, recorded in ``target``; a note where the record cannot be written (the
    plugin will refuse them at its next start)."""
    try:
        record(target, {**_passed(target), **tried})
    except Exception as err:  # noqa: BLE001 - an unwritable profile: said, not raised
        notes.append(f"the record of the wheels tried could not be written ({err}): the plugin will refuse them")


def _plan(missing: list, gistools) -> tuple[list, list, list]:
    """(the GDAL / PROJ / GEOS bound packages missing, what pip installs, notes) of the missing requirements
    (gistools is wanted whenever it does not import, even when ``missing`` does not name it yet)."""
    bound = sorted({m.split(">")[0] for m in missing} & set(BOUND))
    wanted = [m for m in missing if m.split(">")[0] not in BOUND and m != "gistools"]
    notes = []
    lacks = "gistools" in missing or importlib.util.find_spec("gistools") is None
    if lacks and gistools is not None:
        given = Path(gistools).expanduser()
        wanted.append(str(given.absolute()) if given.exists() else str(gistools))  # pip runs in a folder of its own
    elif lacks and any(WHEELS.glob("gistools-*.whl")):
        wanted.append("gistools")  # the zip's wheel for this platform (install_dependencies: _zip_wheel)
    elif lacks:
        notes.append("gistools itself is not on PyPI: give its wheel, install_dependencies("
                     "gistools='path/to/gistools-<version>-<python>-<platform>.whl')")
    return bound, wanted, notes


def _bound_builds(bound: list, exe, timeout: float, notes: list, pins=None) -> tuple[list, dict]:
    """The GDAL / PROJ / GEOS bound packages QGIS's Python lacks, from QGIS's installer where it can add them
    unattended (OSGeo4W's setup), else pip's binary wheels that pass the trial in a QGIS process (bound.trial):
    (those still missing, {package: version} of the wheels to install); ``notes`` say which route each took.
    ``pins`` {package: version}: wheels installed already but not tried, tried in that version."""
    pins = pins or {}
    if not set(bound) <= set(pins):  # packages missing (not only installed wheels to try): QGIS's installer first
        bound = _from_osgeo4w(bound, timeout, notes)
    if not bound or exe is None:
        return bound, {}
    return _wheel_trials(bound, exe, timeout, notes, pins)


def _from_osgeo4w(bound: list, timeout: float, notes: list) -> list:
    """The bound packages OSGeo4W's setup could not add (all of them where QGIS is not an OSGeo4W install)."""
    setup = osgeo4w_setup()
    if setup is None:
        return bound
    failure = _pip(osgeo4w_command(*setup, bound), timeout)  # runs any program the way it runs pip
    importlib.invalidate_caches()
    added = [name for name in bound if importlib.util.find_spec(name) is not None]
    if added:
        notes.append(f"installed OSGeo4W's {', '.join(added)} (QGIS's own builds) with its setup")
    elif failure:
        notes.append(f"OSGeo4W's setup did not add {', '.join(bound)} ({failure.replace('pip', 'setup')})")
    return [name for name in bound if name not in added]


def _wheel_trials(bound: list, exe, timeout: float, notes: list, pins: dict) -> tuple[list, dict]:
    """pip's binary wheels of ``bound`` (in the versions of ``pins``) tried in QGIS processes of their own: (those
    that failed, {package: version} of those that passed)."""
    with tempfile.TemporaryDirectory(prefix="gistools-trial-") as folder:
        site = Path(folder) / "site"
        constraints = Path(folder) / "constraints.txt"
        constraints.write_text(_constraints(_installed()), encoding="utf-8")
        failure = _pip([str(exe), *PIP, "install", "--disable-pip-version-check", "--no-input", "--only-binary",
                        ":all:", "--constraint", str(constraints), "--target", str(site),
                        *[f"{name}=={pins[name]}" if pins.get(name) else name for name in bound]], timeout)
        if failure:
            notes.append(f"pip's binary wheels of {', '.join(bound)} could not be fetched ({failure})")
            return bound, {}
        passed, failed = _tried(exe, site, bound, timeout)
        versions = {name: version_beside(site / name / "__init__.py") for name in passed}
        for name in [n for n, v in versions.items() if not v]:  # no readable version: it could not be recorded
            failed[name] = "its version could not be read from the wheel"
            passed.remove(name)
            del versions[name]
    for name, why in failed.items():
        notes.append(f"pip's binary wheel of {name} failed the trial in a QGIS process of its own ({why}): not "
                     "installed")
    if passed:
        notes.append(f"{', '.join(passed)}: pip's binary wheels (their own GDAL / PROJ / GEOS), installed after a "
                     "QGIS process with them gave QGIS's answers and ended cleanly")
    return [name for name in bound if name not in passed], versions


def _tried(exe, site: Path, bound: list, timeout: float) -> tuple[list, dict]:
    """(the packages whose wheels pass the trial alone and all together, {package: why not} of the others)."""
    failed = {name: why for name in bound if (why := trial(exe, site, [name], timeout)) is not None}
    passed = [name for name in bound if name not in failed]
    if len(passed) > 1 and (why := trial(exe, site, passed, timeout)) is not None:
        failed.update({name: f"together with {', '.join(n for n in passed if n != name)}: {why}" for name in passed})
        passed = []
    return passed, failed


def _take_zip_wheel(wanted: list, exe, timeout: float, notes: list) -> None:
    """``"gistools"`` in ``wanted`` replaced by the path of the zip's own wheel for this platform, never an index's
    (another project has the name); a note where none fits."""
    chosen = _zip_wheel(exe, timeout) if exe is not None else None
    wanted.remove("gistools")
    if chosen is not None:
        wanted.append(chosen)
    else:
        notes.append("no gistools wheel of the plugin fits this QGIS's Python: give one, install_dependencies("
                     "gistools='path/to/gistools-<version>-<python>-<platform>.whl')")


def _takes_gistools(wanted: list) -> bool:
    return any(Path(str(w)).name.startswith("gistools-") or str(w) == "gistools" for w in wanted)


def _zip_wheel(exe, timeout: float) -> str | None:
    """The path of the plugin's gistools wheel (wheels/) that pip, run by ``exe``, takes for this platform: its
    platform wheel (the compiled kernel) where one fits, else the pure one; from that folder alone, never an
    index. None where none fits."""
    import json

    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report.json"
        failure = _pip([str(exe), *PIP, "install", "--dry-run", "--quiet", "--no-deps", "--no-index",
                        "--ignore-installed", "--disable-pip-version-check", "--find-links", str(WHEELS), "--report",
                        str(report), "gistools"], timeout)
        if failure or not report.is_file():
            return None
        items = json.loads(report.read_text(encoding="utf-8")).get("install", [])
    urls = [item.get("download_info", {}).get("url", "") for item in items]
    return next((_local(url) for url in urls if url.startswith("file:")), None)


def _engine_note() -> str:
    """Where the gistools installed has no compiled kernel (the zip's pure wheel, no wheel of this platform): a
    note saying that the numpy engine runs ("" where the kernel runs)."""
    try:
        from gistools import kernel

        if kernel.loaded():
            return ""
    except Exception:  # noqa: BLE001 - reported as missing instead
        return ""
    return ("gistools runs its numpy engine here (no wheel with the compiled kernel for this platform): the same "
            "results, several times slower on large tiles; a platform wheel given as install_dependencies("
            "gistools='gistools-<version>-cp311-abi3-<platform>.whl') brings the kernel")


def _message(result: InstallResult, notes: list) -> str:
    if notes:
        return "gistools: " + "; ".join(notes)
    if result.mismatches:
        return mismatch_message(result.mismatches)
    if result.missing:
        return f"gistools: still missing after the install: {', '.join(result.missing)}"
    if result.installed:
        return f"gistools: installed {', '.join(result.installed)} into {result.target}; restart QGIS"
    return "gistools: nothing to install"


def _run_pip(exe, cmd: list, target: Path, timeout: float, result: InstallResult, allow=frozenset()) -> str | None:
    """Resolve ``cmd``'s requirements with pip against what this Python has (constraints pin it), then install what
    is missing, without the bound packages but those in ``allow`` (wheels that passed the trial), with
    ``--no-deps``: the reason it failed, None when it worked."""
    import json

    if exe is None or not Path(exe).is_file():
        return "QGIS's Python interpreter was not found"
    have = _installed()
    at = cmd.index("--prefix")
    wanted = cmd[at + 2:]
    with tempfile.TemporaryDirectory() as tmp:
        pins, report = Path(tmp) / "constraints.txt", Path(tmp) / "report.json"
        pins.write_text(_constraints(have), encoding="utf-8")
        head = len(PIP) + 2  # the interpreter, -I -m pip, install
        plan = cmd[:head] + ["--dry-run", "--quiet", "--report", str(report), "--constraint", str(pins), *cmd[head:at],
                             *wanted]
        failure = _pip(plan, timeout)
        if failure:
            result.command = plan
            return failure
        chosen = []
        for item in json.loads(report.read_text(encoding="utf-8")).get("install", []):
            meta, url = item["metadata"], item.get("download_info", {}).get("url", "")
            name = _name(meta["name"])
            if (name in BOUND and name not in allow) or name in have:
                continue  # QGIS's build, or what QGIS's Python has (its copy comes first on the path anyway)
            chosen.append(_local(url) if url.startswith("file:") else f"{meta['name']}=={meta['version']}")
    result.command = cmd[:head] + ["--no-deps"] + cmd[head:at + 2] + chosen
    if not chosen:
        return None
    target.mkdir(parents=True, exist_ok=True)
    return _pip(result.command, timeout)


def _pip(command: list, timeout: float) -> str | None:
    """Run pip (``command``) in an empty folder of its own: the folder QGIS was started from is never its working
    folder (with -I it is not on the path either)."""
    try:
        with tempfile.TemporaryDirectory(prefix="gistools-pip-") as cwd:
            run = subprocess.run(command, capture_output=True, text=True, timeout=timeout, cwd=cwd, encoding="utf-8",
                                 errors="replace")
    except (OSError, subprocess.SubprocessError) as err:
        return f"pip could not run ({err})"
    if run.returncode != 0:
        lines = [line for line in (run.stderr or run.stdout).splitlines() if line.strip() and "WARNING" not in line]
        return f"pip failed ({lines[-1] if lines else f'exit status {run.returncode}'})"
    return None
