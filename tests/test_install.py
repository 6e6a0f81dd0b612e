"""The pip route of the install page: a fresh virtual environment (no system packages), every dependency as a
binary wheel from PyPI, gistools built from the source with its compiled kernel, then gistools rasters on the
sample, cell for cell the rasters of this checkout's set-up (the system-library build)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
import rasterio

from conftest import ROOT, SAMPLE


def _pypi_reachable() -> bool:
    import urllib.request

    try:
        urllib.request.urlopen("https://pypi.org/simple/cffi/", timeout=10)
        return True
    except OSError:
        return False


def test_pip_installs_from_binary_wheels_with_the_kernel_and_makes_the_same_rasters(tmp_path, sample_run):
    if not _pypi_reachable():
        if os.environ.get("CI"):
            pytest.fail("CI must test the pip route: PyPI is not reachable")
        pytest.skip("PyPI is not reachable here")
    source = tmp_path / "source"  # a copy: pip builds in the tree it is given
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(".venv", ".git", "out", "dist", "build", "site",
                                                                  "__pycache__", "*.so", "*.egg-info"))
    venv = tmp_path / "venv"
    env = {k: v for k, v in os.environ.items() if not k.startswith("PIP_") and k != "PYTHONPATH"}
    started = time.perf_counter()
    subprocess.run([os.path.join(sys.base_prefix, "bin", "python3"), "-m", "venv", str(venv)],
                   check=True, env=env)
    python = venv / "bin" / "python"
    install = subprocess.run([str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                              "--only-binary", ":all:", "--no-binary", "gistools", str(source)],
                             capture_output=True, text=True, env=env, timeout=1200)
    assert install.returncode == 0, install.stderr[-3000:]
    seconds = time.perf_counter() - started
    print(f"pip install into a fresh venv: {seconds:.0f} s")
    gistools = venv / "bin" / "gistools"
    version = subprocess.run([str(gistools), "--version"], capture_output=True, text=True, env=env, check=True).stdout
    assert "engine: compiled C kernel" in version, version
    assert str(venv) in version  # the venv's own build, not this checkout's
    out = tmp_path / "out"
    run = subprocess.run([str(gistools), "rasters", str(SAMPLE), "--out", str(out), "-q"], capture_output=True, text=True,
                         env=env, timeout=600)
    assert run.returncode == 0 and "4 tiles ok" in run.stdout, run.stdout + run.stderr
    reference, _ = sample_run
    for product in ("dsm", "dem", "ndsm"):
        for tif in sorted((reference / product).glob("*.tif")):
            with rasterio.open(tif) as a, rasterio.open(out / product / tif.name) as b:
                assert a.transform == b.transform and a.crs == b.crs
                assert np.array_equal(a.read(1), b.read(1), equal_nan=True), tif.name
