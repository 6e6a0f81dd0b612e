"""Every command and Python block of the README and of the documentation pages (docs/, in the order of mkdocs.yml's
nav) runs as printed, in order, in one folder: a copy of the checkout to which `gistools examples .` added the
example inputs. Every fenced block is either run or listed here as not run, with the reason. The benchmark
commands of docs/performance.md run as printed with GISTOOLS_BENCH_SMOKE=1 in the environment: each benchmark then
runs its code path end to end on a tiny problem (benchmarks/_smoke.py), in seconds."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from conftest import ROOT, SAMPLE
from test_remote import BOX, server  # noqa: F401 - the loopback service that docs/area.md's route reads

# blocks not run here, by (page, first line): the reason. A reason starting with "repeats" names the page whose
# block of the same text is run.
_NOT_RUN = {
    ("docs/install.md", "python3 -m venv ~/gistools-venv"):
        "makes a second environment and downloads every dependency (network); tests/test_install.py runs this pip "
        "route in a fresh venv and checks its kernel and its rasters; the blocks here run in the one `bash tools/run.sh` "
        "made",
    ("docs/install.md", r"py -m venv %USERPROFILE%\gistools-venv"): "Windows commands",
    ("docs/install.md", "bash tools/run.sh sample   # set up .venv and run the shrub chain on sample_tiles/: map, "
                        "polygons and rasters in out/"): "repeats README.md",
    ("docs/quickstart.md", "gistools info tiles                              # CRS, units, points by class and "
                           "return: check before a long run"): "repeats README.md",
    ("docs/qgis.md", "from gistools_qgis.install import install_dependencies"):
        "runs in QGIS's Python console and installs packages (network, minutes); tests/test_qgis_today.py runs it in a stock QGIS 3.44",
}
# The route the suite runs on (tools/run.sh test runs each): "debian", the project's .venv beside Debian's QGIS;
# "wheels", a plain venv of the newest binary wheels (numpy 2) with `pip install .`, as most users install. On the
# wheels route the blocks of the Debian route and of QGIS are not run (they run on the Debian route), every other
# block is.
ROUTE = os.environ.get("GISTOOLS_ROUTE", "debian")
_NOT_ON_ROUTE = {
    "wheels": {
        ("README.md", "bash tools/run.sh sample   # set up .venv and run the shrub chain on sample_tiles/: map, "
                      "polygons and rasters in out/"):
            "the Debian route's set-up (apt-get, its own .venv); this route installed with pip",
        ("docs/qgis.md", "sudo apt-get install --no-install-recommends python3-pip python3-dev build-essential "
                         "pkg-config \\"): "Debian's QGIS route",
        ("docs/qgis.md", "python tools/build_plugin.py                    # -> dist/gistools_qgis-0.1.0.zip"):
            "QGIS's route (the plugin's zip with its documentation: the Debian route builds it)",
        ("docs/qgis.md", "# qgis_process runs the system Python: give it the venv's packages and this checkout (the "
                         "library)"): "Debian's QGIS route (qgis_process)",
    },
}
# lines of run blocks not run here: the test suite itself (this test is part of it)
_NOT_HERE = ("bash tools/run.sh test",)
_RUN = ("bash", "python")  # ```text blocks are console output or commands shown, never run
_SMOKE = {"GISTOOLS_BENCH_SMOKE": "1"}  # the benchmarks run their tiny problem (benchmarks/_smoke.py)
_FENCE = re.compile(r"^( *)```([\w+-]*)[^\n]*\n(.*?)^\1```[ \t]*$", re.S | re.M)
_COPY_SKIP = shutil.ignore_patterns(".venv", ".git", "out", "dist", "build", "site", "__pycache__", "*.egg-info")


def _pages() -> list[str]:
    """README.md, then the pages of mkdocs.yml's nav in their order (paths from the checkout's root)."""
    import yaml

    def walk(node):
        if isinstance(node, str):
            yield node
        elif isinstance(node, list):
            for item in node:
                yield from walk(item)
        elif isinstance(node, dict):
            for value in node.values():
                yield from walk(value)

    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]
    return ["README.md"] + [f"docs/{page}" for page in walk(nav) if page.endswith(".md")]


def _blocks() -> list[tuple[str, int, str, str]]:
    """Every fenced block of the pages in order: (page, its number on the page, language, text; list items
    dedented)."""
    found = []
    for page in _pages():
        for n, (_, lang, body) in enumerate(_FENCE.findall((ROOT / page).read_text()), 1):
            found.append((page, n, lang, textwrap.dedent(body)))
    return found


def _first_line(text: str) -> str:
    return next((ln for ln in text.splitlines() if ln.strip()), "")


def _to_run(route: str = "debian") -> list[tuple[str, int, str, str]]:
    skip = {**_NOT_RUN, **_NOT_ON_ROUTE.get(route, {})}
    return [b for b in _blocks() if b[2] in _RUN and (b[0], _first_line(b[3])) not in skip]


def test_every_fenced_block_is_run_or_listed_with_a_reason():
    blocks = _blocks()
    assert {p for p, *_ in blocks} >= {"README.md", "docs/quickstart.md", "docs/commands/shrub.md", "docs/python.md"}
    ran = {text for _, _, lang, text in _to_run()}
    unlisted = []
    for page, n, lang, text in blocks:
        key = (page, _first_line(text))
        if key in _NOT_RUN:
            reason = _NOT_RUN[key]
            if reason.startswith("repeats"):  # the same text must run where it is said to
                assert text in ran and any(t == text for p, _, _, t in _to_run() if p == reason.split()[1]), (
                    f"{page} block {n} is not the same as a block run in {reason.split()[1]}")
        elif lang not in _RUN and lang != "text":
            unlisted.append(f"{page} block {n} (```{lang or 'no language'}): {key[1]!r}")
    assert not unlisted, "blocks neither run nor listed in _NOT_RUN with a reason:\n" + "\n".join(unlisted)
    stale = set(_NOT_RUN).union(*_NOT_ON_ROUTE.values()) - {(p, _first_line(t)) for p, _, _, t in blocks}
    assert not stale, f"_NOT_RUN or _NOT_ON_ROUTE list blocks no page holds: {sorted(stale)}"


def _install_stamp() -> str:
    """The stamp tools/run.sh writes into .venv once it installed this checkout (its own WANT= line, evaluated)."""
    line = next(ln for ln in (ROOT / "tools" / "run.sh").read_text().splitlines() if ln.startswith("WANT="))
    proc = subprocess.run(["bash", "-c", f'WHEELS=0\n{line}\necho "$WANT"'], cwd=ROOT, capture_output=True, text=True)
    return proc.stdout.strip()


def _checkout(tmp_path):
    """A copy of this checkout with its .venv linked (run.sh finds it set up) and the example inputs added, and the
    environment the blocks run in: a fresh HOME (the plugin block installs into ~/.local/share/QGIS), the venv first
    on the PATH."""
    venv = ROOT / ".venv" if ROUTE == "debian" else Path(sys.prefix)  # the wheels route: the venv running the suite
    stamp = ROOT / ".venv" / ".gistools-installed"
    if ROUTE == "debian" and (not stamp.exists() or stamp.read_text().strip() != _install_stamp()):
        pytest.fail("the .venv is not set up for this checkout: run `bash tools/run.sh test` (the README's command), "
                    "so that the copy's run.sh does not reinstall gistools into it")
    work = tmp_path / "checkout"
    shutil.copytree(ROOT, work, ignore=_COPY_SKIP)
    (work / ".venv").symlink_to(venv)
    home = tmp_path / "home"
    home.mkdir()
    shims = tmp_path / "shims"  # the docs are written for a user with sudo; as root without it, sudo runs the command
    shims.mkdir()
    if os.geteuid() == 0 and not shutil.which("sudo"):
        (shims / "sudo").write_text('#!/bin/sh\nexec "$@"\n')
        (shims / "sudo").chmod(0o755)
    path = f"{venv / 'bin'}:{shims}:{os.environ['PATH']}"
    env = {**os.environ, "HOME": str(home), "PATH": path, "QT_QPA_PLATFORM": "offscreen", **_SMOKE}
    env.pop("PIP_CONSTRAINT", None)  # run.sh's: the blocks say which constraints they use
    prep = subprocess.run(["gistools", "examples", "."], cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert prep.returncode == 0, prep.stderr[-2000:]
    return work, env


def _run_block(work, env, i: int, page: str, n: int, lang: str, block: str) -> subprocess.CompletedProcess:
    """One block in `work`: bash with -euo pipefail (less the lines of _NOT_HERE), or Python as a script."""
    if lang == "bash":
        lines = [ln for ln in block.splitlines() if not any(ln.strip().startswith(s) for s in _NOT_HERE)]
        cmd = ["bash", "-euo", "pipefail", "-c", "\n".join(lines)]
    else:
        script = work / f".doc_block_{i}.py"
        script.write_text(block)
        cmd = [sys.executable, script.name]
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=1800)
    where = f"{page} block {n} (```{lang})"
    assert proc.returncode == 0, f"{where} failed:\n{block}\n{proc.stdout[-1500:]}\n{proc.stderr[-2500:]}"
    assert "Traceback" not in proc.stderr, f"{where}:\n{proc.stderr[-2500:]}"
    runs = block.count("python benchmarks/")
    if runs:  # each benchmark said first that it ran at the smoke scale
        said = proc.stdout.count("smoke run (GISTOOLS_BENCH_SMOKE=1)")
        assert proc.stdout.startswith("bench_") and said == runs, f"{where}: not {runs} smoke runs:\n{proc.stdout[:1500]}"
    return proc


def _check_the_model_outputs(work):
    """The QGIS model example as printed: every output where it was given, with the CLI's road and water classes
    (the cell-by-cell equality with gistools shrub is tests/test_qgis.py's) and its class polygons."""
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


def test_every_command_and_python_block_runs_as_printed(tmp_path, server):
    """Each ```bash block of the README and the docs, in order, in one copy of this checkout to which `gistools
    examples .` added the example inputs; each ```python block as a script in the same folder, after the blocks
    before it. A block that fails names its page, its number and its output. The route from an area to a map
    (docs/area.md) reads a real COPC file (PDAL's test data) served by nginx on loopback."""
    work, env = _checkout(tmp_path)
    base, _log = server
    env.update(SERVICE=f"{base}/lone-star.copc.laz", AREA=",".join(repr(v) for v in BOX),
               LAST_SEEN="515385,4918360")
    blocks = _to_run(ROUTE)
    assert sum(b[2] == "bash" for b in blocks) >= 20 and sum(b[2] == "python" for b in blocks) >= 3
    readme_py = None
    for i, (page, n, lang, block) in enumerate(blocks):
        proc = _run_block(work, env, i, page, n, lang, block)
        if page == "README.md" and lang == "python" and readme_py is None:
            readme_py = proc
    # the README's Python example as printed: its counts, and the guard lets the workers spawn (no fork warning)
    assert readme_py is not None, "the README has no Python block run here"
    assert "{'ok': 4, 'failed': 0, 'skipped': 0}" in readme_py.stdout
    assert "forked" not in readme_py.stderr
    if ROUTE == "debian":  # the QGIS model's block runs on the Debian route only
        _check_the_model_outputs(work)


def _readme_python() -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python\n"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_python_example_into_a_folder_of_other_settings_speaks_python(tmp_path):
    """Run after the command line made its output folder with 5 ft cells, the example's 1 m call into the same
    folder is refused by the library, and its message names the Python argument (overwrite=True), never a flag."""
    code = _readme_python()
    folder = re.search(r'rasters_from_tiles\(\["sample_tiles"\], "([^"]+)"', code).group(1)
    shutil.copytree(SAMPLE, tmp_path / "sample_tiles")
    first = subprocess.run([sys.executable, "-m", "gistools.cli.main", "rasters", "sample_tiles", "--out", folder, "-q"],
                           cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert first.returncode == 0, first.stderr
    (tmp_path / "example.py").write_text(code)
    proc = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode != 0, "a 1 m run into a folder of 5 ft rasters must be refused"
    last = proc.stderr.strip().splitlines()[-1]
    assert "overwrite=True" in last and "--" not in last, last
