#!/usr/bin/env python3
"""Throughput of the whole shrub chain (``gistools shrub``) against DSM + DEM alone, and a county projection.

Generates (once, cached in --workdir) a 4 x 4 block of 5000 ft tiles (the Levy tile size) with
--points points in all (synthetic scene: rolling ground, roads, a river, a pond, wetland, shrub
crowns in three bands and three covers, trees, buildings; LAS 1.2, EPSG:2882) and its breakline
GeoPackage. Then runs, each in a fresh process: ``gistools rasters`` (DSM + TIN DEM + nDSM) and
``gistools shrub`` with --jobs 1 and --jobs 2, and prints points per second, the peak memory of each run (its
process and workers), the chain / rasters ratio (target >= 0.5) and the projected time of a 733-tile county of the
same density (target < 20 min; at the Levy density, < 10 min), with the seconds by stage from the reports' own
timers.

    python benchmarks/bench_shrub.py [--points 40e6] [--workdir /tmp/gistools-bench-shrub]
    python benchmarks/bench_shrub.py --levy [--repeat 3]    # 16 tiles at the Levy delivery's 4 ft pulse spacing
    python benchmarks/bench_shrub.py --levy --code /path/to/other/checkout   # time another commit with this script

The county projection is made twice: at the 16-tile throughput (per-run costs counted 46 times over) and from
the 8-tile and 16-tile runs apart (a cost a tile plus a cost a run, each measured).

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): the same runs on 2 x 2 tiles of 300 ft (about 6,000 points), one repeat.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, workdir  # noqa: E402

PY = sys.executable
CODE = ROOT  # the gistools checkout the runs time (--code: another one, e.g. an earlier commit, with this script)
TILE_FT = scaled(5000.0, 300.0)
SIDE = scaled(4, 2)  # tiles a side of the block
TILES = SIDE * SIDE
COUNTY_TILES = 733


def generate(work: Path, points: float) -> dict:
    import pyproj
    from shapely.geometry import box

    from gistools.io.points import write_tile
    from gistools.synthetic import make_scene, scene_points, write_breaklines

    meta = work / "block.json"
    if meta.exists():
        info = json.loads(meta.read_text())
        if info["points_target"] == points and info["points"] >= points:
            return info
    crs = pyproj.CRS.from_epsg(2882)
    spacing = math.sqrt(TILES * TILE_FT * TILE_FT * 1.02 / points)  # ft between pulses, about 1.03 returns each
    origin = (400000.0, 1800000.0)
    tiles = work / "tiles"
    tiles.mkdir(parents=True, exist_ok=True)
    scene = make_scene(origin, (SIDE * TILE_FT, SIDE * TILE_FT), seed=7)
    total, footprints = 0, []
    for i in range(SIDE):
        for j in range(SIDE):
            w, s = origin[0] + i * TILE_FT, origin[1] + j * TILE_FT
            p = scene_points(scene, (w, s, w + TILE_FT, s + TILE_FT), spacing=spacing, seed=10 * i + j)
            total += len(p["x"])
            write_tile(tiles / f"t{i}{j}.las", p, crs, version="1.2", point_format=1, offsets=[w, s, 0],
                       vertical_epsg=6360, overwrite=True)
            footprints.append({"TILE_ID": 10 * i + j, "geometry": box(w, s, w + TILE_FT, s + TILE_FT)})
            del p
    gpkg = work / "breaklines.gpkg"
    if gpkg.exists():
        gpkg.unlink()
    write_breaklines(scene, footprints, gpkg, crs)
    info = {"points_target": points, "points": total, "spacing_ft": spacing}
    meta.write_text(json.dumps(info))
    return info


PEAK = """
def peak_mb():
    \"\"\"The largest resident memory of this process and of every process it started (the workers), in MB:
    VmHWM where /proc has it, else ru_maxrss; None without the resource module (Windows).\"\"\"
    try:
        import resource
    except ImportError:
        return None
    scale = 1 / 2**20 if sys.platform == "darwin" else 1 / 1024  # bytes on macOS, KiB elsewhere
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * scale
    try:
        with open("/proc/self/status") as fh:  # ru_maxrss of this process may carry its parent's across exec
            own = next(int(line.split()[1]) for line in fh if line.startswith("VmHWM")) / 1024
    except OSError:
        own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale
    return max(own, kids)
