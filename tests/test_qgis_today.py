"""gistools in today's QGIS LTR (3.44, Python 3.14, numpy 2, from a Debian forky chroot: tools/qgis_chroot.sh): what
Debian 12's QGIS 3.22 cannot open (virtual point clouds, QGIS 3.32+, and COPC layers), and the whole plugin test
module (tests/test_qgis.py) run inside it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, SAMPLE

CHROOT = Path(os.environ.get("GISTOOLS_QGIS_CHROOT", "/var/tmp/gistools-qgis-forky"))


@pytest.fixture(scope="module")
def qgis_today():
    if os.geteuid() != 0 or not shutil.which("chroot"):
        if os.environ.get("CI"):
            pytest.fail("CI must run the QGIS 3.44 tests: they need root for the chroot")
        pytest.skip("QGIS 3.44 tests: need root to build and enter the chroot (tools/qgis_chroot.sh)")
    proc = subprocess.run(["bash", str(ROOT / "tools" / "qgis_chroot.sh"), str(CHROOT)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return CHROOT


def _is_mount(path: Path) -> bool:
    """Whether ``path`` is a mount point, a bind mount of a folder of the same file system included (which
    os.path.ismount, comparing devices, does not see): the kernel's own table."""
    try:
        table = Path("/proc/self/mounts").read_text(encoding="utf-8")
    except OSError:
        return os.path.ismount(path)
    target = str(Path(path).resolve())
    return any(line.split()[1].replace("\\040", " ") == target for line in table.splitlines() if line.split())


