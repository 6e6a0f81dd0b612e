"""The plugin's dependency installer (qgis_plugin/install.py), lightly: a real pip run with QGIS's Python into a
profile folder (a local wheel, no network), the packages it must never pip-install, and the one command it gives
when it cannot install. (Installing the whole set into a fresh QGIS is the chroot's business, not run here.)"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

qgis_core = pytest.importorskip("qgis.core")

from qgis_plugin import install  # noqa: E402


def _wheel(folder: Path, name: str = "gistools_probe", version: str = "1.0") -> Path:
    """A minimal pure-Python wheel (PEP 427 layout) holding ``name/__init__.py``."""
    path = folder / f"{name}-{version}-py3-none-any.whl"
    info = f"{name}-{version}.dist-info"
    files = {f"{name}/__init__.py": "VALUE = 42\n",
             f"{info}/METADATA": f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n",
             f"{info}/WHEEL": "Wheel-Version: 1.0\nGenerator: gistools-tests\nRoot-Is-Purelib: true\nTag: py3-none-any\n"}
    files[f"{info}/RECORD"] = "".join(f"{k},,\n" for k in files) + f"{info}/RECORD,,\n"
    with zipfile.ZipFile(path, "w") as z:
        for k, v in files.items():
            z.writestr(k, v)
    return path


def test_the_interpreter_found_is_this_pythons_version():
    exe = install.qgis_python()
    assert exe is not None and install._version_of(exe) == f"{sys.version_info.major}.{sys.version_info.minor}"


@pytest.mark.parametrize("layout", ["macos", "windows"])
def test_the_interpreter_is_found_without_starting_qgis(tmp_path, monkeypatch, layout):
    """Inside QGIS on macOS and Windows, sys.executable is QGIS's own binary: it is never run (here a program that
    leaves a mark); the bundle's bin/python3 (macOS) or the installer's apps/Python3x/python.exe (the prefix,
    Windows) is found instead. The layouts are imitated with this Python under those names."""
    mark = tmp_path / "QGIS-STARTED"
    if layout == "macos":
        macos = tmp_path / "QGIS.app" / "Contents" / "MacOS"
        qgis, prefix, python = macos / "QGIS", tmp_path / "QGIS.app" / "Contents" / "Frameworks", macos / "bin" / "python3"
    else:
        root = tmp_path / "QGIS 3.44"
        qgis, prefix = root / "bin" / "qgis-bin.exe", root / "apps" / "Python312"
        python = prefix / ("python.exe" if install.os.name == "nt" else "python3")
    for folder in (qgis.parent, prefix, python.parent):
        folder.mkdir(parents=True, exist_ok=True)
    qgis.write_text(f"#!/bin/sh\ntouch '{mark}'\n")
    qgis.chmod(0o755)
    python.symlink_to(sys.executable)
    for name in ("executable",):
        monkeypatch.setattr(sys, name, str(qgis))
    for name in ("prefix", "base_prefix", "exec_prefix"):
        monkeypatch.setattr(sys, name, str(prefix))
    assert install.qgis_python() == python
    assert not mark.exists(), "QGIS's binary was run"


def test_pip_installs_into_the_profile_folder_which_goes_last_on_the_path(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "path", list(sys.path))
    target = tmp_path / "profile" / "python" / install.DEPS_FOLDER
    result = install.install_dependencies(target, requirements=[str(_wheel(tmp_path))])
    assert result.ok and result.missing == [], result.message
    assert "--prefix" in result.command and str(target) in result.command and "--no-deps" in result.command
    site = install.site_folders(target)
    assert len(site) == 1 and site[0].is_relative_to(target) and sys.path[-1] == str(site[0])
    import gistools_probe

    assert gistools_probe.VALUE == 42 and Path(gistools_probe.__file__).parent.parent == site[0]
    sys.modules.pop("gistools_probe", None)


def test_a_gdal_bound_wheel_that_fails_its_trial_is_not_installed_and_nothing_is_while_one_is_missing(tmp_path,
                                                                                                      monkeypatch):
    # pip would fetch rasterio's wheel (its own GDAL) as a dependency of gistools: nothing is installed until QGIS's
    # build is there or the wheel passed its trial (here it cannot: this Python's own rasterio comes first)
    for name in ("laspy", "rasterio"):  # as if QGIS's Python lacked them
        monkeypatch.setitem(sys.modules, name, None)
    target = tmp_path / install.DEPS_FOLDER
    result = install.install_dependencies(target, python=sys.executable)
    assert not result.ok and "laspy" in result.missing and "rasterio" in result.missing
    assert result.installed == [] and result.command == [] and not target.exists()
    assert "pip's binary wheel of rasterio failed the trial" in result.message
    assert ("rasterio should be QGIS's own builds" in result.message
            and "sudo apt-get install python3-rasterio; then run install_dependencies() again (it installs laspy)"
            in result.message), result.message
    assert "\n" not in result.message


def test_when_pip_cannot_run_the_message_is_the_one_command(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "laspy", None)
    target = tmp_path / install.DEPS_FOLDER
    result = install.install_dependencies(target, python=tmp_path / "no-python")
    assert not result.ok and result.missing == ["laspy"] and result.installed == ["laspy"] and result.command == []
    assert result.message.endswith(f"Run this once, then restart QGIS: {tmp_path / 'no-python'} -I -m pip install "
                                   f"--disable-pip-version-check --no-input --prefix {target} laspy"), result.message
    assert "\n" not in result.message


def test_a_pip_planted_in_the_folder_qgis_started_from_or_on_pythonpath_never_runs(tmp_path, monkeypatch):
    """A ``pip/__main__.py`` in the current folder (QGIS started from a downloads folder) or on PYTHONPATH: pip runs
    isolated (-I) in a folder of its own, so the real pip installs and the planted one runs nothing."""
    for place in ("cwd", "pythonpath"):
        planted = tmp_path / place / "pip"
        planted.mkdir(parents=True)
        marker = tmp_path / f"PWNED-{place}"
        (planted / "__init__.py").write_text("")
        (planted / "__main__.py").write_text(f"open({str(marker)!r}, 'w').write('ran')\n")
    monkeypatch.chdir(tmp_path / "cwd")
    monkeypatch.setenv("PYTHONPATH", str(tmp_path / "pythonpath"))
    monkeypatch.setattr(sys, "path", list(sys.path))
    target = tmp_path / install.DEPS_FOLDER
    result = install.install_dependencies(target, requirements=[str(_wheel(tmp_path))])
    assert result.ok, result.message
    assert not (tmp_path / "PWNED-cwd").exists() and not (tmp_path / "PWNED-pythonpath").exists()
    assert result.command[1:4] == ["-I", "-m", "pip"]
    sys.modules.pop("gistools_probe", None)


def test_the_command_to_paste_quotes_a_hostile_wheel_name_so_the_shell_runs_nothing(tmp_path, monkeypatch):
    """pip cannot run; the message's command, pasted into a shell, passes the wheel's name as one word: a name
    holding ``$(touch PWNED)`` or quotes runs nothing (the shell is asked to echo the words back)."""
    import shlex
    import subprocess

    monkeypatch.setitem(sys.modules, "gistools", None)
    monkeypatch.setattr(install, "_plan", lambda missing, given: ([], [str(given)], []))
    wheel = tmp_path / "gistools-1.0-py3-none-any$(touch PWNED)'\"`touch PWNED2`.whl"
    target = tmp_path / install.DEPS_FOLDER
    result = install.install_dependencies(target, gistools=wheel, python=tmp_path / "no-python")
    command = result.message.split("Run this once, then restart QGIS: ", 1)[1]
    run = subprocess.run(["sh", "-c", "printf '%s\\n' " + command], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0 and not (tmp_path / "PWNED").exists() and not (tmp_path / "PWNED2").exists()
    assert run.stdout.splitlines() == shlex.split(command) and run.stdout.splitlines()[-1] == str(wheel)


def test_the_plugin_puts_the_profiles_folder_on_the_path_when_it_starts(tmp_path):
    """A QGIS started on a profile whose python/gistools_deps holds a package: the plugin's start adds that folder
    after QGIS's own packages, so what install_dependencies put there imports."""
    import os
    import subprocess

    from conftest import ROOT

    profile = tmp_path / "profiles" / "default"
    deps = profile / "python" / install.DEPS_FOLDER / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    (deps / "gistools_probe").mkdir(parents=True)
    (deps / "gistools_probe" / "__init__.py").write_text("VALUE = 7\n")
    script = f"""
import os
import subprocess
import sys
sys.path.insert(0, {str(ROOT)!r})
from qgis.core import QgsApplication
app = QgsApplication([], False, {str(profile)!r}); app.initQgis()
import qgis_plugin
plugin = qgis_plugin.classFactory(None)
plugin.initProcessing()
import gistools_probe
print("DEPS", sys.path.index({str(deps)!r}) == len(sys.path) - 1, gistools_probe.VALUE, plugin.provider is not None)
plugin.unload()
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert "DEPS True 7 True" in run.stdout, run.stdout + run.stderr[-3000:]


def test_a_binary_wheel_of_a_gdal_bound_package_is_refused_before_it_is_imported(tmp_path, monkeypatch):
    """QGIS on another Linux with a pip venv on its path: shapely's wheel (its own GEOS in shapely.libs) would be
    loaded into QGIS's process by any import and crash it on exit. The plugin finds the wheel from its files and
    refuses before anything imports it."""
    from qgis_plugin import plugin

    site = tmp_path / "site"
    (site / "shapely").mkdir(parents=True)
    (site / "shapely" / "__init__.py").write_text("raise RuntimeError('imported')\n", encoding="utf-8")
    (site / "shapely.libs").mkdir()
    (site / "shapely.libs" / "libgeos-0123abcd.so.3.14.1").write_bytes(b"\x7fELF")
    monkeypatch.syspath_prepend(str(site))
    for name in list(sys.modules):
        if name == "shapely" or name.startswith("shapely."):
            monkeypatch.delitem(sys.modules, name)
    found = plugin.bundled_before_import()
    assert found == ["shapely carries its own libraries (shapely.libs, a binary wheel)"], found
    assert "shapely" not in sys.modules  # found from the files: nothing imported
    started = plugin.GistoolsPlugin()
    started.initProcessing()
    assert started.provider is None and started.mismatches == found and "shapely" not in sys.modules


def test_gistools_comes_from_the_zips_wheels_where_none_is_given(tmp_path, monkeypatch):
    """Without a wheel given, gistools is taken from the plugin's wheels/ folder (pip picks this platform's wheel
    of it, else the pure one); with neither, the message says how to give one."""
    monkeypatch.setattr(install.importlib.util, "find_spec", lambda name, *a: None if name == "gistools" else True)
    monkeypatch.setattr(install, "WHEELS", tmp_path / "wheels")
    bound, wanted, notes = install._plan(["gistools"], None)
    assert wanted == [] and "give its wheel" in notes[0]
    (tmp_path / "wheels").mkdir()
    _wheel(tmp_path / "wheels", "gistools", "0.1.0")
    bound, wanted, notes = install._plan(["gistools"], None)
    assert bound == [] and wanted == ["gistools"] and notes == []


def test_the_engine_note_names_the_numpy_engine_where_the_kernel_is_missing(monkeypatch):
    from gistools import kernel

    monkeypatch.setattr(kernel, "loaded", lambda: False)
    assert "numpy engine" in install._engine_note()
    monkeypatch.setattr(kernel, "loaded", lambda: True)
    assert install._engine_note() == ""


def test_the_zips_wheel_for_this_platform_is_taken_never_an_index_one(tmp_path, monkeypatch):
    """pip (this Python's) picks from the plugin's wheels/ alone: the pure wheel where the folder's platform wheel
    is another system's; an index's distribution of the same name (PyPI has an unrelated gistools 1.2) is never
    asked for (--no-index), so nothing is chosen where no wheel of the folder fits."""
    wheels = tmp_path / "wheels"
    wheels.mkdir()
    monkeypatch.setattr(install, "WHEELS", wheels)
    other = _wheel(wheels, "gistools", "0.1.0").rename(wheels / "gistools-0.1.0-cp311-abi3-win_arm64.whl")
    assert install._zip_wheel(sys.executable, 120) is None  # only another system's wheel: none fits
    pure = _wheel(wheels, "gistools", "0.1.0")
    chosen = install._zip_wheel(sys.executable, 120)
    assert chosen is not None and Path(chosen) == pure and Path(chosen) != other


def _shapely_wheel_on_path(tmp_path, monkeypatch) -> None:
    """A shapely 2.2.0 binary wheel's files first on the path (its own GEOS in shapely.libs); importing it raises."""
    site = tmp_path / "site"
    (site / "shapely").mkdir(parents=True)
    (site / "shapely" / "__init__.py").write_text("raise RuntimeError('imported')\n", encoding="utf-8")
    (site / "shapely.libs").mkdir()
    (site / "shapely.libs" / "libgeos-0123abcd.so.3.14.1").write_bytes(b"\x7fELF")
    (site / "shapely-2.2.0.dist-info").mkdir()
    monkeypatch.syspath_prepend(str(site))
    for name in list(sys.modules):
        if name == "shapely" or name.startswith("shapely."):
            monkeypatch.delitem(sys.modules, name)


# Debian's QGIS runs in the system's Python (this venv's base); it has no shapely, pyogrio or rasterio of its own
QGIS_PYTHON = Path(sys.base_prefix) / "bin" / f"python{sys.version_info.major}.{sys.version_info.minor}"
_IMPORTED = """
import os, sys, tempfile
from qgis.core import QgsApplication, QgsGeometry, QgsVectorLayer
app = QgsApplication([], False)
app.initQgis()
sys.path.append(sys.argv[1])
module = __import__(sys.argv[2])
print(module.__file__.startswith(sys.argv[1]), flush=True)
ours = QgsGeometry.fromWkt("POINT (0 0)").buffer(1.0, 8)
if sys.argv[2] == "shapely":  # a geometry from QGIS to the wheel
    print(abs(module.from_wkb(bytes(ours.asWkb())).area - ours.area()) < 1e-12, flush=True)
else:  # a GeoPackage from the wheel to QGIS, as a gistools run writes its outputs and QGIS loads them
    import numpy as np
    import pyogrio.raw
    path = os.path.join(tempfile.mkdtemp(), "out.gpkg")
    pyogrio.raw.write(path, geometry=np.array([bytes(ours.asWkb())], dtype=object), field_data=[], fields=[],
                      layer="out", driver="GPKG", geometry_type="Polygon", crs="EPSG:26910")
    layer = QgsVectorLayer(path + "|layername=out", "out", "ogr")  # loaded until QGIS ends, as an output is
    print(layer.featureCount() == 1, flush=True)
app.exitQgis()
"""


def _qgis_python_lacks(*packages) -> bool:
    if not QGIS_PYTHON.is_file():
        return False
    probe = ("import importlib.util as u, qgis.core; print(all(u.find_spec(p) is None for p in %r))" % (packages,))
    run = subprocess.run([str(QGIS_PYTHON), "-c", probe], capture_output=True, text=True, timeout=120)
    return run.stdout.strip() == "True"


@pytest.mark.skipif(not _qgis_python_lacks("shapely", "pyogrio"), reason="needs Debian's QGIS Python without them")
def test_a_binary_wheel_is_tried_in_a_qgis_process_and_the_verdict_is_what_qgis_does_with_it(tmp_path):
    """pip's binary wheels of shapely and pyogrio (their own GEOS / GDAL), tried by the installer's last resort in
    a QGIS process of their own: each verdict agrees with what a separate QGIS process does with the same wheel
    (it imports it, exchanges a polygon with QGIS, ends QGIS): shapely's passes, a wheel whose process crashes is
    refused with the signal."""
    from qgis_plugin import bound

    site = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--only-binary", ":all:",
                          "--target", str(site), "shapely==2.2.0", "pyogrio==0.13.0"], capture_output=True, text=True,
                         timeout=600)
    assert pip.returncode == 0, pip.stderr[-2000:]
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    for name in ("shapely", "pyogrio"):
        verdict = bound.trial(QGIS_PYTHON, site, [name], path=[])
        alone = subprocess.run([str(QGIS_PYTHON), "-c", _IMPORTED, str(site), name], capture_output=True, text=True,
                               timeout=300, env=env, cwd=str(tmp_path))
        assert alone.stdout.split()[:1] == ["True"], alone.stdout + alone.stderr[-2000:]  # the wheel's own copy
        assert (verdict is None) == (alone.returncode == 0 and "False" not in alone.stdout), (name, verdict, alone)
        if alone.returncode < 0:
            assert f"crashed (signal {-alone.returncode})" in verdict
    assert bound.trial(QGIS_PYTHON, site, ["shapely"], path=[]) is None