"""


def run_child(code: str) -> dict:
    full = ("import json, sys, time\nsys.path.insert(0, %r)\n" % str(CODE) + PEAK + "\nif __name__ == '__main__':\n"
            + textwrap.indent(textwrap.dedent(code), "    "))
    out = subprocess.run([PY, "-c", full], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def chain_run(kind: str, inputs: list, out: Path, jobs: int, vectors: dict) -> dict:
    """``gistools rasters`` or ``gistools shrub`` in a fresh process: seconds and the report's stage_seconds."""
    call = ("from gistools import rasters_from_tiles as run\n        kw = {}" if kind == "rasters" else
            f"from gistools.products.shrub import shrub_from_tiles as run\n        kw = {vectors!r}")
    return run_child(f"""
        {call}
        from gistools.engine.batch import worker_thread_environment
        worker_thread_environment()  # as the command line does for its workers
        t = time.perf_counter()
        s = run({[str(i) for i in inputs]!r}, {str(out)!r}, jobs={jobs}, overwrite=True, **kw)
        assert s["counts"]["failed"] == 0
        seconds = time.perf_counter() - t
        import multiprocessing
        for child in multiprocessing.active_children():  # reaped, so that RUSAGE_CHILDREN counts them
            child.join()
        print(json.dumps({{"seconds": seconds, "stages": s.get("stage_seconds", {{}}), "peak_mb": peak_mb()}}))
    """)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=float, default=None, help="points in the 16 tiles (default 40e6; --levy 25.5e6)")
    ap.add_argument("--workdir", default=None,
                    help="default /tmp/gistools-bench-shrub (--levy: /tmp/gistools-bench-levy16)")
    ap.add_argument("--levy", action="store_true", help="the Levy delivery's density: 4 ft pulse spacing (25.5e6 points)")
    ap.add_argument("--repeat", type=int, default=1, help="run the 8- and 16-tile --jobs 2 runs this many times each, "
                                                          "alternating, and project from their medians")
    ap.add_argument("--code", default=None, help="the gistools checkout to time (default: this one)")
    args = ap.parse_args(argv)
    announce("bench_shrub")
    args.repeat = scaled(args.repeat, 1)
    global CODE
    CODE = Path(args.code).resolve() if args.code else ROOT
    points = args.points or scaled(25.5e6 if args.levy else 40e6, 4e3 if args.levy else 6e3)
    work = Path(args.workdir or workdir("/tmp/gistools-bench-levy16" if args.levy else "/tmp/gistools-bench-shrub"))
    work.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    info = json.loads(subprocess.run(
        [PY, "-c", f"import json, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_shrub as b; "
                   f"from pathlib import Path; print(json.dumps(b.generate(Path({str(work)!r}), {points!r})))"],
        check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
    n = info["points"]
    print(f"block: {TILES} tiles of {TILE_FT:.0f} ft, {n:,} points, {info['spacing_ft']:.2f} ft pulse spacing, "
          f"{n / TILES / (TILE_FT / 5) ** 2:.2f} points per 5 ft cell [{time.perf_counter() - t:.0f} s to prepare]",
          flush=True)
    g = work / "breaklines.gpkg"
    vectors = dict(roads=f"{g}:ROADBREAKLINE", hydro=f"{g}:HYDROGRAPHICFEATURE", waterbodies=f"{g}:WATERBODY",
                   wetlands=f"{g}:WETLAND", tile_index=f"{g}:FOOTPRINT")
    tiles = sorted((work / "tiles").glob("*.las"))
    half = [f for f in tiles if int(f.stem[1]) < SIDE // 2]  # the western half: 8 tiles of 16, each with its neighbours
    rows = {}
    for jobs in (1, 2):
        for kind in ("rasters", "shrub"):
            r = rows[f"{kind} --jobs {jobs}"] = chain_run(kind, [work / "tiles"], work / f"out_{kind}{jobs}", jobs, vectors)
            sec = r["seconds"]
            stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages"].items())
            peak = f"{r['peak_mb']:6.0f} MB" if r.get("peak_mb") else "     - MB"
            print(f"{kind + ' --jobs ' + str(jobs):<20} {sec:8.1f} s  {n / sec / 1e6:6.2f} M pts/s  peak {peak}  733 "
                  f"tiles at {TILES}-tile "
                  f"throughput: {sec / TILES * COUNTY_TILES / 60:6.1f} min   [s by stage, summed: {stages}]", flush=True)
    print()
    for jobs in (1, 2):
        ratio = rows[f"rasters --jobs {jobs}"]["seconds"] / rows[f"shrub --jobs {jobs}"]["seconds"]
        print(f"--jobs {jobs}: whole chain / DSM+DEM throughput {ratio:.2f} (target >= 0.5)")
    # per-run costs (starting the workers, the map) measured apart: the 8-tile runs against the 16-tile ones; with
    # --repeat N, N of each, alternating, and their medians (a difference of two runs carries both runs' noise)
    print()
    for kind in ("rasters", "shrub"):
        t8s, t16s = [], [rows[f"{kind} --jobs 2"]["seconds"]]
        for k in range(args.repeat):
            t8s.append(chain_run(kind, half, work / f"out_{kind}8", 2, vectors)["seconds"])
            if k + 1 < args.repeat:
                t16s.append(chain_run(kind, [work / "tiles"], work / f"out_{kind}2", 2, vectors)["seconds"])
        t8, t16 = statistics.median(t8s), statistics.median(t16s)
        per_tile = (t16 - t8) / (TILES - len(half))
        per_run = t16 - TILES * per_tile
        runs = f" (medians of {args.repeat}: {', '.join(f'{v:.1f}' for v in t8s)}; {', '.join(f'{v:.1f}' for v in t16s)})" \
            if args.repeat > 1 else ""
        print(f"{kind} --jobs 2: {len(half)} tiles {t8:.1f} s, {TILES} tiles {t16:.1f} s{runs}: "
              f"{per_tile:.2f} s a tile + {per_run:.1f} s "
              f"a run; 733 tiles: {(per_run + COUNTY_TILES * per_tile) / 60:.1f} min ({TILES}-tile throughput: "
              f"{t16 / TILES * COUNTY_TILES / 60:.1f} min)", flush=True)


if __name__ == "__main__":
    main()
