#!/usr/bin/env python3
"""Quality and speed of ground / noise classification (``gistools ground``) against the libraries' defaults.

Quality, on the real files of ../shared/data/lidar (autzen: suburban, international feet; Megaplot: boreal
forest, metres, heights already normalised: its ground is z = 0): the classes are wiped (every point class 1),
0.5 % of the points are injected as noise (half low: 20-50 m below ground, multipath; half high: 20-60 m above
the highest point within 10 m, birds), each method classifies, and

* type I (ground called non-ground), type II (non-ground called ground), total error, against the provider's
  ground;
* DEM RMSE and p95 |error| (metres): TIN DEM at 1 m from the classified ground against the TIN DEM from the
  provider's ground, on the cells both have;
* noise found (injected points classed 7 / 18) and real points classed noise.

Methods: gistools SMRF with its defaults; the same SMRF with PDAL's default parameters (cell 1 m, slope 0.15,
window 18 m, threshold 0.5 m, scalar 1.25 m); the Cloth Simulation Filter with lidR's defaults, run directly
through the ``cloth-simulation-filter`` library (resolution 0.5 m, threshold 0.5 m, rigidness 1, 500
iterations, no slope smoothing; no noise step: the library has none).

Speed: ``gistools ground`` on a synthetic block of 5000 ft tiles (bench_shrub's generator, cached in
--workdir), --jobs 1 and 2, points per second per core.

    python benchmarks/bench_ground.py [--points 16e6] [--workdir /tmp/gistools-bench-shrub] [--simple-block]

The ISPRS filter test (``--isprs``; ../shared/data/isprs, Sithole & Vosselman 2004): each of the 15 reference
samples alone, its classes wiped, classified by the library call (``classify_ground_and_noise``) with each method's
defaults, scored against the labels (type I, type II, total error, Cohen's kappa, as the data's README defines
them; noise counts as object), per sample and the plain mean, with the published figures (published.csv) beside.
CSF takes about 2.5 minutes for the 15 samples (500 iterations at 0.5 m); ``--methods`` picks methods.

    python benchmarks/bench_ground.py --isprs [--methods smrf,csf]

A block of real tiles with a provider's ground, not in ../shared (``--tiles``; lasR's ``inst/extdata/bcts``: four
LAZ tiles of a British Columbia forest delivery, 2.8 M points, 5 % ground): the classes wiped, ``gistools ground``
on the folder (each tile with its neighbours) with each method, the block's DEM against the provider's.

    python benchmarks/bench_ground.py --tiles '<lasR>/inst/extdata/bcts/*.laz' [--methods adaptive,smrf]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, smoke, workdir  # noqa: E402

SHARED = ROOT.parent / "shared" / "data" / "lidar"
FILES = {"autzen (suburban, ft)": SHARED / "autzen" / "autzen_trim.las",
         "Megaplot (boreal forest, m)": SHARED / "megaplot" / "Megaplot.laz",
         "Topography (steep forested slope, m)": SHARED / "lidr" / "Topography.laz",
         "MixedConifer (conifer stand, m)": SHARED / "lidr" / "MixedConifer.laz"}

ISPRS = ROOT.parent / "shared" / "data" / "isprs"
ISPRS_SAMPLES = ("samp11", "samp12", "samp21", "samp22", "samp23", "samp24", "samp31", "samp41", "samp42", "samp51",
                 "samp52", "samp53", "samp54", "samp61", "samp71")
# published rows shown beside ours (published.csv; "mean" rows included)
PUBLISHED = ("CSF (Zhang 2016)", "SMRF Python (authors), single set", "SMRF Matlab (authors), single set",
             "SMRF (Pingel 2013), single parameter set", "SMRF (Pingel 2013), optimized per sample",
             "SMRF Matlab (authors), optimized", "Mongus & Zalik 2014", "Hu et al. 2014")


def isprs_scores(truth: np.ndarray, ground: np.ndarray) -> dict:
    """The filter test's figures (Sithole & Vosselman 2004; the README's definitions), in %: reference ground as
    rows, a = ground kept, b = ground rejected, c = object accepted, d = object kept."""
    n = len(truth)
    a = float(np.sum(truth & ground))
    b = float(np.sum(truth & ~ground))
    c = float(np.sum(~truth & ground))
    d = float(np.sum(~truth & ~ground))
    po = (a + d) / n
    pe = ((a + b) * (a + c) + (c + d) * (b + d)) / n ** 2
    return {"type I": 100 * b / (a + b), "type II": 100 * c / (c + d), "total": 100 * (b + c) / n,
            "kappa": 100 * (po - pe) / (1 - pe)}


def isprs_classify(path: Path, method: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(reference ground, ground found, seconds): one sample alone, its classes wiped (every point 1, as a new
    user's tiles), classified by the library call with ``gistools ground``'s defaults and ``method``."""
    import laspy

    from gistools.io.points import read_tile_info
    from gistools.lidar.ground import classify_ground_and_noise
    from gistools.products.ground import GroundSettings, _params

    las = laspy.read(path)
    info = read_tile_info(path)
    x, y, z = (np.asarray(a, np.float64) for a in (las.x, las.y, las.z))
    rn, nr = np.asarray(las.return_number), np.asarray(las.number_of_returns)
    truth = np.asarray(las.classification) == 2
    p = _params(GroundSettings(method=method), info)
    t = time.perf_counter()
    with _quiet_stdout():  # the CSF library prints its steps on the C stdout
        cls = classify_ground_and_noise(x, y, z, rn, nr, np.ones(len(x), np.uint8), method=p.method, smrf=p.smrf,
                                        smrftin=p.smrftin, adaptive=p.smrftin, csf=p.csf, noise=p.noise,
                                        z_metres=p.z_metres)
    return truth, cls == 2, time.perf_counter() - t