@pytest.mark.skipif(not _qgis_python_lacks("shapely", "pyogrio"), reason="needs Debian's QGIS Python without them")
def test_the_installer_installs_only_the_bound_wheels_that_pass_the_trial_and_says_which(tmp_path):
    """install_dependencies' last resort for the GDAL / GEOS bound packages QGIS's Python lacks, run by that Python
    inside QGIS (no OSGeo4W here): the newest wheels fetched, tried alone and together; each either passes (its
    version returned for the install) or is named with the reason, never both."""
    script = ("import json, sys; from pathlib import Path; sys.path.insert(0, sys.argv[1])\n"
              "from qgis.core import QgsApplication\napp = QgsApplication([], False)\napp.initQgis()\n"
              "from qgis_plugin import install\nnotes = []\n"
              "left, versions = install._bound_builds(['pyogrio', 'shapely'], Path(sys.executable), 900, notes)\n"
              "print(json.dumps([left, versions, notes]), flush=True)\napp.exitQgis()\n")
    run = subprocess.run([str(QGIS_PYTHON), "-c", script, str(Path(__file__).resolve().parents[1])],
                         capture_output=True, text=True, timeout=1800, cwd=str(tmp_path),
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    import json

    left, versions, notes = json.loads(run.stdout.strip().splitlines()[-1])
    assert sorted(left + list(versions)) == ["pyogrio", "shapely"] and not set(left) & set(versions), run.stdout
    assert "shapely" in versions and versions["shapely"].split(".")[0] >= "2", notes
    for name in left:
        assert any(note.startswith(f"pip's binary wheel of {name} failed the trial") for note in notes), notes
    assert any("installed after a QGIS process with them gave QGIS's answers" in note for note in notes), notes


def test_a_wheel_that_passed_the_trial_is_let_through_in_the_version_tried_only(tmp_path, monkeypatch):
    """The plugin's start refuses a GDAL / GEOS bound binary wheel before importing it, unless the profile's record
    says that this version passed the trial in this QGIS and Python; another version is refused again."""
    from qgis_plugin import bound, plugin

    _shapely_wheel_on_path(tmp_path, monkeypatch)
    profile = tmp_path / "profile"
    refused = ["shapely carries its own libraries (shapely.libs, a binary wheel)"]
    assert plugin.bundled_before_import(profile) == refused
    bound.record(profile, {"shapely": "2.2.0"})
    assert plugin.bundled_before_import(profile) == []
    bound.record(profile, {"shapely": "2.1.0"})
    assert plugin.bundled_before_import(profile) == refused
    assert "shapely" not in sys.modules


_SETUP = """#!{python}
# OSGeo4W's setup, imitated: with the unattended flags it adds python3-<name> packages to --root's Python
import sys
from pathlib import Path
args = sys.argv[1:]
assert {{"--quiet-mode", "--autoaccept", "--advanced"}} <= set(args), args
root = Path(args[args.index("--root") + 1])
assert args[args.index("--site") + 1] == "https://download.osgeo.org/osgeo4w/v2/"
for package in args[args.index("--packages") + 1].split(","):
    name = package.removeprefix("python3-")
    (root / "apps" / "Python311" / "Lib" / "site-packages" / name).mkdir(parents=True)
    (root / "apps" / "Python311" / "Lib" / "site-packages" / name / "__init__.py").write_text("", encoding="utf-8")
"""


def test_where_qgis_came_from_osgeo4w_its_setup_adds_the_bound_packages_unattended(tmp_path, monkeypatch):
    """QGIS installed with OSGeo4W (imitated: its root's etc/setup, its Python in apps/Python311, its setup program
    in bin): the bound packages QGIS's Python lacks are added by that setup, unattended, as python3-<name>, and the
    note says so; nothing is fetched from pip for them."""
    import importlib.machinery

    root = tmp_path / "OSGeo4W"
    (root / "etc" / "setup").mkdir(parents=True)
    site = root / "apps" / "Python311" / "Lib" / "site-packages"
    site.mkdir(parents=True)
    setup = root / "bin" / "osgeo4w-setup.exe"
    setup.parent.mkdir()
    setup.write_text(_SETUP.format(python=sys.executable), encoding="utf-8")
    setup.chmod(0o755)
    monkeypatch.setattr(sys, "prefix", str(root / "apps" / "Python311"))
    monkeypatch.setattr(install.importlib.util, "find_spec",
                        lambda name, *a: importlib.machinery.PathFinder.find_spec(name, [str(site)]))
    notes = []
    left, versions = install._bound_builds(["pyogrio", "rasterio"], Path(sys.executable), 300, notes)
    assert left == [] and versions == {} and (site / "rasterio" / "__init__.py").is_file()
    assert notes == ["installed OSGeo4W's pyogrio, rasterio (QGIS's own builds) with its setup"]


def test_a_wheel_installed_but_not_tried_in_this_qgis_is_tried_again_never_imported(tmp_path, monkeypatch):
    """After a QGIS update the record no longer covers an installed binary wheel: install_dependencies() takes it
    for a trial in its installed version, and finding what is missing does not import it."""
    import json

    _shapely_wheel_on_path(tmp_path, monkeypatch)
    profile = tmp_path / "profile"
    profile.mkdir()
    (profile / "gistools_checked.json").write_text(json.dumps({"qgis": "3.0.0-Girona", "python": "%d.%d" %
                                                              sys.version_info[:2], "packages": {"shapely": "2.2.0"}}),
                                                  encoding="utf-8")
    untried, bound, _wanted, _notes = install._what_to_install(profile, None, None)
    assert untried == {"shapely": "2.2.0"} and "shapely" in bound
    assert "shapely" not in sys.modules
