#!/usr/bin/env python3
"""Time of ``gistools travel`` on a 16-tile block: 4 x 4 copies of the sample's DEM mosaic and shrub classes (5 ft
cells, 1,600 x 1,600 = 2.56 M cells, 8,000 ft square), from two points last seen, 16 neighbours (target < 60 s).

The sample's chain (gistools shrub on sample_tiles/) runs once into --workdir; its dem.vrt and classes.vrt are
tiled 4 x 4 into GeoTIFFs there. The command then runs in a fresh process (read, speed model, graph, Dijkstra,
rasters, isochrone polygons, report); the script prints its wall time, the solve time report.json records and the
process's peak memory.

    python benchmarks/bench_travel.py [--copies 4] [--workdir /tmp/gistools-bench-travel]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): one copy (the sample's own 400 x 400 cells).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, workdir  # noqa: E402


def _block(workdir: Path, copies: int) -> tuple[Path, Path]:
    import numpy as np
    import rasterio
    from rasterio.transform import Affine

    from gistools.products.shrub import shrub_from_tiles

    chain = workdir / "chain"
    if not (chain / "classes.vrt").exists():
        b = ROOT / "sample_tiles" / "breaklines.gpkg"
        shrub_from_tiles(ROOT / "sample_tiles", chain, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                         waterbodies=f"{b}:WATERBODY", tile_index=f"{b}:FOOTPRINT", make_map=False)
    paths = []
    for name in ("dem", "classes"):
        target = workdir / f"{name}_{copies}x{copies}.tif"
        paths.append(target)
        if target.exists():
            continue
        with rasterio.open(chain / f"{name}.vrt") as src:
            data, profile = src.read(1), src.profile.copy()
            t = src.transform
            colormap = src.colormap(1) if name == "classes" else None
            units = src.units
        big = np.tile(data, (copies, copies))
        profile.update(driver="GTiff", width=big.shape[1], height=big.shape[0], tiled=True, blockxsize=256,
                       blockysize=256, compress="deflate", transform=Affine(t.a, t.b, t.c, t.d, t.e, t.f))
        with rasterio.open(target, "w", **profile) as dst:
            dst.write(big, 1)
            if name == "dem":
                dst.units = units
            if colormap:
                dst.write_colormap(1, colormap)
    return paths[0], paths[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--copies", type=int, default=scaled(4, 1), help="copies of the sample's mosaic along each side")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-travel")))
    args = ap.parse_args()
    announce("bench_travel")
    args.workdir.mkdir(parents=True, exist_ok=True)
    import rasterio

    dem, classes = _block(args.workdir, args.copies)
    out = args.workdir / "travel"
    with rasterio.open(dem) as src:  # the points last seen: (431000, 1811000) and (436000, 1805000) in 4 x 4 copies
        w, s, e, n = src.bounds
    second = f"{w + 0.75 * (e - w):.0f},{n - 0.875 * (n - s):.0f}"
    code = ("import resource, sys\nfrom gistools.cli.main import main\nsys.argv = sys.argv[1:]\ntry:\n    main()\n"
            "finally:\n    print('peak_rss_kb', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\n")
    cmd = [sys.executable, "-c", code, "gistools", "travel", str(out), "--dem", str(dem), "--classes", str(classes),
           "--from", "431000,1811000", "--from", second, "--overwrite", "-q"]
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        print(proc.stdout, proc.stderr, file=sys.stderr)
        return 1
    rep = json.loads((out / "report.json").read_text())
    peak = next(int(ln.split()[1]) for ln in proc.stderr.splitlines() if ln.startswith("peak_rss_kb"))
    print(proc.stdout.strip())
    print(f"cells: {rep['cells']:,} ({args.copies} x {args.copies} copies of the sample), {rep['neighbours']} neighbours")
    print(f"gistools travel wall time: {wall:.1f} s (target < 60 s); solve (graph + Dijkstra): {rep['solve_seconds']:.1f} s")
    print(f"peak memory: {peak / 1e6:.2f} GB (estimate {rep['graph_bytes_estimate'] / 1e9:.2f} GB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