@contextlib.contextmanager
def _quiet_stdout():
    """File descriptor 1 sent to /dev/null (C libraries' prints), restored after."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _published() -> dict:
    """{(method, sample): (type I, type II, total, kappa)} from published.csv, None where not given."""
    import csv

    out = {}
    with open(ISPRS / "published.csv", newline="") as f:
        for r in csv.DictReader(f):
            name = next((m for m in PUBLISHED if r["method"].startswith(m)), None)
            if name is None:
                continue
            out[(name, r["sample"])] = tuple(float(r[k]) if r[k] else None for k in ("type_I", "type_II", "total", "kappa"))
    return out


def isprs(methods) -> dict:
    """Print the table of every sample and the mean; {method: mean scores}."""
    pub = _published()
    scores = {m: {} for m in methods}
    seconds = {m: 0.0 for m in methods}
    points = 0
    for s in ISPRS_SAMPLES:
        path = ISPRS / f"{s}.las"
        for m in methods:
            truth, ground, sec = isprs_classify(path, m)
            scores[m][s] = isprs_scores(truth, ground)
            seconds[m] += sec
        points += len(truth)

    def fmt(v):
        return "" if v is None else f"{v:.2f}"

    print("| sample | method | type I % | type II % | total % | kappa % |")
    print("|---|---|---:|---:|---:|---:|")
    for s in ISPRS_SAMPLES + ("mean",):
        for m in methods:
            r = scores[m][s] if s != "mean" else {k: float(np.mean([scores[m][q][k] for q in ISPRS_SAMPLES]))
                                                  for k in ("type I", "type II", "total", "kappa")}
            name = f"**gistools {m}**" if s == "mean" else f"gistools {m}"
            print(f"| {s} | {name} | {r['type I']:.2f} | {r['type II']:.2f} | {r['total']:.2f} | {r['kappa']:.2f} |")
        for name in PUBLISHED:
            v = pub.get((name, s))
            if v is None and s == "mean":
                rows = [pub.get((name, q)) for q in ISPRS_SAMPLES]
                if all(rows):  # the plain mean of the published per-sample figures
                    v = tuple(None if any(r[i] is None for r in rows) else float(np.mean([r[i] for r in rows]))
                              for i in range(4))
            if v is not None:
                print(f"| {s} | published: {name} | {fmt(v[0])} | {fmt(v[1])} | {fmt(v[2])} | {fmt(v[3])} |")
    print()
    print(f"{points:,} points in all; seconds per method (classification only, noise step included): "
          + ", ".join(f"{m} {seconds[m]:.2f} s ({points / seconds[m] / 1e6:.3g} M points/s)" for m in methods))
    return {m: {k: float(np.mean([scores[m][q][k] for q in ISPRS_SAMPLES])) for k in ("type I", "type II", "total", "kappa")}
            for m in methods}


def _inject_noise(x, y, z, truth, zm, rng, share=0.005):
    """Noise points at the positions of ``share`` of the points: half 20-50 m below the ground there (multipath),
    half 20-60 m above the highest point within 10 m (birds over the canopy). (indices, low, their z)."""
    from scipy.spatial import cKDTree

    k = max(int(len(x) * share), 2)
    pick = rng.choice(len(x), k, replace=False)
    low = np.arange(k) < k // 2
    g = cKDTree(np.column_stack([x[truth], y[truth]]))
    ground_z = z[truth][g.query(np.column_stack([x[pick], y[pick]]))[1]]
    allp = cKDTree(np.column_stack([x, y]))
    top = np.array([z[i].max() for i in allp.query_ball_point(np.column_stack([x[pick], y[pick]]), 10 / zm)])
    nz = np.where(low, ground_z - rng.uniform(20, 50, k) / zm, top + rng.uniform(20, 60, k) / zm)
    return pick, low, nz


def _ground_scores(x, y, z, truth, ground, grid, ref, max_distance: float, z_metres: float) -> dict:
    """Type I, type II and total error of ``ground`` against the provider's ``truth``, and the DEM at ``grid`` (a
    TIN of the ground found) against the provider's ``ref`` on the cells both have: RMSE, bias, p95 |error| (m)."""
    from gistools.lidar.gridding import dem_from_ground_points

    g = ground
    new = dem_from_ground_points(x[g], y[g], z[g], grid, max_distance=max_distance)
    both = np.isfinite(ref) & np.isfinite(new)
    err = (new - ref)[both] * z_metres
    return {"type I": float(np.mean(~g[truth])), "type II": float(np.mean(g[~truth])), "total": float(np.mean(g != truth)),
            "RMSE m": float(np.sqrt(np.mean(err ** 2))), "bias m": float(np.mean(err)),
            "p95 m": float(np.percentile(np.abs(err), 95))}