def _in_qgis(root: Path, code: str) -> dict:
    """Run ``code`` (which prints one JSON line last) in the chroot's QGIS, headless; its JSON."""
    proc_mounted = _is_mount(root / "proc")
    if not proc_mounted:
        subprocess.run(["mount", "-t", "proc", "proc", str(root / "proc")], check=True)
    try:
        head = ("import json\nfrom qgis.core import Qgis, QgsApplication, QgsPointCloudLayer\n"
                "app = QgsApplication([], False)\napp.initQgis()\n")
        proc = subprocess.run(["chroot", str(root), "env", "QT_QPA_PLATFORM=offscreen", "python3", "-c", head + code],
                              capture_output=True, text=True, timeout=300)
    finally:
        if not proc_mounted:
            subprocess.run(["umount", str(root / "proc")], check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_qgis_344_opens_the_vpc_and_the_copc_files_gistools_ground_writes(qgis_today):
    from gistools.products.ground import GroundSettings, ground_from_tiles

    work = qgis_today / "tmp" / "gistools-test"
    shutil.rmtree(work, ignore_errors=True)
    laz = ground_from_tiles(SAMPLE, work / "laz")
    copc = ground_from_tiles(SAMPLE, work / "copc", GroundSettings(format="copc"))
    points = sum(t["points"] for t in laz["tiles"])
    got = _in_qgis(qgis_today, """
out = {"version": Qgis.version()}
for name, path, provider in (("vpc", "/tmp/gistools-test/laz/ground.vpc", "vpc"),
                             ("vpc_copc", "/tmp/gistools-test/copc/ground.vpc", "vpc"),
                             ("copc", "/tmp/gistools-test/copc/35712.copc.laz", "copc")):
    layer = QgsPointCloudLayer(path, name, provider)
    e = layer.extent()
    out[name] = {"valid": layer.isValid(), "points": layer.pointCount(), "crs": layer.crs().authid(),
                 "extent": [e.xMinimum(), e.yMinimum(), e.xMaximum(), e.yMaximum()]}
print(json.dumps(out))
""")
    assert got["version"].startswith("3.4"), got["version"]
    for name in ("vpc", "vpc_copc"):
        assert got[name]["valid"] and got[name]["points"] == points and got[name]["crs"] == "EPSG:2882", got[name]
        w, s, e, n = got[name]["extent"]
        assert abs(w - 430000) < 10 and abs(s - 1810000) < 10 and abs(e - 432000) < 10 and abs(n - 1812000) < 10
    one = next(t for t in copc["tiles"] if t["name"] == "35712")
    assert got["copc"]["valid"] and got["copc"]["points"] == one["points"], got["copc"]
    assert got["copc"]["crs"] == "EPSG:2882", got["copc"]  # QGIS reads the CRS from a regular VLR only


_COPY_SKIP = shutil.ignore_patterns(".venv", ".git", "out", "dist", "build", "__pycache__", "*.so", "*.egg-info")


def test_the_plugin_tests_pass_in_qgis_344(qgis_today):
    """tests/test_qgis.py (every algorithm through processing.run and qgis_process, against the library) run
    inside QGIS 3.44 / Python 3.14 / numpy 2, with gistools installed from a copy of this tree into the chroot's
    venv (the GDAL / PROJ / GEOS bound packages are Debian's, built against what QGIS links)."""
    src, shared = qgis_today / "work" / "gistools", qgis_today / "work" / "shared"
    shutil.rmtree(src, ignore_errors=True)
    shutil.copytree(ROOT, src, ignore=_COPY_SKIP)
    mounted = []
    shared.mkdir(parents=True, exist_ok=True)
    if (ROOT.parent / "shared").is_dir() and not _is_mount(shared):
        subprocess.run(["mount", "--bind", "-o", "ro", str(ROOT.parent / "shared"), str(shared)], check=True)
        mounted.append(shared)
    if not _is_mount(qgis_today / "proc"):
        subprocess.run(["mount", "-t", "proc", "proc", str(qgis_today / "proc")], check=True)
        mounted.append(qgis_today / "proc")
    py = "/opt/gistools-venv/bin/python"
    env = ["env", "-u", "PIP_CONSTRAINT", "-u", "PIP_FIND_LINKS", "PIP_CERT=/etc/ssl/certs/ca-certificates.crt",
           "QT_QPA_PLATFORM=offscreen", "HOME=/root", f"CI={os.environ.get('CI', '')}"]
    try:
        install = subprocess.run(["chroot", str(qgis_today), *env, py, "-m", "pip", "install", "-q", "--no-deps",
                                  "--no-build-isolation", "--disable-pip-version-check", "-e", "/work/gistools"],
                                 capture_output=True, text=True, timeout=900)
        assert install.returncode == 0, install.stderr[-3000:]
        run = subprocess.run(["chroot", str(qgis_today), *env, "sh", "-c",
                              f"cd /work/gistools && {py} -m pytest -q -p no:cacheprovider "
                              "tests/test_qgis.py"], capture_output=True, text=True, timeout=2400)
    finally:
        for m in reversed(mounted):
            subprocess.run(["umount", str(m)], check=False)
    print(run.stdout[-3000:])
    assert run.returncode == 0, (run.stdout[-6000:], run.stderr[-3000:])
    assert " passed" in run.stdout and " skipped" not in run.stdout, run.stdout[-3000:]


BARE = Path(os.environ.get("GISTOOLS_QGIS_BARE_CHROOT", "/var/tmp/gistools-qgis-forky-bare"))


@pytest.fixture(scope="module")
def qgis_stock():
    """QGIS 3.44 as apt installs it on Debian forky, with pip: its Python has numpy, pyproj, matplotlib and GDAL's
    bindings (QGIS's own dependencies) and nothing else gistools needs."""
    if os.geteuid() != 0 or not shutil.which("chroot"):
        if os.environ.get("CI"):
            pytest.fail("CI must run the QGIS 3.44 tests: they need root for the chroot")
        pytest.skip("QGIS 3.44 tests: need root to build and enter the chroot (tools/qgis_chroot.sh --bare)")
    proc = subprocess.run(["bash", str(ROOT / "tools" / "qgis_chroot.sh"), "--bare", str(BARE)], capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return BARE


def _chroot(root: Path, *cmd, timeout=900) -> subprocess.CompletedProcess:
    """``cmd`` inside ``root`` (proc mounted meanwhile), headless, pip given the chroot's CAs and no host settings."""
    mounted = not _is_mount(root / "proc")
    if mounted:
        subprocess.run(["mount", "-t", "proc", "proc", str(root / "proc")], check=True)
    env = ["env", "-u", "PIP_CONSTRAINT", "-u", "PIP_FIND_LINKS", "-u", "PIP_INDEX_URL", "-u", "PYTHONPATH",
           "PIP_CERT=/etc/ssl/certs/ca-certificates.crt", "QT_QPA_PLATFORM=offscreen", "HOME=/root",
           "QGIS_CUSTOM_CONFIG_PATH=/work/qgis-config", "DEBIAN_FRONTEND=noninteractive"]
    try:
        return subprocess.run(["chroot", str(root), *env, *cmd], capture_output=True, text=True, timeout=timeout)
    finally:
        if mounted:
            subprocess.run(["umount", str(root / "proc")], check=False)


_SESSION = """
import json, sys
from qgis.core import QgsApplication
app = QgsApplication([], False); app.initQgis()
sys.path.insert(0, "/work/qgis-config/profiles/default/python/plugins")  # what QGIS adds for the profile's plugins
import gistools_qgis
plugin = gistools_qgis.classFactory(None)
plugin.initProcessing()
from gistools_qgis.install import install_dependencies
r = install_dependencies(gistools=WHEEL)
print(json.dumps({"profile": QgsApplication.qgisSettingsDirPath(), "missing_at_start": plugin.missing, "ok": r.ok,
                  "message": r.message, "installed": r.installed, "missing": r.missing, "mismatches": r.mismatches}))
"""


def test_a_stock_qgis_344_gets_gistools_from_the_plugin_zip_and_its_installer(qgis_today, qgis_stock, tmp_path):
    """The route of a QGIS user: the plugin zip unzipped into a fresh profile of a stock QGIS 3.44 (Python 3.14);
    the plugin's installer run from QGIS's Python (it first asks for QGIS's builds of the GDAL / PROJ / GEOS bound
    packages, by the one command it prints, then pip-installs the rest and gistools' wheel into the profile); QGIS
    restarted (qgis_process); gistools:dsm and the aquifer model equal the CLI's outputs, with the compiled kernel."""
    import geopandas as gpd
    import numpy as np
    import rasterio
    import shapely as shp
    from click.testing import CliRunner

    from gistools.aquifer.synthetic import synthetic_aquifer
    from gistools.cli.main import cli

    # gistools' wheel for Python 3.14, built where there is a compiler (the other chroot: the stock one has none)
    src, wheels = qgis_today / "work" / "gistools-wheel-src", qgis_today / "work" / "wheels"
    for folder in (src, wheels):
        shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(ROOT, src, ignore=_COPY_SKIP)
    built = _chroot(qgis_today, "/opt/gistools-venv/bin/python", "-m", "pip", "wheel", "-q", "--no-deps",
                    "--no-build-isolation", "--disable-pip-version-check", "-w", "/work/wheels", "/work/gistools-wheel-src")
    assert built.returncode == 0, built.stderr[-3000:]
    (wheel,) = wheels.glob("gistools-*.whl")
    assert "cp311-abi3" in wheel.name, wheel.name  # the stable-ABI wheel, built on 3.14, installs on every 3.11+
    work = qgis_stock / "work"
    shutil.rmtree(work, ignore_errors=True)
    (work / "wheels").mkdir(parents=True)
    shutil.copy2(wheel, work / "wheels" / wheel.name)
    stock = _chroot(qgis_stock, "sh", "-c", "apt-get remove -y -q --autoremove $(for p in python3-rasterio python3-pyogrio "
                    "python3-shapely; do dpkg -s $p >/dev/null 2>&1 && echo $p; done) </dev/null >/dev/null || true")
    assert stock.returncode == 0, stock.stderr[-2000:]  # as apt left it, before an earlier run of this test
    assert _chroot(qgis_stock, "sh", "-c", "command -v gcc cc || true").stdout.strip() == ""  # no compiler here

    # the zip into a fresh profile, as QGIS's "Install from ZIP" does
    sys.path.insert(0, str(ROOT / "tools"))
    import build_plugin

    build_plugin.install(build_plugin.build(tmp_path / "dist"), work / "qgis-config" / "profiles" / "default")
    session = _SESSION.replace("WHEEL", repr(f"/work/wheels/{wheel.name}"))

    first = _chroot(qgis_stock, "python3", "-c", session)
    assert first.returncode == 0, first.stderr[-3000:]
    said = json.loads(first.stdout.strip().splitlines()[-1])
    assert said["profile"].rstrip("/") == "/work/qgis-config/profiles/default", said
    assert {"scipy", "laspy", "rasterio", "geopandas"} <= set(said["missing_at_start"]), said
    assert not said["ok"] and said["installed"] == [], said  # nothing pip-installed while a bound package is missing
    command = said["message"].split("install them with: ", 1)[1].split(";", 1)[0]
    assert command.startswith("sudo apt-get install python3-"), said["message"]
    apt = _chroot(qgis_stock, "sh", "-c", command.replace("sudo ", "") .replace("apt-get install", "apt-get install -y -q"))
    assert apt.returncode == 0, apt.stderr[-3000:]

    second = _chroot(qgis_stock, "python3", "-c", session, timeout=1800)
    assert second.returncode == 0, second.stderr[-3000:]
    said = json.loads(second.stdout.strip().splitlines()[-1])
    assert said["ok"] and said["missing"] == [] and said["mismatches"] == [], said
    assert f"/work/wheels/{wheel.name}" in said["installed"] and "restart QGIS" in said["message"], said

    # "restart QGIS": qgis_process loads the enabled plugin from the profile; the plugin finds what was installed
    enable = _chroot(qgis_stock, "qgis_process", "plugins", "enable", "gistools_qgis")
    assert enable.returncode == 0 or "already enabled" in enable.stdout + enable.stderr, enable.stdout[-2000:] + enable.stderr[-2000:]
    tile = sorted(SAMPLE.glob("*.las"))[0]
    shutil.copytree(SAMPLE, work / "sample")
    dsm = _chroot(qgis_stock, "qgis_process", "run", "gistools:dsm", "--", f"INPUT=/work/sample/{tile.name}",
                  "CELL_SIZE=5ft", "OUTPUT_FOLDER=/work/out/dsm")
    assert dsm.returncode == 0, dsm.stdout[-3000:] + dsm.stderr[-3000:]
    points, _ = synthetic_aquifer(2012)
    gdf = gpd.GeoDataFrame(points, geometry=shp.points(points["x"], points["y"]), crs=3003)
    gdf.to_file(work / "contacts.gpkg", layer="contacts")
    aquifer = _chroot(qgis_stock, "qgis_process", "run", "gistools:aquifer", "--",
                      "INPUT=/work/contacts.gpkg|layername=contacts", "LAYERS=LS,AU,AD,AQ", "OUTPUT_FOLDER=/work/out/aquifer")
    assert aquifer.returncode == 0, aquifer.stdout[-3000:] + aquifer.stderr[-3000:]
    engine = _chroot(qgis_stock, "python3", "-c", "import sys; sys.path.append('/work/qgis-config/profiles/default/python/plugins');"
                     "from gistools_qgis.install import add_to_path; add_to_path('/work/qgis-config/profiles/default/python/gistools_deps');"
                     "from gistools import kernel; print(kernel.loaded(), kernel.engine())")
    assert engine.stdout.strip().startswith("True compiled C kernel (/work/qgis-config/"), engine.stdout + engine.stderr[-2000:]

    runner = CliRunner()
    result = runner.invoke(cli, ["rasters", str(tile), "--out", str(tmp_path / "dsm"), "--products", "dsm", "-q"])
    assert result.exit_code == 0, result.output
    gdf.to_file(tmp_path / "contacts.gpkg", layer="contacts")
    result = runner.invoke(cli, ["aquifer", "model", f"{tmp_path / 'contacts.gpkg'}|layername=contacts", "--layers",
                                 "LS,AU,AD,AQ", "--out", str(tmp_path / "aquifer"), "-q"])
    assert result.exit_code == 0, result.output
    with rasterio.open(work / "out" / "dsm" / "dsm.vrt") as a, rasterio.open(tmp_path / "dsm" / "dsm.vrt") as b:
        assert a.transform == b.transform and a.crs == b.crs
        np.testing.assert_array_equal(a.read(1), b.read(1))
    qgis_report = json.loads((work / "out" / "aquifer" / "report.json").read_text())
    cli_report = json.loads((tmp_path / "aquifer" / "report.json").read_text())
    assert qgis_report["units"].keys() == cli_report["units"].keys()
    for name, unit in cli_report["units"].items():
        assert qgis_report["units"][name]["volume"] == pytest.approx(unit["volume"], rel=1e-9), name
    for rel in cli_report["outputs"]["thickness"].values():
        got = Path(str(rel).replace(str(tmp_path / "aquifer"), str(work / "out" / "aquifer")))
        with rasterio.open(got) as a, rasterio.open(rel) as b:
            np.testing.assert_allclose(a.read(1), b.read(1), rtol=1e-9, atol=1e-9)


def test_every_command_block_runs_on_python_314_from_binary_wheels(qgis_today):
    """The pip route on today's Python (3.14, the forky chroot's): a venv without system packages, gistools from a
    copy of this tree with the newest binary wheel of every dependency (numpy 2), then every command block of the
    README and the documentation as printed, in order (tests/test_readme.py on the pip route: the Debian and QGIS
    set-up blocks are that route's own)."""
    src = qgis_today / "work" / "gistools-pip"
    shutil.rmtree(src, ignore_errors=True)
    shutil.copytree(ROOT, src, ignore=_COPY_SKIP)
    (src / "gistools").joinpath("_kernel.abi3.so").unlink(missing_ok=True)
    venv = "/opt/gistools-pip314"
    shared = qgis_today / "work" / "shared"
    shared.mkdir(parents=True, exist_ok=True)
    mounted = []
    if (ROOT.parent / "shared").is_dir() and not _is_mount(shared):
        subprocess.run(["mount", "--bind", "-o", "ro", str(ROOT.parent / "shared"), str(shared)], check=True)
        mounted.append(shared)
    try:
        made = _chroot(qgis_today, "sh", "-c", f"test -x {venv}/bin/python || python3 -m venv {venv}")
        assert made.returncode == 0, made.stderr[-2000:]
        install = _chroot(qgis_today, f"{venv}/bin/python", "-m", "pip", "install", "-q", "--disable-pip-version-check",
                          "--upgrade", "--only-binary", ":all:", "--no-binary", "gistools", "/work/gistools-pip",
                          "pytest", "pyyaml", timeout=1800)
        assert install.returncode == 0, install.stderr[-3000:]
        version = _chroot(qgis_today, f"{venv}/bin/python", "-c", "import sys, numpy; print(sys.version_info[:2], "
                          "numpy.__version__)")
        assert version.returncode == 0 and "(3, 14)" in version.stdout and " 2." in version.stdout, version.stdout
        run = _chroot(qgis_today, "sh", "-c", f"cd /work/gistools-pip && GISTOOLS_ROUTE=wheels CI={os.environ.get('CI', '')} "
                      f"{venv}/bin/python -m pytest -q -p no:cacheprovider "
                      "tests/test_readme.py::test_every_command_and_python_block_runs_as_printed", timeout=2400)
    finally:
        for m in reversed(mounted):
            subprocess.run(["umount", str(m)], check=False)
    print(run.stdout[-2000:])
    assert run.returncode == 0 and "1 passed" in run.stdout, (run.stdout[-6000:], run.stderr[-3000:])


def test_without_the_proj_command_gistools_finds_the_systems_proj_data(qgis_today):
    """Debian forky's pyproj (a system build, /opt/gistools-venv sees it) with no ``proj`` command on the PATH finds
    no PROJ data by itself (pyproj's DataDirError); gistools finds /usr/share/proj and the run completes."""
    src = qgis_today / "work" / "gistools-proj"
    shutil.rmtree(src, ignore_errors=True)
    shutil.copytree(ROOT, src, ignore=_COPY_SKIP)
    (src / "gistools" / "_kernel.abi3.so").unlink(missing_ok=True)
    env = ["env", "-i", "HOME=/root", "PATH=/opt/gistools-venv/bin", "PYTHONPATH=/work/gistools-proj"]
    mounted = not _is_mount(qgis_today / "proc")
    if mounted:
        subprocess.run(["mount", "-t", "proc", "proc", str(qgis_today / "proc")], check=True)
    try:
        alone = subprocess.run(["chroot", str(qgis_today), *env, "/opt/gistools-venv/bin/python", "-c",
                                "import pyproj; pyproj.datadir.get_data_dir()"], capture_output=True, text=True)
        run = subprocess.run(["chroot", str(qgis_today), *env, "/opt/gistools-venv/bin/python", "-m",
                              "gistools.cli.main", "rasters", "/work/gistools-proj/sample_tiles", "--out",
                              "/tmp/gistools-proj-out", "--overwrite", "-q"], capture_output=True, text=True,
                             timeout=900)
    finally:
        if mounted:
            subprocess.run(["umount", str(qgis_today / "proc")], check=False)
    assert alone.returncode != 0 and "DataDirError" in alone.stderr  # the set-up of the fault: pyproj alone fails
    assert run.returncode == 0 and "4 tiles ok" in run.stdout, run.stdout + run.stderr[-3000:]
    assert "proj.db" not in run.stderr and "CRS" not in run.stderr, run.stderr[-2000:]
