#!/usr/bin/env python3
"""Throughput and memory of ``gistools rasters`` (DSM + TIN DEM + nDSM) against WhiteboxTools.

Generates (once, cached in --workdir) a block of 4 tiles totalling --points points
(synthetic scene: smooth rolling ground, roads, water, shrub and trees with up to 4
returns), as LAS and as LAZ, plus one tile of --big-tile points. Then runs, each in a
fresh process so peak RSS is its own:

* pure laspy decode of the same files (chunked, nothing else: the floor);
* gistools DSM + DEM (TIN) + nDSM from LAS and LAZ with --jobs 1 and --jobs 2;
* gistools DSM alone from LAZ, --jobs 1, against the decode throughput;
* WhiteboxTools (whitebox-workflows wheel) lidar_block_maximum + lidar_tin_gridding over
  the same LAS tiles, two tiles at a time (it uses mostly one core per tile here);
* gistools on the single big tile, for peak RSS.

Prints points per second, peak RSS per worker and the ratios the targets are stated in.

    python benchmarks/bench_rasters.py [--points 20e6] [--big-tile 20e6] [--workdir /tmp/gistools-bench] [--repeat 3]
    python benchmarks/bench_rasters.py --density levy [--repeat 3] [--laz14]   # the Levy delivery's density

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): the same runs on a tiny block (20,000 points at 5 ft pulse spacing;
Levy tiles of 300 ft), one repeat, without WhiteboxTools.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, smoke, workdir  # noqa: E402

CODE = ROOT  # the gistools checkout the runs time (--code: another one, e.g. an earlier commit, with this script)

PY = sys.executable


def generate(workdir: Path, points: float, big: float) -> dict:
    """Write the block (LAS and LAZ) and the big tile, unless already there."""
    import pyproj

    from gistools.io.points import write_tile
    from gistools.synthetic import make_scene, scene_points

    crs = pyproj.CRS.from_epsg(2882)
    spacing = scaled(1.0, 5.0)  # ft between pulses: about 11 pulses per m2, a modern ALS density (smoke: 5 ft)
    pts_per_pulse = 1.06  # measured on the scene (vegetation gives extra returns)
    tile = math.ceil(math.sqrt(points / 4 / pts_per_pulse) * spacing / 10) * 10
    meta = workdir / "block.json"
    if meta.exists():
        info = json.loads(meta.read_text())
        if info["points_target"] == points and info["big_target"] == big:
            return info
    for sub in ("las", "laz", "big"):
        (workdir / sub).mkdir(parents=True, exist_ok=True)
        for f in (workdir / sub).iterdir():
            f.unlink()
    origin = (430000.0, 1810000.0)
    scene = make_scene(origin, (2 * tile, 2 * tile), seed=1)
    total = 0
    for i in range(2):
        for j in range(2):
            w, s = origin[0] + i * tile, origin[1] + j * tile
            p = scene_points(scene, (w, s, w + tile, s + tile), spacing=spacing, seed=10 * i + j)
            total += len(p["x"])
            for sub, suffix in (("las", ".las"), ("laz", ".laz")):
                write_tile(workdir / sub / f"t{i}{j}{suffix}", p, crs, version="1.2", point_format=1, offsets=[w, s, 0])
            del p
    big_side = math.ceil(math.sqrt(big / pts_per_pulse) * spacing / 10) * 10
    bscene = make_scene(origin, (big_side, big_side), seed=2)
    p = scene_points(bscene, bscene.bounds, spacing=spacing, seed=3)
    big_points = len(p["x"])
    write_tile(workdir / "big" / "big.las", p, crs, version="1.2", point_format=1, offsets=[origin[0], origin[1], 0])
    del p
    info = {"points_target": points, "big_target": big, "points": total, "tile_ft": tile, "big_points": big_points,
            "big_ft": big_side}
    meta.write_text(json.dumps(info))
    return info


def generate_levy(workdir: Path) -> dict:
    """Four 5,000 ft tiles at the Levy County delivery's density (4 ft pulse spacing: about 1.7 M points a tile,
    1.6 points per 5 ft cell), LAS and LAZ, unless already there."""
    import pyproj

    from gistools.io.points import write_tile
    from gistools.synthetic import make_scene, scene_points

    meta = workdir / "levy.json"
    tile, spacing = scaled(5000, 300), 4.0
    if meta.exists() and json.loads(meta.read_text())["tile_ft"] == tile:
        return json.loads(meta.read_text())
    crs = pyproj.CRS.from_epsg(2882)
    origin = (430000.0, 1810000.0)
    scene = make_scene(origin, (2 * tile, 2 * tile), seed=5)
    total = 0
    for sub in ("levy_las", "levy_laz"):
        (workdir / sub).mkdir(parents=True, exist_ok=True)
    for i in range(2):
        for j in range(2):
            w, s = origin[0] + i * tile, origin[1] + j * tile
            p = scene_points(scene, (w, s, w + tile, s + tile), spacing=spacing, seed=100 + 10 * i + j)
            total += len(p["x"])
            for sub, suffix in (("levy_las", ".las"), ("levy_laz", ".laz")):
                write_tile(workdir / sub / f"t{i}{j}{suffix}", p, crs, version="1.2", point_format=1, offsets=[w, s, 0])
            del p
    info = {"points": total, "tile_ft": tile, "spacing_ft": spacing}
    meta.write_text(json.dumps(info))
    return info


def generate_laz14(workdir: Path) -> None:
    """The Levy block again as LAS 1.4 point format 6 LAZ, with the fields a delivery of today carries: GPS time
    (rising along the file), intensity (by class, with noise), scan angle and point source (flight lines 1,500 ft
    wide, east to west), unless already there."""
    import laspy
    import numpy as np

    out = workdir / "levy_laz14"
    if out.is_dir() and len(list(out.glob("*.laz"))) == 4:
        return
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(14)
    for src in sorted((workdir / "levy_las").glob("*.las")):
        las = laspy.read(src)
        header = laspy.LasHeader(point_format=6, version="1.4")
        header.scales, header.offsets = las.header.scales, las.header.offsets
        header.add_crs(las.header.parse_crs())
        new = laspy.LasData(header)
        n = len(las.points)
        new.X, new.Y, new.Z = las.X, las.Y, las.Z
        for name in ("classification", "return_number", "number_of_returns"):
            setattr(new, name, np.asarray(getattr(las, name)))
        line = np.floor((np.asarray(las.x) - 430000.0) / 1500.0)
        new.point_source_id = (line + 1).astype(np.uint16)
        new.scan_angle = np.clip(((np.asarray(las.x) - 430000.0) % 1500.0 - 750.0) / 750.0 * 2000, -30000, 30000).astype(np.int16)
        new.gps_time = 3.0e8 + np.arange(n) * 2e-6 + rng.uniform(0, 1e-7, n)
        base = np.where(np.asarray(las.classification) == 2, 900, 400)
        new.intensity = np.clip(base + rng.normal(0, 120, n), 0, 65535).astype(np.uint16)
        new.write(out / (src.stem + ".laz"))


def run_child(code: str) -> dict:
    """Run code in a fresh interpreter; it prints one JSON line, to which peak RSS is added."""
    prologue = textwrap.dedent(
        """
        import json, resource, sys, time
        sys.path.insert(0, %r)
        def _done(result):
            import multiprocessing
            for child in multiprocessing.active_children():  # workers exit on their own once done: reap them,
                child.join()                                  # so that RUSAGE_CHILDREN counts them
            # VmHWM: this process's own peak (ru_maxrss would carry the parent's peak across fork+exec)
            with open("/proc/self/status") as fh:
                self_mb = next(int(l.split()[1]) for l in fh if l.startswith("VmHWM")) / 1024
            kids_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # max over spawned workers
            result.update(rss_self_mb=self_mb, rss_children_mb=kids_mb)
            print(json.dumps(result))
        """ % str(CODE)
    )
    full = prologue + "\nif __name__ == '__main__':\n" + textwrap.indent(textwrap.dedent(code), "    ")
    out = subprocess.run([PY, "-c", full], capture_output=True, text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def decode(files) -> dict:
    return run_child(f"""
        import laspy
        t = time.perf_counter(); n = 0
        for f in {[str(f) for f in files]!r}:
            with laspy.open(f) as r:
                for pts in r.chunk_iterator(2_000_000):
                    n += len(pts)
                    pts.X, pts.Y, pts.Z, pts.classification, pts.return_number  # decode the fields we use
        _done(dict(seconds=time.perf_counter() - t, points=n))
    """)


def gistools_run(folder, out, jobs, products=("dsm", "dem", "ndsm")) -> dict:
    return run_child(f"""
        import shutil
        from gistools import rasters_from_tiles, RasterSettings
        from gistools.engine.batch import worker_thread_environment
        worker_thread_environment()  # as the command line does for its workers
        shutil.rmtree({str(out)!r}, ignore_errors=True)
        t = time.perf_counter()
        s = rasters_from_tiles([{str(folder)!r}], {str(out)!r}, RasterSettings(products={tuple(products)!r}), jobs={jobs})
        assert s["counts"]["failed"] == 0, s
        _done(dict(seconds=time.perf_counter() - t, points=sum(t["points"] for t in s["tiles"]),
                   stages=s["stage_seconds"]))
    """)


def heights_run(kind, folder, out, jobs, **settings) -> dict:
    """gistools normalize (LAS out) or gistools metrics on the block."""
    if kind == "normalize":
        call = (f"from gistools.products.normalize import NormalizeSettings as S, normalize_from_tiles as run\n"
                f"        settings = S(format='las', **{settings!r})")
    else:
        call = (f"from gistools.products.metrics import MetricsSettings as S, metrics_from_tiles as run\n"
                f"        settings = S(cell_size='5ft', **{settings!r})")
    return run_child(f"""
        import shutil
        {call}
        from gistools.engine.batch import worker_thread_environment
        worker_thread_environment()  # as the command line does for its workers
        shutil.rmtree({str(out)!r}, ignore_errors=True)
        t = time.perf_counter()
        s = run([{str(folder)!r}], {str(out)!r}, settings, jobs={jobs})
        assert s["counts"]["failed"] == 0, s
        _done(dict(seconds=time.perf_counter() - t))
    """)


def whitebox_available() -> bool:
    try:
        import whitebox_workflows  # noqa: F401
    except ImportError:
        return False
    return True


def whitebox_run(files, out: Path, cell: float, max_edge: float) -> dict:
    """WhiteboxTools: block maximum (DSM) + TIN gridding of ground, two tiles at a time (two processes)."""
    out.mkdir(parents=True, exist_ok=True)
    halves = [files[0::2], files[1::2]]
    code = """
