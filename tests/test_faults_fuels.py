"""Faults of gistools fuels (and gistools metrics without ground) found by a hostile user: each option that would
multiply the work or the memory is checked against the tiles' headers before the first tile, with the arithmetic;
tiles without ground or first returns fail with the reason; values the LCP's int16 cannot hold are refused, never
clipped. Every case through the command line: the exit code, no traceback, the one line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import laspy
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from conftest import SAMPLE
from gistools.cli.main import cli

TILE = SAMPLE / "35712.las"  # 67,059 points in US feet, z 29.8 to 106.61 ft


def invoke(args) -> tuple[int, str]:
    """The CLI in this process: (exit code, everything it printed); an uncaught exception is a traceback."""
    result = CliRunner().invoke(cli, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise AssertionError(f"traceback: {type(result.exception).__name__}: {result.exception}\n{result.output}")
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


def one_line(text: str, *needles: str, start: str = "gistools:") -> str:
    """The single line of ``text`` that starts with ``start`` (stripped), holding every needle."""
    lines = [line for line in text.splitlines() if line.strip().startswith(start)]
    assert len(lines) == 1, text
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def refused(args, out: Path, *needles: str) -> str:
    """``gistools fuels`` refused in one error line, exit 1, before anything is written."""
    code, text = invoke(["fuels", *args, "--out", out, "-q"])
    assert code == 1, text
    line = one_line(text, "gistools: error:", *needles)
    assert not out.exists(), list(out.rglob("*"))
    return line


def rewritten(src: Path, dest: Path, *, z_shift: float = 0.0, **fields) -> Path:
    """A copy of ``src`` with the point fields of ``fields`` (name -> function of the old values) changed and z
    shifted by ``z_shift``."""
    las = laspy.read(src)
    for name, change in fields.items():
        setattr(las, name, change(np.asarray(getattr(las, name))))
    if z_shift:
        z = np.asarray(las.z) + z_shift
        las.header.offsets = np.array([las.header.offsets[0], las.header.offsets[1], las.header.offsets[2] + z_shift])
        las.z = z
    dest.parent.mkdir(parents=True, exist_ok=True)
    las.write(dest)
    return dest


@pytest.fixture(scope="module")
def no_ground(tmp_path_factory) -> Path:
    """The tile with its ground (2) and water (9) points made unclassified (1)."""
    return rewritten(TILE, tmp_path_factory.mktemp("tiles") / "noground.las",
                     classification=lambda c: np.where(np.isin(c, (2, 9)), 1, c).astype(np.uint8))


# ------------------------------------------------------------------ 1. bounds before work


def test_a_layer_of_zero_is_refused(tmp_path):
    for value in ("0", "-1m"):  # was a ZeroDivisionError traceback
        refused([TILE, "--layer", value], tmp_path / "o", f"--layer '{value}'", "positive", "--layer 1m")


def test_a_layer_too_thin_for_the_heights_is_refused_with_its_layer_count(tmp_path):
    """1e-12 m layers over the 76.81 ft of z in the header: 2.34e+13 layers, not an out-of-memory."""
    refused([TILE, "--layer", "1e-12m"], tmp_path / "o", "--layer 1e-12m", "76.81", "2.34e+13 layers", "100,000",
            "thicker --layer")


def test_profiles_beyond_the_available_memory_are_refused_with_the_arithmetic(tmp_path, monkeypatch):
    """0.1 ft cells: 99,890,030 cells x 24 layers x 128 bytes = 306.9 GB, over 80 % of the (here 8 GB) memory."""
    import gistools.machine

    monkeypatch.setattr(gistools.machine, "available_memory", lambda: 8_000_000_000)
    refused([TILE, "--cell-size", "0.1ft"], tmp_path / "o", "306.9 GB", "99,890,030 cells", "24 layers", "128 bytes",
            "8.0 GB", "larger --cell-size")


def test_columns_far_narrower_than_the_pulses_are_refused(tmp_path):
    """(100 ft / 3.28e-9 ft)^2 columns a cell against about 626 pulses a cell: not a ValueError per tile."""
    refused([TILE, "--column", "1e-9m"], tmp_path / "o", "--column 1e-9m", "9.29e+20 columns a cell", "626 pulses",
            "wider --column")


def test_a_cell_larger_than_the_earth_is_refused(tmp_path):
    refused([TILE, "--cell-size", "1e9m"], tmp_path / "o", "--cell-size 1e9m", "off the Earth", "smaller --cell-size")


# ------------------------------------------------------------------ 2. a tile without first returns


def test_a_tile_without_first_returns_fails_and_no_landscape_is_written(tmp_path):
    tile = rewritten(TILE, tmp_path / "t" / "nofirst.las", return_number=lambda r: np.full(len(r), 2, np.uint8),
                     number_of_returns=lambda r: np.full(len(r), 2, np.uint8))
    code, text = invoke(["fuels", tile, "--out", tmp_path / "o", "-q"])
    assert code == 1, text
    one_line(text, "nofirst.las", "is a first return (return number 1)", "gistools info", start="FAILED")
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["counts"] == {"ok": 0, "skipped": 0, "failed": 1} and report["landscape"] is None
    assert not (tmp_path / "o" / "landscape.lcp").exists()


# ------------------------------------------------------------------ 3. elevations the LCP's int16 cannot hold


def test_tiles_whose_every_z_is_beyond_int16_metres_are_refused_before_work(tmp_path):
    high = rewritten(TILE, tmp_path / "t" / "high.las", z_shift=120000.0)  # 36,585 m and up
    refused([high], tmp_path / "o", "120,030 to 120,107", "36,585 to 36,609 m", "int16", "gistools info")


def test_a_landscape_elevation_beyond_int16_is_refused_not_clipped(tmp_path):
    """One tile beyond 32,767 m among good ones: the fuel layers are made, the landscape is refused in one line
    (named in report.json too), nothing clipped to 32767."""
    folder = tmp_path / "t"
    folder.mkdir()
    shutil.copy(TILE, folder / TILE.name)
    rewritten(SAMPLE / "35713.las", folder / "35713.las", z_shift=120000.0)
    code, text = invoke(["fuels", folder, "--out", tmp_path / "o", "-q"])
    assert code == 1, text
    one_line(text, "gistools: error:", "landscape.lcp", "elevation reaches 36,5", "int16", "not written")
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["counts"]["ok"] == 2 and report["landscape"] is None
    assert any("int16" in w for w in report["warnings"])
    assert not (tmp_path / "o" / "landscape.lcp").exists() and (tmp_path / "o" / "elevation.vrt").exists()


# ------------------------------------------------------------------ 4. extinction


def test_an_extinction_of_zero_is_refused(tmp_path):
    """k = 0 gave CBD and CBH 0 under full cover; the leaf mass per area scales the profile alike."""
    refused([TILE, "--extinction", "0"], tmp_path / "o", "--extinction", "must be positive", "Beer-Lambert",
            "--extinction 0.5")
    refused([TILE, "--leaf-mass-area", "0"], tmp_path / "o", "--leaf-mass-area", "must be positive",
            "--leaf-mass-area 0.141")


# ------------------------------------------------------------------ 5. fuel codes


def test_fuel_codes_that_are_not_whole_numbers_are_refused(tmp_path):
    refused([TILE, "--fuel-codes", "1.5,2.5,3.5"], tmp_path / "o", "--fuel-codes 1.5,2.5,3.5", "1.5",
            "whole numbers", "--fuel-codes 121,142,145")


def test_the_same_fuel_code_three_times_is_a_constant_fuel_model(tmp_path):
    code, text = invoke(["fuels", TILE, "--out", tmp_path / "o", "-q", "--fuel-codes", "121,121,121"])
    assert code == 0, text
    with rasterio.open(tmp_path / "o" / "landscape.tif") as src:
        fuel = src.read(4)
    assert set(np.unique(fuel[fuel != -9999])) == {121}


# ------------------------------------------------------------------ 6. tiles without ground


NO_GROUND = ("no ground (class 2 or 9) points in the tile or its buffer", "Classify ground first (gistools ground)")


def test_fuels_on_a_tile_without_ground_names_the_missing_class(tmp_path, no_ground):
    code, text = invoke(["fuels", no_ground, "--out", tmp_path / "o", "-q"])
    assert code == 1, text
    one_line(text, "noground.las", *NO_GROUND, start="FAILED")


@pytest.mark.parametrize("metric", ["hag_p95", "fhd"])
def test_metrics_of_heights_on_a_tile_without_ground_fail_with_the_reason(tmp_path, no_ground, metric):
    code, text = invoke(["metrics", no_ground, "--out", tmp_path / "o", "-q", "--metrics", metric])
    assert code == 1, text
    one_line(text, "noground.las", *NO_GROUND, metric, start="FAILED")
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["counts"]["failed"] == 1 and report["counts"]["ok"] == 0


def test_metrics_that_need_no_ground_still_work_without_it(tmp_path, no_ground):
    code, text = invoke(["metrics", no_ground, "--out", tmp_path / "o", "-q", "--metrics", "z_max,count"])
    assert code == 0, text
    with rasterio.open(tmp_path / "o" / "z_max.vrt") as src:
        assert np.isfinite(src.read(1, masked=True).compressed()).any()