def quality(path: Path, rng, only=None) -> list[dict]:
    import laspy

    from gistools.grid import snapped_grid
    from gistools.io.points import read_tile_info
    from gistools.lidar.ground import CsfParams, csf_ground, classify_ground_and_noise
    from gistools.lidar.gridding import dem_from_ground_points
    from gistools.products.ground import GroundSettings, _params

    las = laspy.read(path)
    info = read_tile_info(path)
    x, y, z = (np.asarray(a, np.float64) for a in (las.x, las.y, las.z))
    rn, nr = np.asarray(las.return_number), np.asarray(las.number_of_returns)
    truth = np.asarray(las.classification) == 2
    zm = info.z_unit.metres
    pick, low, nz = _inject_noise(x, y, z, truth, zm, rng)
    nx, ny = x[pick], y[pick]
    X, Y, Z = np.r_[x, nx], np.r_[y, ny], np.r_[z, nz]
    RN, NR = np.r_[rn, np.ones(len(pick), rn.dtype)], np.r_[nr, np.ones(len(pick), nr.dtype)]
    ones = np.ones(len(X), np.uint8)
    m = 1 / info.unit.metres
    grid = snapped_grid((x.min(), y.min(), x.max(), y.max()), 1 * m)
    ref = dem_from_ground_points(x[truth], y[truth], z[truth], grid, max_distance=10 * m)
    ours = _params(GroundSettings(method="smrf"), info)
    pdal = _params(GroundSettings(method="smrf", slope=0.15, threshold="0.5m", scalar="1.25m"), info)
    tin = _params(GroundSettings(method="smrftin"), info)
    auto = _params(GroundSettings(), info)  # the default: adaptive
    methods = {
        "gistools adaptive (the default)": lambda: classify_ground_and_noise(X, Y, Z, RN, NR, ones, method="adaptive",
                                                                             adaptive=auto.smrftin, noise=auto.noise,
                                                                             z_metres=auto.z_metres),
        "gistools smrf": lambda: classify_ground_and_noise(X, Y, Z, RN, NR, ones, method="smrf", smrf=ours.smrf,
                                                           noise=ours.noise),
        "gistools smrftin": lambda: classify_ground_and_noise(X, Y, Z, RN, NR, ones, method="smrftin",
                                                                         smrftin=tin.smrftin, noise=tin.noise,
                                                                         z_metres=tin.z_metres),
        "smrf, PDAL's parameters": lambda: classify_ground_and_noise(X, Y, Z, RN, NR, ones, method="smrf",
                                                                     smrf=pdal.smrf, noise=pdal.noise),
        "CSF, lidR's defaults (library)": lambda: np.where(
            csf_ground(X, Y, Z, np.ones(len(X), bool), CsfParams(resolution=0.5 * m, threshold=0.5 / zm)), 2, 1),
    }
    rows = []
    for name, run in methods.items():
        if only and not any(name.startswith(o) or o in name for o in only):
            continue
        t = time.perf_counter()
        with _quiet_stdout():  # the CSF library prints its steps on the C stdout
            cls = run()
        seconds = time.perf_counter() - t
        g = cls[: len(x)] == 2
        noise = cls[len(x):]
        rows.append({
            "method": name, **_ground_scores(x, y, z, truth, g, grid, ref, 10 * m, zm),
            "noise found": float(np.mean(np.isin(noise, (7, 18)))),
            "real as noise": float(np.mean(np.isin(cls[: len(x)], (7, 18)))),
            "Mpts/s": len(X) / seconds / 1e6,
        })
    return rows


