"""Bad input: clear one-line errors, the batch goes on, nothing partial is left; the CLI end to end."""

from __future__ import annotations

import json
import shutil

import laspy
import numpy as np
import pytest
from click.testing import CliRunner

from gistools import RasterSettings, rasters_from_tiles
from gistools.cli.main import cli
from gistools.io.raster import read_raster
from gistools.errors import Cancelled, CRSMismatchError, MissingCRSError
from gistools.io.points import read_tile_info


def _copy_sample(sample_tiles, dest, n=4):
    dest.mkdir(parents=True, exist_ok=True)
    for p in sample_tiles[:n]:
        shutil.copy(p, dest / p.name)
    return dest


def test_folder_with_a_truncated_tile_and_a_text_file(sample_tiles, tmp_path):
    tiles = _copy_sample(sample_tiles, tmp_path / "tiles", 3)
    data = sample_tiles[0].read_bytes()
    (tiles / "broken.las").write_bytes(data[: len(data) // 2])
    (tiles / "notes.las").write_text("this is not a LAS file\n")
    before = {p.name: p.read_bytes() for p in tiles.iterdir()}
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["rasters", str(tiles), "--out", str(out), "--quiet"])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    assert "broken.las" in result.output and "truncated" in result.output
    assert "notes.las" in result.output and "not a readable LAS/LAZ file" in result.output
    report = json.loads((out / "report.json").read_text())
    status = {t["name"]: t["status"] for t in report["tiles"]}
    assert status == {"broken": "failed", "notes": "failed", **{p.stem: "ok" for p in sample_tiles[:3]}}
    errors = {t["name"]: t["error"] for t in report["tiles"]}
    assert "Re-copy or re-export" in errors["broken"]
    assert sorted(p.stem for p in (out / "dem").glob("*.tif")) == sorted(p.stem for p in sample_tiles[:3])
    assert not list(out.rglob("*.partial")) and not list(out.glob(".gistools-scratch-*"))
    assert {p.name: p.read_bytes() for p in tiles.iterdir()} == before  # inputs untouched


def test_truncated_laz_fails_while_decoding_and_is_reported(sample_tiles, tmp_path):
    laz = next(p for p in sample_tiles if p.suffix == ".laz")
    tiles = _copy_sample([p for p in sample_tiles if p.suffix == ".las"], tmp_path / "tiles", 1)
    data = laz.read_bytes()
    (tiles / "cut.laz").write_bytes(data[: int(len(data) * 0.6)])
    summary = rasters_from_tiles([tiles], tmp_path / "out")
    status = {t["name"]: t for t in summary["tiles"]}
    assert status["cut"]["status"] == "failed" and "cut.laz" in status["cut"]["error"]
    assert summary["counts"]["ok"] == 1


def _write_without_crs(src, dest):
    las = laspy.read(src)
    for name in ("GeoKeyDirectoryVlr", "GeoAsciiParamsVlr", "GeoDoubleParamsVlr", "WktCoordinateSystemVlr"):
        try:
            las.vlrs.extract(name)
        except IndexError:
            pass
    las.write(dest)


def test_missing_crs_is_refused_unless_given(sample_tiles, tmp_path):
    tile = tmp_path / "nocrs.las"
    _write_without_crs(sample_tiles[0], tile)
    with pytest.raises(MissingCRSError, match="nocrs.las: header has no CRS. Pass the tiles' CRS with crs"):
        read_tile_info(tile)
    result = CliRunner().invoke(cli, ["rasters", str(tile), "--out", str(tmp_path / "a"), "-q"])
    assert result.exit_code == 1 and "header has no CRS" in result.output and "--crs" in result.output
    result = CliRunner().invoke(cli, ["rasters", str(tile), "--out", str(tmp_path / "b"), "-q", "--crs", "EPSG:2882"])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "b" / "report.json").read_text())
    assert report["crs"].startswith("EPSG:2882") and report["tiles"][0]["status"] == "ok"


def test_tiles_with_different_crs_are_refused_naming_both(sample_tiles, megaplot, tmp_path):
    with pytest.raises(CRSMismatchError) as err:
        rasters_from_tiles([sample_tiles[0], megaplot], tmp_path)
    text = str(err.value)
    assert sample_tiles[0].name in text and "Megaplot.laz" in text
    assert "EPSG:2882" in text and "EPSG:26917" in text
    result = CliRunner().invoke(cli, ["rasters", str(sample_tiles[0]), str(megaplot), "--out", str(tmp_path / "c")])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.output.count("\n") == 1 and "EPSG:26917" in result.output


def test_cell_size_in_metres_on_feet_and_metre_files(autzen, megaplot, tmp_path):
    a = rasters_from_tiles([autzen], tmp_path / "a", RasterSettings(cell_size="1m"))
    assert a["horizontal_unit"] == "foot" and a["cell_size"] == pytest.approx(1 / 0.3048, rel=1e-12)
    m = rasters_from_tiles([megaplot], tmp_path / "m", RasterSettings(cell_size="1m"))
    assert m["horizontal_unit"] == "metre" and m["cell_size"] == 1.0
    import rasterio

    with rasterio.open(tmp_path / "a" / "dsm" / "autzen_trim.tif") as src:
        assert src.res[0] == pytest.approx(3.280839895, rel=1e-9)
        assert (src.transform.c / src.res[0]) == pytest.approx(round(src.transform.c / src.res[0]), abs=1e-6)
    m5 = rasters_from_tiles([megaplot], tmp_path / "m5", RasterSettings(cell_size="5ft"))
    assert m5["cell_size"] == pytest.approx(1.524)


