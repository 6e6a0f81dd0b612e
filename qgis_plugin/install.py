"""Installing what the plugin needs into QGIS's Python, without a prompt: ``install_dependencies()``.

In the QGIS Python console (Plugins > Python Console)::

    from gistools_qgis.install import install_dependencies
    print(install_dependencies(gistools="C:/Downloads/gistools-0.1.0-py3-none-any.whl").message)

It runs ``python -m pip install --target <profile>/python/gistools_deps ...`` with QGIS's own Python, for the
packages QGIS's Python cannot import, each at most once: what QGIS's Python already has is pinned to the version it
has (a constraints file), so nothing it uses changes under it. The folder is added at the end of ``sys.path`` (the
plugin adds it at every start), then the GDAL / PROJ / GEOS check runs before the algorithms are enabled.

rasterio, pyogrio, pyproj and shapely are linked to GDAL / PROJ / GEOS: pip's binary wheels bring their own copies,
which fail or crash inside QGIS, so this function never installs them; it names the one command that installs QGIS's
(or the system's) builds instead. When it cannot install (no pip, no network), its message holds the one command to
run by hand.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["DEPS_FOLDER", "InstallResult", "default_target", "qgis_python", "install_dependencies", "add_to_path"]

DEPS_FOLDER = "gistools_deps"
BOUND = ("rasterio", "pyogrio", "pyproj", "shapely")  # built against GDAL / PROJ / GEOS: QGIS's builds only


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


def add_to_path(target: Path) -> bool:
    """Put ``target`` at the end of ``sys.path`` (QGIS's own packages keep precedence); False when it is absent."""
    target = Path(target)
    if not target.is_dir():
        return False
    if str(target) not in sys.path:
        sys.path.append(str(target))
        importlib.invalidate_caches()
    return True


def qgis_python() -> Path | None:
    """The Python interpreter of this QGIS (inside QGIS ``sys.executable`` is QGIS itself on Windows and macOS):
    the first candidate of this process's version, None where none is found."""
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    names = ("python.exe", "python3.exe") if os.name == "nt" else (f"python{version}", "python3", "python")
    prefixes = [Path(sys.executable).parent, Path(sys.prefix), Path(sys.base_prefix), Path(sys.exec_prefix)]
    candidates = [Path(sys.executable)] + [p / sub / n for p in prefixes for sub in ("", "bin") for n in names]
    for exe in candidates:
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


def _constraints() -> str:
    """``name==version`` of every distribution this Python already has: pip keeps those versions."""
    from importlib.metadata import distributions

    pins = {}
    for dist in distributions():
        name = dist.metadata.get("Name")
        if name and dist.version:
            pins[name.lower()] = dist.version
    return "".join(f"{name}=={version}\n" for name, version in sorted(pins.items()))


def _quoted(parts) -> str:
    return " ".join(f'"{p}"' if (" " in str(p) or not str(p)) else str(p) for p in parts)


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
        not on PyPI).
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
    from .plugin import library_mismatches, missing_requirements

    target = Path(target) if target is not None else default_target()
    result = InstallResult(target=target)
    bound, wanted, notes = _plan(missing_requirements(), gistools) if requirements is None else ([], list(requirements), [])
    exe = Path(python) if python is not None else qgis_python()
    failure = None
    if wanted:
        cmd = [str(exe or "python"), "-m", "pip", "install", "--disable-pip-version-check", "--no-input",
               "--target", str(target), *wanted]
        result.installed = wanted
        failure = _run_pip(exe, cmd, target, timeout, result)
        if failure:
            notes.insert(0, f"{failure}. Run this once, then restart QGIS: {_quoted(cmd)}")
    add_to_path(target)
    if requirements is None:
        result.missing = missing_requirements()
        result.mismatches = [] if result.missing else library_mismatches()
    elif failure:
        result.missing = wanted
    if bound:
        notes.append(f"{', '.join(bound)} must be QGIS's own builds (pip's wheels bring other GDAL / PROJ / GEOS "
                     f"libraries, which crash QGIS); install them with: {_bound_command(bound)}; then restart QGIS")
    result.message = _message(result, notes)
    return result


def _plan(missing: list, gistools) -> tuple[list, list, list]:
    """(the GDAL / PROJ / GEOS bound packages missing, what pip installs, notes) of the missing requirements."""
    bound = sorted({m.split(">")[0] for m in missing} & set(BOUND))
    wanted = [m for m in missing if m.split(">")[0] not in BOUND and m != "gistools"]
    notes = []
    if "gistools" in missing and gistools is not None:
        wanted.append(str(gistools))
    elif "gistools" in missing:
        notes.append("gistools itself is not on PyPI: give its wheel, install_dependencies("
                     "gistools='path/to/gistools-<version>-py3-none-any.whl')")
    return bound, wanted, notes


def _message(result: InstallResult, notes: list) -> str:
    from .plugin import mismatch_message

    if notes:
        return "gistools: " + "; ".join(notes)
    if result.mismatches:
        return mismatch_message(result.mismatches)
    if result.missing:
        return f"gistools: still missing after the install: {', '.join(result.missing)}"
    if result.installed:
        return f"gistools: installed {', '.join(result.installed)} into {result.target}; restart QGIS"
    return "gistools: nothing to install"


def _run_pip(exe, cmd: list, target: Path, timeout: float, result: InstallResult) -> str | None:
    """Run pip (``cmd`` with the constraints file added); the reason it failed, None when it worked."""
    if exe is None or not Path(exe).is_file():
        return "QGIS's Python interpreter was not found"
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as pins:
        pins.write(_constraints())
    result.command = cmd[:4] + ["--constraint", pins.name] + cmd[4:]
    try:
        run = subprocess.run(result.command, capture_output=True, text=True, timeout=timeout)
    except (OSError, subprocess.SubprocessError) as err:
        return f"pip could not run ({err})"
    finally:
        Path(pins.name).unlink(missing_ok=True)
    if run.returncode != 0:
        lines = [line for line in (run.stderr or run.stdout).splitlines() if line.strip() and "WARNING" not in line]
        return f"pip failed ({lines[-1] if lines else f'exit status {run.returncode}'})"
    return None
