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


def tin_oracle(grid, paths, max_distance):
    """An independent TIN DEM: scipy LinearNDInterpolator (Qhull) of ground points at cell centres; repeated xy averaged."""
    x, y, z, cls, _, withheld = read_las_independently(paths)
    g = (cls == 2) & ~withheld
    xy, inv = np.unique(np.column_stack([x[g], y[g]]), axis=0, return_inverse=True)
    zz = np.bincount(inv.ravel(), weights=z[g]) / np.bincount(inv.ravel())
    from scipy.interpolate import LinearNDInterpolator

    from gistools.grid import cell_centres
    from gistools.lidar import within_distance

    xs, ys = cell_centres(grid)
    cx, cy = np.meshgrid(xs, ys)
    ref = LinearNDInterpolator(xy - xy.mean(axis=0), zz)(cx - xy[:, 0].mean(), cy - xy[:, 1].mean())
    interior = within_distance(grid, xy[:, 0], xy[:, 1], max_distance) & np.isfinite(ref)
    # interior: away from the hull edge, where Qhull and Triangle may close the hull differently
    interior[:3, :] = interior[-3:, :] = interior[:, :3] = interior[:, -3:] = False
    return ref, interior
