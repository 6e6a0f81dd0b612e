"""Reruns of the commands that write per tile or per input (chm, metrics, fuels, terrain, viewshed) or one model
(aquifer, runway, structure): a rerun keeps only outputs made with its settings, from its input as it is now, and
whole; it refuses other settings naming both values, remakes a damaged output, and never replaces a file gistools did not write (nor writes through a link).

Each case is run through the command line as a user would, and asserts the exit status, the one line, and the bytes
of the files that must not change (the outputs' values against an independent computation where they change).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.transform import from_origin

from conftest import SAMPLE
from gistools.cli.main import cli

TILE = "35712"


def run(args) -> tuple[int, str]:
    result = CliRunner().invoke(cli, [str(a) for a in args])
    return result.exit_code, result.output


def digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def one_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    assert "Traceback" not in text, text
    assert lines and lines[-1].startswith("gistools: error: "), text
    return lines[-1]


@pytest.fixture(scope="module")
def chm_done(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("chm") / "out"
    code, text = run(["chm", SAMPLE, "--out", out, "--method", "p2r", "-q"])
    assert code == 0, text
    return out


@pytest.fixture
def chm_out(chm_done, tmp_path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(chm_done, out, symlinks=True)
    return out


def _tile_pits(out: Path) -> dict:
    report = json.loads((out / "report.json").read_text())
    return {t["name"]: (t["status"], t["pits"], t["cells"]) for t in report["tiles"]}


def test_a_rerun_with_other_settings_is_refused_naming_both_values_and_changes_no_byte(chm_out):
    before = {p: digest(p) for p in sorted((chm_out / "chm").glob("*.tif"))}
    code, text = run(["chm", SAMPLE, "--out", chm_out, "--method", "pitfree", "-q"])
    line = one_line(text)
    assert code == 1 and "method p2r" in line and "pitfree" in line and "--overwrite" in line, line
    code, text = run(["chm", SAMPLE, "--out", chm_out, "--method", "p2r", "--cell-size", "10ft", "-q"])
    line = one_line(text)
    assert code == 1 and "--cell-size 1.64042 ft" in line and "10 ft" in line, line
    assert before == {p: digest(p) for p in sorted((chm_out / "chm").glob("*.tif"))}
    code, text = run(["chm", SAMPLE, "--out", chm_out, "--method", "pitfree", "--overwrite", "-q"])
    assert code == 0, text
    assert all(status == "ok" for status, _, _ in _tile_pits(chm_out).values())


def test_a_rerun_keeps_what_the_tiles_found_and_remakes_a_truncated_tile(chm_out, chm_done):
    first = _tile_pits(chm_done)
    tif = chm_out / "chm" / f"{TILE}.tif"
    tif.write_bytes(tif.read_bytes()[:500])  # truncated after it was made
    code, text = run(["chm", SAMPLE, "--out", chm_out, "--method", "p2r", "-q"])
    assert code == 0, text
    again = _tile_pits(chm_out)
    assert again[TILE] == ("ok", *first[TILE][1:])  # remade, the same pits as the first run
    assert all(again[n] == ("skipped", *first[n][1:]) for n in first if n != TILE)  # kept with what they found
    totals = [json.loads((o / "report.json").read_text())["pits"] for o in (chm_done, chm_out)]
    assert totals[0] == totals[1] == sum(p for _, p, _ in first.values())  # the run's total counts kept tiles
    with rasterio.open(tif) as a, rasterio.open(chm_done / "chm" / f"{TILE}.tif") as b:
        assert np.array_equal(a.read(1), b.read(1))


@pytest.mark.parametrize("overwrite", [False, True])
def test_a_file_gistools_did_not_write_at_a_tiles_output_is_never_replaced(chm_out, tmp_path, overwrite):
    tif = chm_out / "chm" / f"{TILE}.tif"
    tif.unlink()
    (chm_out / "tile_reports" / f"{TILE}.json").unlink()
    with rasterio.open(tif, "w", driver="GTiff", width=4, height=4, count=1, dtype="uint8") as dst:
        dst.write(np.full((1, 4, 4), 7, np.uint8))  # the user's own raster of that name
    mine = digest(tif)
    code, text = run(["chm", SAMPLE, "--out", chm_out, "--method", "p2r", "-q", *(["--overwrite"] if overwrite else [])])
    line = one_line(text)
    assert code == 1 and "gistools did not write" in line and str(tif) in line, line
    assert digest(tif) == mine


def test_a_product_folder_that_links_to_a_users_folder_is_refused_and_the_users_files_kept(tmp_path):
    """fuels into OUT whose cbh/ is a link to a user's folder holding a file named as a tile's output."""
    mine = tmp_path / "my_rasters"
    mine.mkdir()
    (mine / f"{TILE}.tif").write_bytes(b"my own raster, not a GeoTIFF")
    out = tmp_path / "out"
    out.mkdir()
    (out / "cbh").symlink_to(mine, target_is_directory=True)
    for extra in ([], ["--overwrite"]):
        code, text = run(["fuels", SAMPLE, "--out", out, "-q", *extra])
        line = one_line(text)
        assert code == 1 and "is a link" in line and "cbh" in line, line
    assert (mine / f"{TILE}.tif").read_bytes() == b"my own raster, not a GeoTIFF"
    assert sorted(p.name for p in mine.iterdir()) == [f"{TILE}.tif"]


def test_metrics_rerun_with_another_cell_size_is_refused(tmp_path):
    out = tmp_path / "m"
    code, text = run(["metrics", SAMPLE, "--out", out, "--metrics", "count,z_max", "-q"])
    assert code == 0, text
    code, text = run(["metrics", SAMPLE, "--out", out, "--metrics", "count,z_max", "--cell-size", "50ft", "-q"])
    line = one_line(text)
    assert code == 1 and "--cell-size 16.4042 ft" in line and "50 ft" in line and "--overwrite" in line, line


# --- terrain and viewshed: one input, kept outputs checked against it -----------------------------------------------

def _plane(path: Path, dz_per_cell: float, size: int = 40, cell: float = 10.0) -> None:
    """A DEM rising ``dz_per_cell`` per cell eastward (slope atan(dz / cell)), EPSG:32611 metres."""
    z = np.tile(np.arange(size, dtype=np.float32) * dz_per_cell, (size, 1))
    with rasterio.open(path, "w", driver="GTiff", width=size, height=size, count=1, dtype="float32",
                       crs="EPSG:32611", transform=from_origin(500000, 4100000, cell, cell), nodata=-9999) as dst:
        dst.write(z, 1)


def _inner_slope(path: Path) -> float:
    with rasterio.open(path) as src:
        s = src.read(1, masked=True)
    return float(np.ma.median(s[2:-2, 2:-2]))


def test_terrain_remakes_a_truncated_or_emptied_slope(tmp_path):
    dem = tmp_path / "dem.tif"
    _plane(dem, 10.0)  # 45 degrees
    out = tmp_path / "t"
    assert run(["terrain", dem, "--out", out, "--products", "slope", "-q"])[0] == 0
    for damage in (lambda p: p.write_bytes(p.read_bytes()[:500]), lambda p: p.write_bytes(b"")):
        damage(out / "slope.tif")
        code, text = run(["terrain", dem, "--out", out, "--products", "slope", "-q"])
        assert code == 0 and "kept" not in text, text
        assert _inner_slope(out / "slope.tif") == pytest.approx(45.0, abs=1e-3)


def test_terrain_remakes_its_slope_once_the_dem_is_rewritten(tmp_path):
    dem = tmp_path / "dem.tif"
    _plane(dem, 1.0)  # atan(0.1) = 5.71 degrees
    out = tmp_path / "t"
    assert run(["terrain", dem, "--out", out, "--products", "slope", "-q"])[0] == 0
    assert _inner_slope(out / "slope.tif") == pytest.approx(np.degrees(np.arctan(0.1)), abs=1e-3)
    _plane(dem, 10.0)  # the same file rewritten: 45 degrees
    code, text = run(["terrain", dem, "--out", out, "--products", "slope", "-q"])
    assert code == 0 and "kept" not in text, text
    assert _inner_slope(out / "slope.tif") == pytest.approx(45.0, abs=1e-3)


def test_viewshed_remakes_a_damaged_output_and_refuses_other_settings(tmp_path):
    dem = tmp_path / "dem.tif"
    _plane(dem, 0.0)  # flat: every cell in range is seen
    out = tmp_path / "v"
    args = ["viewshed", dem, "--out", out, "--from", "500200,4099800", "-q"]
    assert run(args)[0] == 0
    first = (out / "viewshed.tif").read_bytes()
    (out / "viewshed.tif").write_bytes(first[:500])
    code, text = run(args)
    assert code == 0, text
    with rasterio.open(out / "viewshed.tif") as src:
        assert (src.read(1) == 1).all()  # flat ground, no range limit: all seen
    code, text = run([*args, "--height", "20ft"])
    line = one_line(text)
    assert code == 1 and "--height" in line and "--overwrite" in line, line


# the commands that make their outputs together from their inputs: (arguments before --out, a changed setting)
TOGETHER = {
    "runway": (["runway", "survey.csv", "--code", "4E", "--crs", "EPSG:3003"], ["--code", "4D"], "--code 4E"),
    "aquifer": (["aquifer", "model", "contacts.csv", "--layers", "LS,AU,AD,AQ", "--crs", "EPSG:3003"], ["--k", "10"],
                "--k 12"),
    "structure": (["structure", "scan.txt"], ["--loop-mode", "catmull-rom"], "--loop-mode classic"),
}


@pytest.fixture(scope="module")
def example_inputs(tmp_path_factory):
    from gistools.datasets.examples import write_examples

    folder = tmp_path_factory.mktemp("examples")
    write_examples(folder, sample_tiles=SAMPLE)
    return folder


def _digests(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())
            if p.is_file() and p.name != "report.json"}


@pytest.mark.parametrize("command", sorted(TOGETHER))
def test_a_command_of_one_model_reruns_as_every_command(command, example_inputs, tmp_path, monkeypatch):
    """aquifer, runway and structure rerun as the tile commands do: the same settings from the same inputs keep the
    outputs (not one byte rewritten, the record says ``kept``); another setting is refused before any work, naming
    both values; --overwrite makes them again; an input changed since makes them again."""
    args, other, before = TOGETHER[command]
    work = tmp_path / "inputs"
    shutil.copytree(example_inputs, work, ignore=shutil.ignore_patterns("sample_tiles", "tiles"))
    monkeypatch.chdir(work)
    out = tmp_path / "out"
    code, text = run([*args, "--out", out, "-q"])
    assert code == 0, text
    first = _digests(out)
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.is_file() and p.name != "report.json"}
    code, text = run([*args, "--out", out, "-q"])
    assert code == 0 and "outputs kept" in text, text
    assert _digests(out) == first
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.is_file() and p.name != "report.json"} == mtimes
    record = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert record["kept"] and [r["tool"] for r in record["runs"]] == [record["tool"]] * 2
    code, text = run([*args, *other, "--out", out, "-q"])
    assert code == 1 and f"with {before}, this run asks" in text and "--overwrite" in text, text
    assert _digests(out) == first  # refused before any work
    code, text = run([*args, *other, "--out", out, "-q", "--overwrite"])
    assert code == 0 and "outputs kept" not in text, text
    source = work / args[2 if command == "aquifer" else 1]
    source.write_text(source.read_text(encoding="utf-8") + "\n", encoding="utf-8")  # the input rewritten
    code, text = run([*args, *other, "--out", out, "-q"])
    assert code == 0 and "outputs kept" not in text, text
    assert "kept" not in json.loads((out / "report.json").read_text(encoding="utf-8"))


def test_a_model_of_per_layer_files_is_made_again_when_one_changes(example_inputs, tmp_path, monkeypatch):
    """The aquifer's per-layer files (``LS=LSInput.txt ...``): each is stamped, so an edit of one makes the model
    again instead of keeping it; a --z-max change of the runway is refused naming --z-max."""
    work = tmp_path / "inputs"
    shutil.copytree(example_inputs, work, ignore=shutil.ignore_patterns("sample_tiles", "tiles"))
    monkeypatch.chdir(work)
    layers = [f"{name}={name}Input.txt" for name in ("LS", "AU", "AD", "AQ")]
    args = ["aquifer", "model", *layers, "--layers", "LS,AU,AD,AQ", "--crs", "EPSG:3003", "--out", tmp_path / "aq", "-q"]
    code, text = run(args)
    assert code == 0, text
    code, text = run(args)
    assert code == 0 and "outputs kept" in text, text
    (work / "AUInput.txt").write_text((work / "AUInput.txt").read_text(encoding="utf-8") + "\n", encoding="utf-8")
    code, text = run(args)
    assert code == 0 and "outputs kept" not in text, text
    runway = ["runway", "survey.csv", "--code", "4E", "--crs", "EPSG:3003", "--out", tmp_path / "rw", "-q"]
    assert run(runway)[0] == 0
    code, text = run([*runway, "--z-max", "2.5"])
    assert code == 1 and "with --z-max 3.5, this run asks 2.5" in text, text