def _rasters_once(sample_tiles, tmp_path):
    """Two sample tiles rastered into tmp_path/out; returns (rerun(*args) -> click result, out, a DSM tif, its mtime)."""
    tiles = _copy_sample(sample_tiles, tmp_path / "tiles", 2)
    out = tmp_path / "out"
    runner = CliRunner()

    def rerun(*args):
        return runner.invoke(cli, ["rasters", str(tiles), "--out", str(out), "-q", *args])

    assert rerun().exit_code == 0
    tif = out / "dsm" / f"{sample_tiles[0].stem}.tif"
    return rerun, out, tif, tif.stat().st_mtime_ns


def test_existing_outputs_are_kept_unless_overwrite(sample_tiles, tmp_path):
    rerun, out, tif, stamp = _rasters_once(sample_tiles, tmp_path)
    second = rerun()
    assert second.exit_code == 0 and "2 skipped" in second.output
    assert tif.stat().st_mtime_ns == stamp
    third = rerun("--overwrite")
    assert third.exit_code == 0 and "2 tiles ok" in third.output
    assert tif.stat().st_mtime_ns != stamp


def test_resume_with_other_settings_is_refused(sample_tiles, tmp_path):
    """A rerun into the same --out with another cell size (or DEM method) would mix grids in the mosaic: refused,
    naming both values and the fix, nothing rewritten; --overwrite redoes the tiles."""
    rerun, out, tif, stamp = _rasters_once(sample_tiles, tmp_path)
    other = rerun("--cell-size", "3ft")
    assert other.exit_code != 0 and "Traceback" not in other.output
    assert "cell size 5 US survey foot, this run asks 3 US survey foot" in other.output and "--overwrite" in other.output
    assert tif.stat().st_mtime_ns == stamp and not list(out.glob(".gistools-scratch-*"))
    method = rerun("--dem-method", "max")
    assert method.exit_code != 0 and "DEM method tin, this run asks max" in method.output
    redo = rerun("--cell-size", "3ft", "--overwrite")
    assert redo.exit_code == 0 and "2 tiles ok" in redo.output
    _, grid, _ = read_raster(tif)
    assert grid.cell_size == pytest.approx(3.0)


def test_cancel_stops_and_leaves_no_partial_output(sample_tiles, tmp_path):
    calls = []

    def progress(fraction, message):
        calls.append(fraction)
        return fraction < 0.5  # ask to stop half way

    with pytest.raises(Cancelled):
        rasters_from_tiles(sample_tiles, tmp_path / "out", progress=progress)
    out = tmp_path / "out"
    assert not list(out.rglob("*.partial")) and not list(out.glob(".gistools-scratch-*"))
    assert not list(out.rglob("*.tif"))
    assert calls and max(calls) >= 0.5


def test_info_prints_header_crs_units_and_counts(sample_tiles, autzen):
    result = CliRunner().invoke(cli, ["info", str(sample_tiles[0]), str(autzen)])
    assert result.exit_code == 0, result.output
    assert "LAS 1.1, point format 1" in result.output
    assert "EPSG:2882" in result.output and "US survey foot" in result.output
    assert "x/y foot, z foot" in result.output  # autzen: international feet
    js = CliRunner().invoke(cli, ["info", str(sample_tiles[0]), "--json"])
    info = json.loads(js.output)[0]
    las = laspy.read(sample_tiles[0])
    assert info["points"] == len(las.points)
    assert info["points_by_class"] == {str(c): int(n) for c, n in enumerate(np.bincount(las.classification)) if n} or \
        {int(k): v for k, v in info["points_by_class"].items()} == {c: int(n) for c, n in enumerate(np.bincount(las.classification)) if n}


def test_bad_cell_size_is_one_line(sample_tiles, tmp_path):
    result = CliRunner().invoke(cli, ["rasters", str(sample_tiles[0]), "--out", str(tmp_path), "--cell-size", "5 parsecs"])
    assert result.exit_code == 1 and "--cell-size" in result.output and "Traceback" not in result.output


def test_ctrl_c_leaves_no_partial_file(sample_tiles, tmp_path):
    """SIGINT in the middle of a run: exit 130, one line, no partial file, no scratch left."""
    import signal
    import subprocess
    import sys
    import time

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for k in range(4):  # 16 tiles, so the run is long enough to be interrupted
        for p in sample_tiles:
            shutil.copy(p, tiles / f"{p.stem}_{k}{p.suffix}")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles),
                             "--out", str(out), "-q", "--chunk-size", "5000", "--jobs", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not list(out.glob(".gistools-scratch-*/*")) and time.time() < deadline:
        time.sleep(0.01)  # wait until the run is under way: a tile's scratch files are being written
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not list(out.rglob("*.partial")) and not list(out.glob(".gistools-scratch-*"))
