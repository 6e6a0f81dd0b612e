"""gistools in today's QGIS LTR (3.44, Python 3.14, numpy 2, from a Debian forky chroot: tools/qgis_chroot.sh): what
Debian 12's QGIS 3.22 cannot open (virtual point clouds, QGIS 3.32+, and COPC layers), and the whole plugin test
module (tests/test_qgis.py) run inside it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
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


def _in_qgis(root: Path, code: str) -> dict:
    """Run ``code`` (which prints one JSON line last) in the chroot's QGIS, headless; its JSON."""
    proc_mounted = os.path.ismount(root / "proc")
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
    if (ROOT.parent / "shared").is_dir() and not os.path.ismount(shared):
        subprocess.run(["mount", "--bind", "-o", "ro", str(ROOT.parent / "shared"), str(shared)], check=True)
        mounted.append(shared)
    if not os.path.ismount(qgis_today / "proc"):
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
