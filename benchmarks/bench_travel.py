#!/usr/bin/env python3
"""Time of ``gistools travel`` on a 16-tile block: 4 x 4 copies of the sample's DEM mosaic and shrub classes (5 ft
cells, 1,600 x 1,600 = 2.56 M cells, 8,000 ft square), from two points last seen, 16 neighbours (target < 60 s).

The sample's chain (gistools shrub on sample_tiles/) runs once into --workdir; its dem.vrt and classes.vrt are
tiled 4 x 4 into GeoTIFFs there. The command then runs in a fresh process (read, speed model, graph, Dijkstra,
rasters, isochrone polygons, report), twice: with the default memory limit (the whole grid's graph) and with
--max-memory BLOCKS_GB (the graph block by block); the script prints each run's wall time, the solve time
report.json records and the process's peak memory (and that of a process that only imports the command, to take
off), checks that both runs wrote the same minutes, and prints the bytes a cell of each route.

    python benchmarks/bench_travel.py [--copies 4] [--blocks-memory 0.5] [--workdir /tmp/gistools-bench-travel]

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


_PEAK = ("import resource, sys\nfrom gistools.cli.main import main\nsys.argv = sys.argv[1:]\ntry:\n    main()\n"
         "finally:\n    print('peak_rss_kb', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)\n")


# the libraries a travel run loads, then the command's help: the memory of a run before any cell
_IMPORTS = ("import numpy, scipy.sparse.csgraph, rasterio, pyogrio, geopandas, shapely\n"
            "import gistools.products.travel, gistools.io.raster, gistools.io.vector, gistools.vector.breaklines\n")


def _run(args: list[str], code: str = _PEAK) -> tuple[float, int, str] | None:
    """(wall seconds, peak RSS in bytes, stdout) of ``gistools ARGS`` in a fresh process; None when it failed."""
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code, "gistools", *args], capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        print(proc.stdout, proc.stderr, file=sys.stderr)
        return None
    peak = next(int(ln.split()[1]) for ln in proc.stderr.splitlines() if ln.startswith("peak_rss_kb"))
    return wall, peak * 1024, proc.stdout.strip()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--copies", type=int, default=scaled(4, 1), help="copies of the sample's mosaic along each side")
    ap.add_argument("--blocks-memory", type=float, default=scaled(0.5, 0.05),
                    help="--max-memory (GB) of the block-by-block run, below the whole graph's estimate")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-travel")))
    args = ap.parse_args()
    announce("bench_travel")
    args.workdir.mkdir(parents=True, exist_ok=True)
    import numpy as np
    import rasterio

    dem, classes = _block(args.workdir, args.copies)
    with rasterio.open(dem) as src:  # the points last seen: (431000, 1811000) and (436000, 1805000) in 4 x 4 copies
        w, s, e, n = src.bounds
    second = f"{w + 0.75 * (e - w):.0f},{n - 0.875 * (n - s):.0f}"
    common = ["--dem", str(dem), "--classes", str(classes), "--from", "431000,1811000", "--from", second,
              "--overwrite", "-q"]
    base = _run(["travel", "--help"], _IMPORTS + _PEAK)  # the interpreter and the libraries a run loads
    if base is None:
        return 1
    runs = {}
    for name, extra in (("whole", []), ("blocks", ["--max-memory", f"{args.blocks_memory:g}"])):
        out = args.workdir / f"travel_{name}"
        ran = _run(["travel", str(out), *common, *extra])
        if ran is None:
            return 1
        runs[name] = (*ran, json.loads((out / "report.json").read_text()), out)
    print(runs["whole"][2])
    rep = runs["whole"][3]
    cells = rep["cells"]
    if runs["blocks"][3]["solver"]["method"] != "blocks":
        print(f"--blocks-memory {args.blocks_memory:g} holds the whole graph: give less", file=sys.stderr)
        return 1
    print(f"cells: {cells:,} ({args.copies} x {args.copies} copies of the sample), {rep['neighbours']} neighbours; "
          f"a process importing the command peaks at {base[1] / 1e6:.0f} MB")
    for name, (wall, peak, said, rep, out) in runs.items():
        solver = rep["solver"]
        how = ("the whole grid's graph" if solver["method"] == "whole" else
               "block by block, blocks of {} x {} cells: {} solves of {} blocks".format(
                   *solver["block"], solver["block_solves"], solver["blocks"]))
        print(f"{name} (--max-memory {rep['settings']['max_memory']:g}): {how}")
        print(f"  wall time: {wall:.1f} s (target < 60 s); solve: {rep['solve_seconds']:.1f} s; peak memory "
              f"{peak / 1e6:.0f} MB (estimate {rep['memory_estimate'] / 1e6:.0f} MB), "
              f"{(peak - base[1]) / cells:.0f} bytes a cell above the imports")
    with rasterio.open(runs["whole"][4] / "travel_minutes.tif") as a, \
            rasterio.open(runs["blocks"][4] / "travel_minutes.tif") as b:
        same = np.array_equal(a.read(1), b.read(1))
    print(f"block by block {'equals' if same else 'DIFFERS FROM'} the whole grid's minutes")
    if not same:
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