def tiles_quality(files: list[Path], methods) -> list[dict]:
    """A block of real tiles with a provider's ground (``--tiles``), run as a user runs it: the classes wiped,
    ``gistools ground`` on the folder of tiles (each tile with its neighbours), the DEM of the whole block at 1 m
    from the classified ground against the DEM from the provider's, on the cells both have."""
    import tempfile

    import laspy

    from gistools.grid import snapped_grid
    from gistools.io.points import read_tile_info, write_tile
    from gistools.lidar.gridding import dem_from_ground_points
    from gistools.products.ground import GroundSettings, ground_from_tiles

    fields = ("x", "y", "z", "intensity", "return_number", "number_of_returns", "classification")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        xs, ys, zs, truths = [], [], [], []
        for f in files:
            las, info = laspy.read(f), read_tile_info(f)
            d = {k: np.asarray(getattr(las, k)) for k in fields if k in "xyz" or k in las.point_format.dimension_names}
            truths.append(d["classification"] == 2)
            d["classification"] = np.ones(len(las.x), np.uint8)
            write_tile(tmp / "in" / f"{f.stem}.las", d, info.crs, version="1.2", point_format=1,
                       offsets=list(las.header.offsets), scale=float(las.header.scales[0]))
            xs.append(d["x"]), ys.append(d["y"]), zs.append(d["z"])
        x, y, z, truth = (np.concatenate(a) for a in (xs, ys, zs, truths))
        m, zm = 1 / info.unit.metres, info.z_unit.metres
        grid = snapped_grid((x.min(), y.min(), x.max(), y.max()), 1 * m)
        ref = dem_from_ground_points(x[truth], y[truth], z[truth], grid, max_distance=10 * m)
        for method in methods:
            t = time.perf_counter()
            ground_from_tiles(tmp / "in", tmp / method, GroundSettings(method=method))
            seconds = time.perf_counter() - t
            g = np.concatenate([np.asarray(laspy.read(tmp / method / f"{f.stem}.laz").classification) == 2
                                for f in files])
            rows.append({"method": method, **_ground_scores(x, y, z, truth, g, grid, ref, 10 * m, zm),
                         "Mpts/s": len(x) / seconds / 1e6})
    return rows


