"""The README's Python example runs as printed, as a script, in a folder holding a copy of sample_tiles/."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT, SAMPLE


def test_the_readme_python_example_runs_as_a_script(tmp_path):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python\n"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    shutil.copytree(SAMPLE, tmp_path / "sample_tiles")
    (tmp_path / "example.py").write_text(code)
    proc = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "{'ok': 4, 'failed': 0, 'skipped': 0}" in proc.stdout
    assert "Traceback" not in proc.stderr and "forked" not in proc.stderr  # the guard lets the workers spawn


_COPY_SKIP = shutil.ignore_patterns(".venv", ".git", "out", "dist", "build", "__pycache__", "*.egg-info")
# the one README command not run here: it is the test suite itself (.ci/run runs it)
_NOT_HERE = ("bash tools/run.sh test",)


def _bash_blocks(text: str) -> list[str]:
    """The ```bash blocks, list-item indented ones dedented."""
    import textwrap

    return [textwrap.dedent(body) for _, body in re.findall(r"^( *)```bash\n(.*?)^\1```", text, re.S | re.M)]


def test_every_readme_command_block_runs_as_printed(tmp_path):
    """Each ```bash block of the README, in order, in a copy of this checkout (its .venv linked, so run.sh finds
    it set up) to which `gistools examples .` added the example inputs; HOME is a fresh folder (the plugin
    block installs into ~/.local/share/QGIS). A block that fails names itself and its output."""
    import os

    stamp = ROOT / ".venv" / ".gistools-installed"
    inputs = b"".join((ROOT / f).read_bytes() for f in ("pyproject.toml", "setup.py", "gistools/lidar/_tinkernel.c",
                                                         "tools/constraints-debian12.txt")) + b"wheels=0\n"
    import hashlib

    if not stamp.exists() or stamp.read_text().strip() != hashlib.sha256(inputs).hexdigest()[:16]:
        pytest.fail("the .venv is not set up for this checkout: run `bash tools/run.sh test` (the README's command), "
                    "so that the copy's run.sh does not reinstall gistools into it")
    work = tmp_path / "checkout"
    shutil.copytree(ROOT, work, ignore=_COPY_SKIP)
    (work / ".venv").symlink_to(ROOT / ".venv")
    home = tmp_path / "home"
    home.mkdir()
    venv_bin = ROOT / ".venv" / "bin"
    shims = tmp_path / "shims"  # the README is written for a user with sudo; as root without it, sudo runs the command
    shims.mkdir()
    if os.geteuid() == 0 and not shutil.which("sudo"):
        (shims / "sudo").write_text('#!/bin/sh\nexec "$@"\n')
        (shims / "sudo").chmod(0o755)
    env = {**os.environ, "HOME": str(home), "PATH": f"{venv_bin}:{shims}:{os.environ['PATH']}", "QT_QPA_PLATFORM": "offscreen"}
    env.pop("PIP_CONSTRAINT", None)  # run.sh's: the blocks say which constraints they use
    prep = subprocess.run(["gistools", "examples", "."], cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert prep.returncode == 0, prep.stderr[-2000:]
    blocks = _bash_blocks((ROOT / "README.md").read_text())
    assert len(blocks) >= 9
    for i, block in enumerate(blocks, 1):
        lines = [ln for ln in block.splitlines() if not any(ln.strip().startswith(s) for s in _NOT_HERE)]
        proc = subprocess.run(["bash", "-euo", "pipefail", "-c", "\n".join(lines)], cwd=work, env=env,
                              capture_output=True, text=True, timeout=1800)
        assert proc.returncode == 0, f"README bash block {i} failed:\n{block}\n{proc.stdout[-1500:]}\n{proc.stderr[-2500:]}"
        assert "Traceback" not in proc.stderr, f"README bash block {i}:\n{proc.stderr[-2500:]}"
    # the model example as printed: every output where it was given, with the CLI's road and water classes (the
    # cell-by-cell equality with gistools shrub is tests/test_qgis.py's) and its class polygons
    import geopandas as gpd
    import numpy as np
    import rasterio

    model = work / "out" / "qgis_model"
    assert sorted(p.name for p in model.iterdir() if not p.name.endswith((".aux.xml", ".qml"))) == [
        "classes.tif", "cover.tif", "shrub_classes.gpkg", "wetveg.tif"]
    with rasterio.open(model / "classes.tif") as src:
        codes = set(np.unique(src.read(1)).tolist())
    assert {0, 1, 2, 3, 4, 5} <= codes
    assert len(gpd.read_file(model / "shrub_classes.gpkg")) > 0


def test_the_python_example_after_the_command_blocks_speaks_python(tmp_path):
    """Run after the command blocks (which made out/ with 5 ft cells), the example's 1 m call into the same folder
    is refused by the library, and its message names the Python argument (overwrite=True), never a flag."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python\n"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    shutil.copytree(SAMPLE, tmp_path / "sample_tiles")
    first = subprocess.run([sys.executable, "-m", "gistools.cli.main", "rasters", "sample_tiles", "--out", "out", "-q"],
                           cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stderr
    (tmp_path / "example.py").write_text(code)
    proc = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        last = proc.stderr.strip().splitlines()[-1]
        assert "overwrite=True" in last and "--" not in last, last
