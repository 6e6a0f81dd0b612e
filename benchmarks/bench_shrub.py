#!/usr/bin/env python3
"""Throughput of the whole shrub chain (``gistools shrub``) against DSM + DEM alone, and a county projection.

Generates (once, cached in --workdir) a 4 x 4 block of 5000 ft tiles (the Levy tile size) with
--points points in all (synthetic scene: rolling ground, roads, a river, a pond, wetland, shrub
crowns in three bands and three covers, trees, buildings; LAS 1.2, EPSG:2882) and its breakline
GeoPackage. Then runs, each in a fresh process: ``gistools rasters`` (DSM + TIN DEM + nDSM) and
``gistools shrub`` with --jobs 1 and --jobs 2, and prints points per second, the chain / rasters
ratio (target >= 0.5) and the projected time of a 733-tile county of the same density (target < 20 min).

    python benchmarks/bench_shrub.py [--points 40e6] [--workdir /tmp/gistools-bench-shrub]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
PY = sys.executable
TILE_FT = 5000.0
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
    spacing = math.sqrt(16 * TILE_FT * TILE_FT * 1.02 / points)  # ft between pulses, about 1.03 returns each
    origin = (400000.0, 1800000.0)
    tiles = work / "tiles"
    tiles.mkdir(parents=True, exist_ok=True)
    scene = make_scene(origin, (4 * TILE_FT, 4 * TILE_FT), seed=7)
    total, footprints = 0, []
    for i in range(4):
        for j in range(4):
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


def run_child(code: str) -> dict:
    full = "import json, sys, time\nsys.path.insert(0, %r)\nif __name__ == '__main__':\n" % str(ROOT) + \
        textwrap.indent(textwrap.dedent(code), "    ")
    out = subprocess.run([PY, "-c", full], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=float, default=40e6)
    ap.add_argument("--workdir", default="/tmp/gistools-bench-shrub")
    args = ap.parse_args(argv)
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    info = json.loads(subprocess.run(
        [PY, "-c", f"import json, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_shrub as b; "
                   f"from pathlib import Path; print(json.dumps(b.generate(Path({str(work)!r}), {args.points!r})))"],
        check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1])
    n = info["points"]
    print(f"block: 16 tiles of {TILE_FT:.0f} ft, {n:,} points, {info['spacing_ft']:.2f} ft pulse spacing "
          f"[{time.perf_counter() - t:.0f} s to prepare]", flush=True)
    g = work / "breaklines.gpkg"
    vectors = dict(roads=f"{g}:ROADBREAKLINE", hydro=f"{g}:HYDROGRAPHICFEATURE", waterbodies=f"{g}:WATERBODY",
                   wetlands=f"{g}:WETLAND", tile_index=f"{g}:FOOTPRINT")
    rows = {}
    for jobs in (1, 2):
        rows[f"rasters --jobs {jobs}"] = run_child(f"""
            from gistools import rasters_from_tiles
            t = time.perf_counter()
            s = rasters_from_tiles([{str(work / 'tiles')!r}], {str(work / f'out_r{jobs}')!r}, jobs={jobs}, overwrite=True)
            assert s["counts"]["failed"] == 0
            print(json.dumps({{"seconds": time.perf_counter() - t}}))
        """)
        rows[f"shrub --jobs {jobs}"] = run_child(f"""
            from gistools.tasks.shrub import shrub_from_tiles
            t = time.perf_counter()
            s = shrub_from_tiles([{str(work / 'tiles')!r}], {str(work / f'out_s{jobs}')!r}, jobs={jobs}, overwrite=True,
                                 **{vectors!r})
            assert s["counts"]["failed"] == 0
            print(json.dumps({{"seconds": time.perf_counter() - t}}))
        """)
        for k in (f"rasters --jobs {jobs}", f"shrub --jobs {jobs}"):
            sec = rows[k]["seconds"]
            print(f"{k:<20} {sec:8.1f} s  {n / sec / 1e6:6.2f} M pts/s  733 tiles: {sec / 16 * COUNTY_TILES / 60:6.1f} min",
                  flush=True)
    print()
    for jobs in (1, 2):
        ratio = rows[f"rasters --jobs {jobs}"]["seconds"] / rows[f"shrub --jobs {jobs}"]["seconds"]
        print(f"--jobs {jobs}: whole chain / DSM+DEM throughput {ratio:.2f} (target >= 0.5)")
    county = rows["shrub --jobs 2"]["seconds"] / 16 * COUNTY_TILES / 60
    print(f"projected 733-tile county, whole chain, --jobs 2: {county:.1f} min (target < 20 min)")


if __name__ == "__main__":
    main()