def simple_block(work: Path, points: float) -> dict:
    """A 4 x 4 block of 5000 ft tiles in EPSG:2882 made in seconds (bench_shrub's scene takes many minutes at this
    size): rolling ground, 400 houses of 60 x 40 ft raised 25 ft, a quarter of the points 1-60 ft up in vegetation
    as last returns of two-return pulses. Cached in ``work`` by point count."""
    import json

    import pyproj

    from gistools.io.points import write_tile

    meta = work / "simple_block.json"
    if meta.exists() and json.loads(meta.read_text())["points"] == int(points):
        return json.loads(meta.read_text())
    tile, crs, x0, y0 = 5000.0, pyproj.CRS.from_epsg(2882), 400000.0, 1800000.0
    rng = np.random.default_rng(7)
    hx, hy = rng.uniform(x0, x0 + 4 * tile, 400), rng.uniform(y0, y0 + 4 * tile, 400)
    n = int(points) // 16
    (work / "tiles").mkdir(parents=True, exist_ok=True)
    for i in range(4):
        for j in range(4):
            w, s = x0 + i * tile, y0 + j * tile
            x, y = rng.uniform(w, w + tile, n), rng.uniform(s, s + tile, n)
            z = 300 + 40 * np.sin(x / 2000) * np.cos(y / 1700) + 5 * np.sin(x / 170) + rng.normal(0, 0.1, n)
            for cx, cy in zip(hx, hy):
                z[(np.abs(x - cx) < 30) & (np.abs(y - cy) < 20)] += 25
            veg = rng.uniform(size=n) < 0.25
            z[veg] += rng.uniform(1, 60, veg.sum())
            nr = np.where(veg, 2, 1).astype(np.uint8)
            rn = np.where(veg, rng.integers(1, 3, n), 1).astype(np.uint8)
            write_tile(work / "tiles" / f"t{i}{j}.las", {"x": x, "y": y, "z": z, "classification": np.ones(n, np.uint8),
                       "return_number": rn, "number_of_returns": nr}, crs, version="1.2", point_format=1,
                       offsets=[w, s, 0], overwrite=True)
    info = {"points": 16 * n}
    meta.write_text(json.dumps(info))
    return info


