"""Shared fixtures: paths to the committed sample tiles and to ../shared/data real files."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import laspy
import numpy as np
import pytest
from scipy import ndimage

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
    """An independent TIN DEM: scipy LinearNDInterpolator (Qhull) of ground points at cell centres; repeated xy averaged.

    Returns (ref, interior, nodata, decided): ``interior`` the cells to compare values on; ``nodata`` the cells the
    DEM must leave empty by an independent rule: centre farther than ``max_distance`` from every ground point
    (scipy cKDTree), or a water cell (water points and no ground point in it), or outside the hull, or in a Qhull
    triangle with an edge longer than 2 x ``max_distance``; ``decided`` the cells where that rule is not within
    1e-6 of a threshold (ties between cocircular points aside)."""
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import Delaunay, cKDTree

    from gistools.grid import cell_centres

    x, y, z, cls, _, withheld = read_las_independently(paths)
    g = (cls == 2) & ~withheld
    xy, inv = np.unique(np.column_stack([x[g], y[g]]), axis=0, return_inverse=True)
    zz = np.bincount(inv.ravel(), weights=z[g]) / np.bincount(inv.ravel())
    xs, ys = cell_centres(grid)
    cx, cy = np.meshgrid(xs, ys)
    shift = xy.mean(axis=0)
    tri = Delaunay(xy - shift)
    ref = LinearNDInterpolator(tri, zz)(cx - shift[0], cy - shift[1])
    centres = np.column_stack([cx.ravel() - shift[0], cy.ravel() - shift[1]])
    dist = cKDTree(xy - shift).query(centres)[0].reshape(grid.shape)
    simplex = tri.find_simplex(centres)
    corners = tri.points[tri.simplices[np.maximum(simplex, 0)]]
    edge = np.max([np.hypot(*(corners[:, i] - corners[:, (i + 1) % 3]).T) for i in range(3)], axis=0).reshape(grid.shape)
    outside = (simplex < 0).reshape(grid.shape)
    from scipy.stats import binned_statistic_2d

    w, s_, e, n = grid.bounds

    def counts(mask):  # points per cell, cells [west, east) x [south, north) as scipy bins them
        if not mask.any():
            return np.zeros(grid.shape)
        c = binned_statistic_2d(y[mask], x[mask], None, "count", bins=[np.linspace(s_, n, grid.height + 1),
                                                                     np.linspace(w, e, grid.width + 1)])[0]
        return c[::-1]

    water = (counts((cls == 9) & ~withheld) > 0) & (counts(g) == 0)
    nodata = (dist > max_distance) | water | outside | (edge > 2 * max_distance)
    decided = (np.abs(dist - max_distance) > 1e-6) & (np.abs(edge - 2 * max_distance) > 1e-6)
    interior = ~nodata & np.isfinite(ref)
    # away from the grid's edge and the hull's, where Qhull and the TIN may close the hull differently
    near_hull = ndimage.binary_dilation(outside, iterations=2)
    interior &= ~near_hull
    decided &= ~near_hull
    for a in (interior, decided):
        a[:3, :] = a[-3:, :] = a[:, :3] = a[:, -3:] = False
    return ref, interior, nodata, decided


def reference_tin_heights(x, y, z, gx, gy, gz):
    """Heights above a scipy (Qhull) TIN of the ground points (gx, gy, gz), and, per point, whether its triangle is
    one of two equally valid Delaunay choices (its circumcircle passes through a neighbouring triangle's far vertex,
    to 1e-9 relative: points on a survey's lattice make such ties, and any two TINs may split those quads either
    way). An independent reference for heights above ground: NaN outside the ground's hull."""
    from scipy.spatial import Delaunay

    x0, y0 = float(np.min(gx)), float(np.min(gy))
    pts = np.column_stack([np.asarray(gx, float) - x0, np.asarray(gy, float) - y0])
    tri = Delaunay(pts)
    q = np.column_stack([np.asarray(x, float) - x0, np.asarray(y, float) - y0])
    s = tri.find_simplex(q)
    inside = s >= 0
    h = np.full(len(q), np.nan)
    t = tri.transform[s[inside]]
    b = np.einsum("ijk,ik->ij", t[:, :2], q[inside] - t[:, 2])
    w = np.column_stack([b, 1 - b.sum(axis=1)])
    gz = np.asarray(gz, float)
    h[inside] = np.asarray(z, float)[inside] - np.einsum("ij,ij->i", w, gz[tri.simplices[s[inside]]])
    tied = np.zeros(len(q), bool)
    verts = pts[tri.simplices]  # (ntri, 3, 2)
    tie_tri = np.zeros(len(tri.simplices), bool)
    for k in range(3):
        nb = tri.neighbors[:, k]
        has = nb >= 0
        own = tri.simplices[has]  # neighbour k is opposite vertex k: the far vertex is the one it does not share
        far = tri.simplices[nb[has]].sum(axis=1) - (own.sum(axis=1) - own[:, k])
        a, bb, c = (verts[has, m] - pts[far] for m in range(3))
        det = ((a ** 2).sum(1) * (bb[:, 0] * c[:, 1] - bb[:, 1] * c[:, 0]) - (bb ** 2).sum(1) * (a[:, 0] * c[:, 1] - a[:, 1] * c[:, 0])
               + (c ** 2).sum(1) * (a[:, 0] * bb[:, 1] - a[:, 1] * bb[:, 0]))
        scale = np.maximum.reduce([(a ** 2).sum(1), (bb ** 2).sum(1), (c ** 2).sum(1)]) ** 2
        tie_tri[np.flatnonzero(has)[np.abs(det) <= 1e-9 * scale]] = True
    tied[inside] = tie_tri[s[inside]]
    return h, tied


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
SIZE = (1000, 800)
QUIET = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-default-apps",
         "--disable-features=MediaRouter,OptimizationHints,Translate,NetworkTimeServiceQuerying", "--virtual-time-budget=4000"]
