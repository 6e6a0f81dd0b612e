"""Options whose value multiplies the work or the memory are checked against the data before the first tile, with
the arithmetic in the one line; nothing is read past the headers and no output is written."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pytest
from click.testing import CliRunner

from conftest import SAMPLE
from gistools.cli.main import cli


def run(args) -> tuple[int, str]:
    result = CliRunner().invoke(cli, [str(a) for a in args])
    return result.exit_code, result.output


def one_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    assert "Traceback" not in text and len(lines) == 1 and lines[0].startswith("gistools: error: "), text
    return lines[0]


def _header_span() -> tuple[float, float]:
    """The sample tiles' largest header z range, and their unit's metres (US survey feet), read with laspy."""
    spans = []
    for p in sorted(SAMPLE.glob("*.la[sz]")):
        with laspy.open(p) as f:
            spans.append(f.header.maxs[2] - f.header.mins[2])
    return max(spans), 1200 / 3937


@pytest.mark.parametrize("args,needles", [
    (["--method", "smrftin", "--smrftin-window", "1e6m"], ["--smrftin-window 1e6m", "666,667 cells", "at most 200"]),
    (["--method", "smrf", "--window", "300m"], ["--window 300m", "radius of 300 cells", "at most 200"]),
    (["--method", "csf", "--csf-resolution", "1e-6m"], ["CSF cloth", "--csf-resolution"]),
    (["--method", "smrftin", "--smrftin-cell", "1e-6m"], ["--smrftin-cell"]),
    (["--method", "smrf", "--cell", "1e-5m"], ["--cell"]),
    (["--csf-time-step", "0"], ["--csf-time-step", "above 0"]),
])
def test_ground_refuses_settings_whose_work_explodes_before_any_tile(tmp_path, args, needles):
    out = tmp_path / "g"
    started = time.monotonic()
    code, text = run(["ground", SAMPLE, "--out", out, "-q", *args])
    line = one_line(text)
    assert code == 1 and all(n in line for n in needles), line
    assert "--cell-size" not in line and "--chunk-size" not in line  # options ground does not have
    assert time.monotonic() - started < 10
    assert not out.exists() or not [p for p in out.iterdir() if p.suffix in (".laz", ".las", ".vpc")]


def test_a_window_wider_than_the_grid_gives_the_same_objects_as_the_grid_wide_window():
    """The progressive filter stops at a radius of rows + cols: the diamond then covers the grid from every cell, so
    a wider window marks the same cells (checked against the numpy form run to the full radius)."""
    from gistools.lidar import ground

    rng = np.random.default_rng(3)
    surface = rng.normal(0, 0.3, (12, 9)).cumsum(axis=0)
    surface[4:7, 3:6] += 8  # a block standing above
    capped = ground.progressive_filter(surface, 1.0, 0.1, 500.0)
    full = np.zeros(surface.shape, bool)
    previous, erosion = surface, surface
    for radius in range(1, 501):
        erosion = ground.cross_filter(erosion, 1, maximum=False)
        opening = ground.cross_filter(erosion, radius, maximum=True)
        full |= (previous - opening) > 0.1 * radius
        previous = opening
    assert np.array_equal(capped, full) and capped[5, 4]


def test_chm_refuses_a_threshold_step_of_too_many_layers_with_the_arithmetic(tmp_path):
    span, ft = _header_span()
    step_m = 1e-3
    layers = 1 + math.ceil((span - 0.0) / (step_m / ft))  # thresholds 0m,2m: the second below every step here
    code, text = run(["chm", SAMPLE, "--out", tmp_path / "c", "--thresholds", "0m", "--threshold-step", f"{step_m}m",
                      "-q"])
    line = one_line(text)
    assert code == 1 and f"{layers:,} pit-free layers" in line and "at most 500" in line, line


def test_mapbook_refuses_a_scale_of_too_many_pages_before_reading_them(tmp_path):
    out = tmp_path / "s"
    assert run(["shrub", SAMPLE, "--out", out, "-q"])[0] == 0
    before = sorted(p.name for p in out.iterdir())
    for scale in ("1", "100"):
        started = time.monotonic()
        code, text = run(["mapbook", out, "--scale", scale])
        line = one_line(text)
        assert code == 1 and "sheets" in line and "--max-pages 1000" in line, line
        assert time.monotonic() - started < 10
    assert sorted(p.name for p in out.iterdir()) == before


def test_a_step_rerun_killed_midway_is_put_back_by_the_next_run(tmp_path):
    """kill -9 during ``gistools density`` (a step rerun that holds its rollback): the next command into the folder
    puts the files the step had replaced back, byte for byte, before it does anything."""
    out = tmp_path / "s"
    assert run(["shrub", SAMPLE, "--out", out, "-q"])[0] == 0
    before = {p.relative_to(out).as_posix(): p.read_bytes() for p in (out / "density").glob("*.tif")}
    proc = subprocess.Popen([sys.executable, "-m", "gistools.cli.main", "density", str(out), "--radius", "20ft",
                             "-q"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(out.glob(".gistools-scratch-rollback-*/manifest.json")):
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    assert list(out.glob(".gistools-scratch-rollback-*"))  # what the killed step left
    code, text = run(["webmap", out])  # the next command into the folder
    assert code == 0, text
    assert not list(out.glob(".gistools-scratch-*"))
    after = {p.relative_to(out).as_posix(): p.read_bytes() for p in (out / "density").glob("*.tif")}
    assert after == before
    assert json.loads((out / "report.json").read_text())["density_radius"] is not None
