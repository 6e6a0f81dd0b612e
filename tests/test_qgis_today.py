"""gistools' outputs in today's QGIS LTR (3.44, from a Debian forky chroot: tools/qgis_chroot.sh), for what
Debian 12's QGIS 3.22 cannot open: virtual point clouds (QGIS 3.32+) and COPC layers."""

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
    from gistools.tasks.ground import GroundSettings, ground_from_tiles

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
    assert got["copc"]["valid"] and got["copc"]["points"] == one["points"]
