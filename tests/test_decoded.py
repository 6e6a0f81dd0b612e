"""LAZ tiles decoded once: pass 1 keeps a compressed tile decoded for pass 2 in the same process (io.decoded), and
the outputs are those of the same tiles read from LAS, which are never kept."""

from __future__ import annotations

import os

import laspy
import numpy as np
import pytest
import rasterio

from conftest import SAMPLE


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """The sample tiles twice: as LAZ and as LAS (the same point records)."""
    root = tmp_path_factory.mktemp("decoded")
    for kind in ("laz", "las"):
        (root / kind).mkdir()
        for p in sorted(SAMPLE.glob("*.la[sz]")):
            las = laspy.read(p)
            las.write(root / kind / f"{p.stem}.{kind}")
    return root


@pytest.fixture
def spied(monkeypatch):
    """The tiles pass 2 took from those pass 1 kept."""
    from gistools.io import decoded

    taken = []
    real = decoded.take

    def take(path):
        las = real(path)
        if las is not None:
            taken.append(os.path.basename(path))
        return las

    monkeypatch.setattr(decoded, "take", take)
    return taken


def _points(folder):
    return {p.stem.split(".")[0]: laspy.read(p).points.array for p in sorted(folder.glob("*.la[sz]"))}


def _rasters(folder):
    return {p.relative_to(folder).as_posix(): rasterio.open(p).read() for p in sorted(folder.rglob("*.tif"))}


@pytest.mark.parametrize("jobs", [1, "auto"])
def test_normalize_of_laz_tiles_kept_decoded_equals_the_las_tiles_run(pair, tmp_path, spied, jobs):
    from gistools.io import decoded
    from gistools.products.normalize import NormalizeSettings, normalize_from_tiles

    settings = NormalizeSettings(format="las")
    normalize_from_tiles(pair / "laz", tmp_path / "laz", settings, jobs=jobs)
    assert sorted(spied) == sorted(p.name for p in (pair / "laz").glob("*.laz"))  # every tile decoded once
    normalize_from_tiles(pair / "las", tmp_path / "las", settings, jobs=jobs)
    assert len(spied) == 4  # LAS tiles are read again: no decoding to save
    got, want = _points(tmp_path / "laz"), _points(tmp_path / "las")
    assert sorted(got) == sorted(want)
    for name in want:
        assert got[name].tobytes() == want[name].tobytes(), name
    assert not decoded._kept  # nothing left behind


def test_metrics_with_heights_of_laz_tiles_kept_decoded_equal_the_las_tiles_run(pair, tmp_path, spied):
    from gistools.products.metrics import MetricsSettings, metrics_from_tiles

    settings = MetricsSettings(metrics=("count", "z_p95", "hag_p95", "cover_above2m"))
    metrics_from_tiles(pair / "laz", tmp_path / "laz", settings, jobs=1)
    assert len(spied) == 4
    metrics_from_tiles(pair / "las", tmp_path / "las", settings, jobs=1)
    got, want = _rasters(tmp_path / "laz"), _rasters(tmp_path / "las")
    assert sorted(got) == sorted(want) and len(want) == 16
    for name in want:
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)


def test_a_kept_tile_whose_file_changed_is_not_taken(pair, tmp_path):
    from gistools.io import decoded

    path = tmp_path / "t.laz"
    las = laspy.read(next((pair / "laz").glob("*.laz")))
    las.write(path)
    decoded.keep(path, las)
    assert decoded.take(path) is las and decoded.take(path) is None  # taken once
    decoded.keep(path, las)
    os.utime(path, ns=(1, 1))  # rewritten since
    assert decoded.take(path) is None


def test_a_tile_kept_by_a_relative_path_is_not_taken_from_another_working_folder(tmp_path, monkeypatch):
    """Two copies of a tile with the same size and time, in two folders: kept by a relative path in one, the same
    relative path from the other names another file, and is not taken."""
    import shutil

    from gistools.io import decoded

    src = SAMPLE / "35813.laz"
    for folder in ("a", "b"):
        (tmp_path / folder / "t").mkdir(parents=True)
        shutil.copy2(src, tmp_path / folder / "t" / "35813.laz")
    monkeypatch.chdir(tmp_path / "a")
    las = laspy.read("t/35813.laz")
    decoded.keep("t/35813.laz", las)
    try:
        monkeypatch.chdir(tmp_path / "b")
        assert decoded.take("t/35813.laz") is None
        monkeypatch.chdir(tmp_path / "a")
        assert decoded.take("t/35813.laz") is las
    finally:
        decoded.discard([tmp_path / "a" / "t" / "35813.laz"])
