"""Values a hostile user gives (infinite lengths, south-up rasters, a report nested 200,000 deep, a value of 100,000
characters, a layer in another CRS): each is right, or refused in one line that names the file or option, the
problem and the fix, and no output is written."""

from __future__ import annotations

import json
import shutil
import sys

import geopandas as gpd
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import Affine, from_origin
from shapely.geometry import Point

from conftest import SAMPLE
from gistools.cli.main import cli, one_line as shorten


def run(args) -> tuple[int, str]:
    result = CliRunner().invoke(cli, [str(a) for a in args])
    return result.exit_code, result.output


def one_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("warning:")]
    assert "Traceback" not in text and len(lines) == 1 and lines[0].startswith("gistools: error: "), text
    return lines[0]


def _dem(path, transform, n: int = 30):
    z = np.add.outer(np.arange(n), np.arange(n)).astype(np.float32)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32", crs="EPSG:32611",
                       transform=transform, nodata=-9999) as dst:
        dst.write(z, 1)
        dst.update_tags(1, units="m")
    return path


def test_a_south_up_dem_is_refused_by_terrain_and_viewshed_in_one_line(tmp_path):
    dem = _dem(tmp_path / "south_up.tif", Affine(10, 0, 500000, 0, 10, 4100000))  # rows run north
    code, text = run(["terrain", dem, "--out", tmp_path / "t", "-q"])
    line = one_line(text)
    assert code == 1 and "south-up" in line and "gdalwarp" in line and str(dem) in line, line
    code, text = run(["viewshed", dem, "--out", tmp_path / "v", "--from", "500100,4100100", "-q"])
    line = one_line(text)
    assert code == 1 and "south-up" in line and "gdalwarp" in line, line
    assert not (tmp_path / "t" / "slope.tif").exists() and not (tmp_path / "v" / "viewshed.tif").exists()


@pytest.mark.parametrize("value", ["1e400ft", "1e999m"])
def test_an_infinite_eye_height_is_refused(tmp_path, value):
    dem = _dem(tmp_path / "dem.tif", from_origin(500000, 4100300, 10, 10))
    code, text = run(["viewshed", dem, "--out", tmp_path / "v", "--from", "500100,4100200", "--height", value, "-q"])
    line = one_line(text)
    assert code == 1 and "must be a finite length" in line and value in line, line


def test_observers_in_another_crs_are_refused_with_the_command_that_reprojects_them(tmp_path):
    dem = _dem(tmp_path / "dem.tif", from_origin(500000, 4100300, 10, 10))
    gpd.GeoDataFrame(geometry=[Point(-117.0, 37.05)], crs="EPSG:4326").to_file(tmp_path / "obs.gpkg", layer="seen")
    code, text = run(["viewshed", dem, "--out", tmp_path / "v", "--observers", f"{tmp_path / 'obs.gpkg'}:seen", "-q"])
    line = one_line(text)
    assert code == 1 and "ogr2ogr -t_srs EPSG:32611" in line and "--reproject-vectors" not in line, line


def test_terrains_warning_names_the_option_as_the_command_line_takes_it(tmp_path):
    dem = tmp_path / "dem.tif"
    _dem(dem, from_origin(500000, 4100300, 10, 10))
    with rasterio.open(dem, "r+") as dst:
        dst.update_tags(1, units="")  # no vertical unit
    result = CliRunner().invoke(cli, ["terrain", str(dem), "--out", str(tmp_path / "t"), "-q"])
    assert result.exit_code == 0, result.output
    assert "--z-unit m" in result.output and "\ue000" not in result.output, result.output
    record = json.loads((tmp_path / "t" / "report.json").read_text())
    assert all("\ue000" not in w for w in record["warnings"]) and "--z-unit m" in record["warnings"][0]


def test_a_scene_of_an_absurd_exaggeration_is_refused(tmp_path):
    code, text = run(["scene", tmp_path, "--exaggeration", "1e308"])
    line = one_line(text)
    assert code == 1 and "--exaggeration" in line and "at most 100" in line, line


def test_a_report_nested_200000_deep_is_one_line_not_a_recursion_error(tmp_path):
    out = tmp_path / "out"
    shutil.copytree(SAMPLE, tmp_path / "tiles")
    assert run(["shrub", tmp_path / "tiles", "--out", out, "-q"])[0] == 0
    (out / "report.json").write_text('{"tool": "gistools shrub", "x": ' + "[" * 200_000 + "]" * 200_000 + "}")
    code, text = run(["density", out, "-q"])
    line = one_line(text)
    assert code == 1 and "report.json" in line, line
    code, text = run(["rasters", tmp_path / "tiles", "--out", out, "-q"])
    line = one_line(text)
    assert code == 1 and "report.json" in line, line


def test_a_value_of_100000_characters_is_named_in_a_short_line(tmp_path):
    value = "7" * 50 + "x" * 100_000
    code, text = run(["rasters", SAMPLE, "--out", tmp_path / "r", "--cell-size", value])
    line = one_line(text)
    assert code == 1 and len(line) < 500 and "--cell-size" in line and "characters" in line, line
    assert shorten("a " + "b" * 1000 + " c").startswith("a " + "b" * 80 + "...(840 characters)...")