import sys, time
import whitebox_workflows as wbw
wbe = wbw.WbEnvironment()
for f in sys.argv[2:]:
    lidar = wbe.read_lidar(f)
    grid = wbe.lidar.interpolation_gridding
    dsm = grid.lidar_block_maximum(input=lidar, resolution=%r)
    wbe.write_raster(dsm, sys.argv[1] + "/" + f.split("/")[-1] + ".dsm.tif")
    dem = grid.lidar_tin_gridding(input=lidar, resolution=%r, returns_included="all",
                                 excluded_classes=[c for c in range(19) if c != 2], max_triangle_edge_length=%r)
    wbe.write_raster(dem, sys.argv[1] + "/" + f.split("/")[-1] + ".dem.tif")
""" % (cell, cell, max_edge)
    t = time.perf_counter()
    procs = [subprocess.Popen([PY, "-c", code, str(out)] + [str(f) for f in h]) for h in halves if h]
    rc = [p.wait() for p in procs]
    if any(rc):
        raise RuntimeError(f"whitebox-workflows failed: {rc}")
    return {"seconds": time.perf_counter() - t}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=float, default=scaled(20e6, 2e4), help="points in the 4-tile block")
    ap.add_argument("--big-tile", type=float, default=scaled(20e6, 1e4),
                    help="points in the single big tile (RSS check)")
    ap.add_argument("--workdir", default=workdir("/tmp/gistools-bench"))
    ap.add_argument("--skip-whitebox", action="store_true")
    ap.add_argument("--only-heights", action="store_true", help="only the normalize and metrics rows")
    ap.add_argument("--repeat", type=int, default=1, help="run gistools (--jobs 2) and WhiteboxTools alternately this "
                                                          "many times and compare the medians")
    ap.add_argument("--code", default=None, help="the gistools checkout to time (default: this one)")
    ap.add_argument("--density", choices=("dense", "levy"), default="dense",
                    help="dense: the 4-tile block of 1 pulse per ft2 (the README's table); levy: four 5,000 ft tiles at "
                         "the Levy delivery's 4 ft pulse spacing, beside WhiteboxTools, with the time by stage")
    ap.add_argument("--laz14", action="store_true",
                    help="with --density levy: also the block as LAS 1.4 point format 6 LAZ (GPS time, intensity, scan "
                         "angle, point source), of which pass 1 decodes only the layers it uses")
    args = ap.parse_args(argv)
    announce("bench_rasters")
    args.repeat = scaled(args.repeat, 1)
    if not args.skip_whitebox and (smoke() or not whitebox_available()):
        print("WhiteboxTools skipped: " + ("smoke run" if smoke() else
                                          "whitebox-workflows is not installed (pip install '.[bench]')"), flush=True)
        args.skip_whitebox = True
    global CODE
    CODE = Path(args.code).resolve() if args.code else ROOT
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    if args.density == "levy":
        return levy(work, args.skip_whitebox, args.repeat, args.laz14)
    t = time.perf_counter()
    info = json.loads(subprocess.run(
        [PY, "-c", f"import json, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_rasters as b; "
                   f"from pathlib import Path; print(json.dumps(b.generate(Path({str(work)!r}), {args.points!r}, {args.big_tile!r})))"],
        check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
    print(f"block: 4 tiles of {info['tile_ft']} ft, {info['points']:,} points (LAS and LAZ); "
          f"big tile: {info['big_points']:,} points  [{time.perf_counter() - t:.0f} s to prepare]", flush=True)
    las = sorted((work / "las").glob("*.las"))
    laz = sorted((work / "laz").glob("*.laz"))
    n = info["points"]
    rows = {}

    def show(name, r, npts=n):
        rows[name] = r
        # --jobs 1 works in the process itself; --jobs 2 in spawned workers (the parent only waits)
        rss = max(r.get("rss_self_mb", 0), r.get("rss_children_mb", 0)) if "rss_self_mb" in r else float("nan")
        print(f"{name:<44} {r['seconds']:8.2f} s  {npts / r['seconds'] / 1e6:7.2f} M pts/s  peak RSS/worker {rss:7.0f} MB", flush=True)

    show("laspy decode, LAS", decode(las))
    hag_metrics = ("count", "z_max", "z_p95", "hag_p95", "cover_above2m", "fuel_1_3m", "fhd")
    show("gistools normalize (HAG dimension), LAS, --jobs 2", heights_run("normalize", work / "las", work / "out_hag", 2))
    show("gistools metrics, default 7, LAS, --jobs 2", heights_run("metrics", work / "las", work / "out_m", 2))
    show("gistools metrics, 7 with heights, LAS, --jobs 2", heights_run("metrics", work / "las", work / "out_m", 2,
                                                                         metrics=hag_metrics))
    if args.only_heights:
        return
    show("laspy decode, LAZ", decode(laz))
    show("gistools DSM only, LAZ, --jobs 1", gistools_run(work / "laz", work / "out", 1, ("dsm",)))
    show("gistools DSM+DEM+nDSM, LAS, --jobs 1", gistools_run(work / "las", work / "out", 1))
    show("gistools DSM+DEM+nDSM, LAS, --jobs 2", gistools_run(work / "las", work / "out", 2))
    show("gistools DSM+DEM+nDSM, LAZ, --jobs 1", gistools_run(work / "laz", work / "out", 1))
    show("gistools DSM+DEM+nDSM, LAZ, --jobs 2", gistools_run(work / "laz", work / "out", 2))
    if not args.skip_whitebox:
        # same cell (5 ft) and triangle edge limit (2 x 15 m) as gistools' defaults
        show("WhiteboxTools block max + TIN, LAS, 2 at a time", whitebox_run(las, work / "wbt", 5.0, 2 * 15 / 0.3048006096))
        show("WhiteboxTools block max + TIN, LAZ, 2 at a time", whitebox_run(laz, work / "wbt", 5.0, 2 * 15 / 0.3048006096))
    show("gistools DSM+DEM+nDSM, one big LAS tile", gistools_run(work / "big", work / "out_big", 1), info["big_points"])
    print()
    rate = {k: (info["big_points"] if "big" in k else n) / v["seconds"] for k, v in rows.items()}
    print(f"DSM alone from LAZ / pure LAZ decode:     {rate['gistools DSM only, LAZ, --jobs 1'] / rate['laspy decode, LAZ']:.2f}  (target >= 0.70)")
    if not args.skip_whitebox:
        for fmt in ("LAS", "LAZ"):
            wb = rate[f"WhiteboxTools block max + TIN, {fmt}, 2 at a time"]
            for jobs in (1, 2):
                k = f"gistools DSM+DEM+nDSM, {fmt}, --jobs {jobs}"
                print(f"{k} / WhiteboxTools ({fmt}):  {rate[k] / wb:.2f}  (target >= 3 with --jobs 2)")
    if args.repeat > 1 and not args.skip_whitebox:  # the ratio again as medians of alternating runs (see levy())
        for fmt, files in (("LAS", las), ("LAZ", laz)):
            ours = [rows[f"gistools DSM+DEM+nDSM, {fmt}, --jobs 2"]["seconds"]]
            theirs = [rows[f"WhiteboxTools block max + TIN, {fmt}, 2 at a time"]["seconds"]]
            for _ in range(args.repeat - 1):
                theirs.append(whitebox_run(files, work / "wbt", 5.0, 2 * 15 / 0.3048006096)["seconds"])
                ours.append(gistools_run(work / fmt.lower(), work / "out", 2)["seconds"])
            mo, mt = statistics.median(ours), statistics.median(theirs)
            print(f"{fmt}, --jobs 2, medians of {args.repeat} runs (alternating): gistools {mo:.2f} s "
                  f"({', '.join(f'{v:.2f}' for v in ours)}), WhiteboxTools {mt:.2f} s "
                  f"({', '.join(f'{v:.2f}' for v in theirs)}): {mt / mo:.2f}x (target >= 4)", flush=True)
    big = rows["gistools DSM+DEM+nDSM, one big LAS tile"]
    print(f"peak RSS, {info['big_points']:,}-point tile: {max(big['rss_self_mb'], big['rss_children_mb']):.0f} MB  (target < 1500 MB)")


def levy(work: Path, skip_whitebox: bool, repeat: int = 1, laz14: bool = False) -> None:
    """The rasters at the Levy density, LAS and LAZ, --jobs 2, beside WhiteboxTools, with gistools' stage timers;
    with ``repeat`` > 1 the two tools run alternately that many times and the medians are compared (this machine's
    speed moves by a fifth from one run to the next)."""
    t = time.perf_counter()
    info = json.loads(subprocess.run(
        [PY, "-c", f"import json, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_rasters as b; "
                   f"from pathlib import Path; print(json.dumps(b.generate_levy(Path({str(work)!r}))))"],
        check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
    n = info["points"]
    print(f"Levy block: 4 tiles of {info['tile_ft']} ft at {info['spacing_ft']} ft pulse spacing, {n:,} points "
          f"({n / 4 / (info['tile_ft'] / 5) ** 2:.2f} points per 5 ft cell)  [{time.perf_counter() - t:.0f} s to prepare]",
          flush=True)
    formats = ("las", "laz")
    if laz14:
        t = time.perf_counter()
        subprocess.run([PY, "-c", f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_rasters as b; "
                                  f"from pathlib import Path; b.generate_laz14(Path({str(work)!r}))"], check=True)
        print(f"the same as LAS 1.4 point format 6 LAZ with GPS time, intensity, scan angle and point source "
              f"[{time.perf_counter() - t:.0f} s to prepare]", flush=True)
        formats += ("laz14",)
    for fmt in formats:
        files = sorted((work / f"levy_{fmt}").glob("*.la[sz]"))
        label = {"laz14": "LAZ 1.4 PF 6"}.get(fmt, fmt.upper())
        ours, theirs = [], []
        for k in range(repeat):
            r = gistools_run(work / f"levy_{fmt}", work / "out_levy", 2)
            ours.append(r["seconds"])
            stages = ", ".join(f"{k} {v:.2f} s" for k, v in r["stages"].items())
            print(f"gistools DSM+DEM+nDSM, {label}, --jobs 2: {r['seconds']:.2f} s ({n / r['seconds'] / 1e6:.2f} M "
                  f"pts/s); summed over the tiles: {stages}", flush=True)
            if not skip_whitebox:
                wb = whitebox_run(files, work / "wbt_levy", 5.0, 2 * 15 / 0.3048006096)
                theirs.append(wb["seconds"])
                print(f"WhiteboxTools block max + TIN, {label}, 2 at a time: {wb['seconds']:.2f} s; gistools is "
                      f"{wb['seconds'] / r['seconds']:.2f}x (target >= 4)", flush=True)
        if repeat > 1 and theirs:
            mo, mt = statistics.median(ours), statistics.median(theirs)
            print(f"{label}, medians of {repeat} alternating runs: gistools {mo:.2f} s, WhiteboxTools {mt:.2f} s: "
                  f"{mt / mo:.2f}x (target >= 4)", flush=True)


if __name__ == "__main__":
    main()
