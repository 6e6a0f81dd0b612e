"""Shared fixtures: paths to the committed sample tiles and to ../shared/data real files."""

from __future__ import annotations

import os
from pathlib import Path

import laspy
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_tiles"
SHARED_DATA = ROOT.parent / "shared" / "data"
AUTZEN = SHARED_DATA / "lidar" / "autzen" / "autzen_trim.las"
MEGAPLOT = SHARED_DATA / "lidar" / "megaplot" / "Megaplot.laz"


def need_shared(path: Path = SHARED_DATA, what: str = "real-data test"):
    """Skip (with the reason) when ``path`` under ../shared is absent; fail instead in CI (CI=true)."""
    if path.exists():
        return
    if os.environ.get("CI"):
        pytest.fail(f"{path} is missing: CI must run the {what}s (clone with ../shared beside it)")
    pytest.skip(f"{what}: {path} is absent (a fresh clone without ../shared)")


def _need_shared():
    need_shared(SHARED_DATA)


@pytest.fixture
def autzen() -> Path:
    _need_shared()
    return AUTZEN


@pytest.fixture
def megaplot() -> Path:
    _need_shared()
    return MEGAPLOT


@pytest.fixture(params=["autzen", "megaplot"])
def real_tile(request) -> Path:
    _need_shared()
    return {"autzen": AUTZEN, "megaplot": MEGAPLOT}[request.param]


@pytest.fixture(scope="session")
def sample_tiles() -> list[Path]:
    tiles = sorted(SAMPLE.glob("*.la[sz]"))
    assert len(tiles) == 4, "sample_tiles/ must hold the 2 x 2 block (python tools/make_sample_tiles.py)"
    return tiles


@pytest.fixture(scope="session")
def sample_run(tmp_path_factory, sample_tiles):
    """gistools rasters on sample_tiles/ with defaults (5 ft, TIN DEM), run once per session."""
    from gistools import rasters_from_tiles

    out = tmp_path_factory.mktemp("sample_out")
    summary = rasters_from_tiles(sample_tiles, out)
    return out, summary


def read_las_independently(paths):
    """x, y, z, classification, return_number of tiles, read with laspy directly (an oracle path)."""
    parts = []
    for p in paths:
        las = laspy.read(p)
        parts.append((np.asarray(las.x), np.asarray(las.y), np.asarray(las.z), np.asarray(las.classification),
                      np.asarray(las.return_number), np.asarray(las.withheld, bool)))
    return [np.concatenate(c) for c in zip(*parts)]
