"""What a plain install needs and finds: PROJ's data where the system keeps it (or one line naming PROJ), example
files of plain numbers whatever numpy is installed, and the main job's drawing libraries as dependencies."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

from conftest import ROOT, SAMPLE

GISTOOLS = [sys.executable, "-m", "gistools.cli.main"]


def test_the_main_jobs_drawing_libraries_are_dependencies_not_extras():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=;\[ ]", d, maxsplit=1)[0].lower() for d in project["dependencies"]}
    assert {"matplotlib", "trimesh"} <= names


def test_example_files_hold_plain_numbers(tmp_path):
    done = subprocess.run(GISTOOLS + ["examples", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    for name in ("scan.txt", "cctv.txt", "AQInput.txt"):
        rows = (tmp_path / name).read_text().splitlines()[1:]
        assert rows and all(len(r.split()) == 4 for r in rows)
        assert all(float(v) == float(v) for r in rows for v in r.split()[1:]), name  # each one a number
    assert "np." not in (tmp_path / "scan.txt").read_text()


def test_proj_data_is_found_where_the_system_keeps_it_when_pyproj_looks_elsewhere(tmp_path):
    """PROJ_DATA pointing at an empty folder (as a venv without the proj command finds nothing): gistools finds
    the system's proj.db and the run completes, the tiles' CRS read."""
    env = {**os.environ, "PROJ_DATA": str(tmp_path / "empty"), "PROJ_LIB": str(tmp_path / "empty"),
           "PATH": os.path.dirname(sys.executable)}  # no `proj` command either
    (tmp_path / "empty").mkdir()
    done = subprocess.run(GISTOOLS + ["rasters", str(SAMPLE), "--out", str(tmp_path / "r"), "-q"], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and "4 tiles ok" in done.stdout, done.stderr
    assert "proj.db" not in done.stderr, done.stderr  # GDAL found it too


def test_without_proj_data_anywhere_the_run_stops_once_naming_proj(tmp_path):
    import pyproj
    import pytest

    if (Path(pyproj.__file__).parent / "proj_dir" / "share" / "proj" / "proj.db").is_file():
        pytest.skip("pyproj is a binary wheel here, which carries its own PROJ data: it is never missing")
    empty = tmp_path / "empty"
    empty.mkdir()
    script = ("import sys, gistools.projdata as p; p.proj_data_candidates = lambda: []; "
              "from gistools.cli.main import main; sys.argv = ['gistools'] + sys.argv[1:]; main()")
    env = {**os.environ, "PROJ_DATA": str(empty), "PROJ_LIB": str(empty), "PATH": os.path.dirname(sys.executable)}
    done = subprocess.run([sys.executable, "-c", script, "rasters", str(SAMPLE), "--out", str(tmp_path / "r"), "-q"],
                          env=env, capture_output=True, text=True, timeout=600)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode == 1 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert "PROJ's database (proj.db) is not found" in lines[0] and "proj-data" in lines[0], lines[0]
    assert "35712" not in done.stderr and not (tmp_path / "r").exists()  # no tile blamed, nothing written


def test_geopackages_are_written_in_version_1_2_which_gdal_3_6_opens_without_a_warning(tmp_path):
    """Every GeoPackage writer (one layer, several layers, the points' chunked writer): SQLite's own user_version
    (10200 for GeoPackage 1.2, read with sqlite3), and the system's ogrinfo (QGIS 3.22's GDAL 3.6 on Debian 12)
    opens each without the version warning."""
    import shutil
    import sqlite3

    import geopandas as gpd
    from shapely.geometry import Point

    from gistools.io.vector import write_layer, write_layers

    frame = gpd.GeoDataFrame({"a": [1]}, geometry=[Point(0, 0)], crs=32611)
    written = [write_layer(frame, tmp_path / "one.gpkg", "L"), write_layers({"A": frame, "B": frame},
                                                                          tmp_path / "two.gpkg")]
    done = subprocess.run(GISTOOLS + ["points", str(SAMPLE / "35712.las"), "--out", str(tmp_path / "p")],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    written += sorted((tmp_path / "p").glob("*.gpkg"))
    assert len(written) == 3
    for path in written:
        with sqlite3.connect(path) as db:
            assert db.execute("PRAGMA user_version").fetchone()[0] == 10200, path
        if shutil.which("ogrinfo"):
            info = subprocess.run(["ogrinfo", "-so", "-al", str(path)], capture_output=True, text=True)
            assert info.returncode == 0 and "user_version" not in info.stderr, info.stderr