BLOCKED = ["--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND"]  # no network: a request fails


def need_chromium(what: str) -> None:
    """Skip the calling module where Debian's chromium is missing; fail it in CI (the test command installs it)."""
    if CHROMIUM is None:  # pragma: no cover - depends on the machine
        if os.environ.get("CI"):
            raise RuntimeError(f"CI must run the {what} tests: the test command installs Debian's chromium")
        pytest.skip(f"{what} tests: chromium is not installed (apt-get install chromium)", allow_module_level=True)


def chromium(*args, home, size=SIZE):
    """A real headless Chromium run with ``args`` (a page, --dump-dom, --screenshot=...), its profile under ``home``."""
    env = {**os.environ, "HOME": str(home)}
    run = subprocess.run([CHROMIUM, *QUIET, f"--window-size={size[0]},{size[1]}", f"--user-data-dir={home}/profile", *args],
                         capture_output=True, text=True, timeout=120, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    return run


def need_kernel(what: str = "the compiled kernel") -> None:
    """Skip a test of the compiled kernel where it is not built; fail it in CI, whose install builds it."""
    from gistools import kernel

    if not kernel.loaded():
        if os.environ.get("CI"):
            pytest.fail(f"CI must test {what}, but the kernel is not built: {kernel.engine()}")
        pytest.skip(f"{what}: the compiled kernel is not built here")


def repeated_block(folder: Path, k: int = 4) -> Path:
    """The sample block repeated k x k times side by side (64 tiles of 2,000 ft at k = 4): a run of several
    seconds even on a fast machine (a stop's moments, a worker lost in the middle)."""
    folder.mkdir()
    for p in sorted(SAMPLE.glob("*.la[sz]")):
        las = laspy.read(p)
        x, y = np.asarray(las.x), np.asarray(las.y)
        for i in range(k):
            for j in range(k):
                las.x, las.y = x + 2000 * i, y + 2000 * j
                las.write(folder / f"{p.stem}_{i}{j}.laz")
    return folder