def speed(workdir: Path, points: float, methods=("smrf",), simple: bool = False) -> list[tuple[str, int, float, int, float]]:
    """(method, jobs, wall seconds, points, CPU seconds of the run: every process and thread, LAZ compression
    included)."""
    import resource

    if simple:  # in its own folder: bench_shrub's block keeps its tiles in workdir / "tiles"
        workdir = workdir / "simple"
        info = simple_block(workdir, points)
    else:
        import bench_shrub

        info = bench_shrub.generate(workdir, points)
    rows = []
    for method in methods:
        for jobs in (1, 2):
            out = workdir / f"ground_out_{method}_{jobs}"
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "gistools.cli.main", "ground", str(workdir / "tiles"), "--out", str(out),
                            "-q", "--overwrite", "--jobs", str(jobs), "--method", method], check=True, cwd=ROOT)
            seconds = time.perf_counter() - t
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            rows.append((method, jobs, seconds, info["points"], cpu))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=float, default=16e6)
    ap.add_argument("--workdir", default="/tmp/gistools-bench-shrub")
    ap.add_argument("--no-speed", action="store_true", help="Only the quality table.")
    ap.add_argument("--simple-block", action="store_true", help="Time on a block made in seconds (simple_block) "
                    "instead of bench_shrub's scene.")
    ap.add_argument("--only-speed", action="store_true", help="Only the speed table.")
    ap.add_argument("--isprs", action="store_true", help="Only the ISPRS filter test (../shared/data/isprs): every "
                    "sample alone, every method with its defaults, against the labels and the published figures.")
    ap.add_argument("--tiles", default=None, help="Only a block of real tiles with a provider's ground (a glob, "
                    "e.g. lasR's inst/extdata/bcts/*.laz), classified by `gistools ground` tile by tile.")
    ap.add_argument("--methods", default=None, help="Comma-separated methods (default: every one); on the real files, "
                    "names as the table prints them or a part of them (smrf, smrftin, CSF).")
    args = ap.parse_args(argv)
    announce("bench_ground")
    if smoke():  # the default alone (CSF takes minutes), a block of 200,000 points made in seconds
        args.methods = args.methods or "adaptive"
        args.points, args.simple_block, args.workdir = 2e5, True, workdir(args.workdir)
    if args.isprs:
        from gistools.lidar.ground import GROUND_METHODS

        isprs(args.methods.split(",") if args.methods else list(GROUND_METHODS))
        return 0
    rng = np.random.default_rng(2012)
    only = args.methods.split(",") if args.methods else None
    if args.tiles:
        import glob

        files = sorted(Path(f) for f in glob.glob(args.tiles))
        if not files:
            print(f"bench_ground: no tile matches {args.tiles}", file=sys.stderr)
            return 1
        print(f"{len(files)} tiles: {args.tiles} (whole run's time, points read and written included)")
        print("| method | type I | type II | total | DEM RMSE (m) | DEM bias (m) | DEM p95 (m) | M points/s |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|")
        for r in tiles_quality(files, only or ("adaptive", "smrf", "smrftin")):
            print(f"| {r['method']} | {r['type I']:.3f} | {r['type II']:.3f} | {r['total']:.3f} | {r['RMSE m']:.3f} | "
                  f"{r['bias m']:+.3f} | {r['p95 m']:.3f} | {r['Mpts/s']:.2f} |")
        return 0
    print("| file | method | type I | type II | total | DEM RMSE (m) | DEM bias (m) | DEM p95 (m) | noise found | "
          "real as noise | M points/s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, path in ({} if args.only_speed else FILES).items():
        if not path.exists():
            print(f"| {label} | (missing: {path}) |")
            continue
        for r in quality(path, rng, only):
            print(f"| {label} | {r['method']} | {r['type I']:.3f} | {r['type II']:.3f} | {r['total']:.3f} | {r['RMSE m']:.3f} | "
                  f"{r['bias m']:+.3f} | "
                  f"{r['p95 m']:.3f} | {r['noise found']:.1%} | {r['real as noise']:.2%} | {r['Mpts/s']:.2f} |")
    if not args.no_speed:
        print()
        print("| gistools ground on the block | points | seconds | M points/s | per job | CPU seconds | M points per CPU second |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        methods = [m for m in (only or ("smrf", "adaptive")) if m in ("smrf", "smrftin", "adaptive")] or ["adaptive"]
        for method, jobs, seconds, n, cpu in speed(Path(args.workdir), args.points, methods, args.simple_block):
            print(f"| --method {method} --jobs {jobs} | {n:,} | {seconds:.1f} | {n / seconds / 1e6:.2f} | "
                  f"{n / seconds / 1e6 / jobs:.2f} | {cpu:.1f} | {n / cpu / 1e6:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
