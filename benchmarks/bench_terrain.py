#!/usr/bin/env python3
"""Time of ``gistools terrain`` (slope, slope percent, aspect, hillshade, TRI in one pass) against GDAL's gdaldem (five
runs, one per product) on the same VRT mosaic of DEM tiles (target: gistools no slower).

The mosaic is --tiles x --tiles GeoTIFF tiles of --size cells a side of a synthetic terrain (hills and noise,
float32, nodata -9999, in US survey feet), written once to --workdir with a VRT. Both write tiled DEFLATE GeoTIFFs
(level 1, floating-point predictor, as gistools' rasters; gdaldem's hillshade is bytes: horizontal predictor). The script prints both wall times and their ratio.

    python benchmarks/bench_terrain.py [--tiles 3] [--size 2000] [--workdir /tmp/gistools-bench-terrain]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): tiles of 100 x 100 cells, and exit status 0 whichever is faster.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, smoke, workdir  # noqa: E402

GDALDEM_RUNS = {"slope": ["slope"], "slope_percent": ["slope", "-p"], "aspect": ["aspect"], "hillshade": ["hillshade"],
                "tri": ["TRI", "-alg", "Riley"]}
CREATION = ["-co", "TILED=YES", "-co", "COMPRESS=DEFLATE", "-co", "ZLEVEL=1", "-co", "BLOCKXSIZE=256", "-co",
            "BLOCKYSIZE=256"]


def make_mosaic(workdir: Path, tiles: int, size: int, cell: float = 5.0) -> Path:
    import rasterio
    from rasterio.transform import from_origin

    vrt = workdir / f"dem_{tiles}x{size}.vrt"
    if vrt.exists():
        return vrt
    from gistools.io.raster import write_vrt

    rng = np.random.default_rng(0)
    crs = rasterio.crs.CRS.from_epsg(2882)
    paths = []
    n = tiles * size
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    for r in range(tiles):
        for c in range(tiles):
            gx, gy = (xx + c * size) / n, (yy + r * size) / n
            z = (200 + 80 * np.sin(6 * gx) * np.cos(5 * gy) + 30 * np.sin(23 * gx + 11 * gy)
                 + rng.normal(0, 0.3, (size, size))).astype(np.float32)
            z[rng.random((size, size)) < 1e-4] = -9999
            path = workdir / f"dem_{tiles}x{size}_{r}_{c}.tif"
            with rasterio.open(path, "w", driver="GTiff", width=size, height=size, count=1, dtype="float32", crs=crs,
                               transform=from_origin(500000 + c * size * cell, 600000 - r * size * cell, cell, cell),
                               nodata=-9999, tiled=True, blockxsize=256, blockysize=256, compress="deflate") as dst:
                dst.write(z, 1)
                dst.units = ("ftUS",)
            paths.append(path)
    return write_vrt(vrt, paths)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tiles", type=int, default=3, help="tiles a side of the mosaic")
    ap.add_argument("--size", type=int, default=scaled(2000, 100), help="cells a side of a tile")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-terrain")))
    args = ap.parse_args()
    announce("bench_terrain")
    args.workdir.mkdir(parents=True, exist_ok=True)
    gdaldem = shutil.which("gdaldem")
    if gdaldem is None:
        print("gdaldem is not installed")
        return 1
    vrt = make_mosaic(args.workdir, args.tiles, args.size)
    from gistools.products.terrain import terrain_from_dem

    ours_dir, theirs_dir = args.workdir / "gistools", args.workdir / "gdaldem"
    shutil.rmtree(ours_dir, ignore_errors=True)
    shutil.rmtree(theirs_dir, ignore_errors=True)
    theirs_dir.mkdir()
    t0 = time.perf_counter()
    terrain_from_dem(vrt, ours_dir)
    ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    for product, (mode, *extra) in GDALDEM_RUNS.items():
        subprocess.run([gdaldem, mode, str(vrt), str(theirs_dir / f"{product}.tif"), "-q", *extra, *CREATION, "-co",
                        f"PREDICTOR={2 if mode == 'hillshade' else 3}"], check=True)
    theirs = time.perf_counter() - t0
    cells = (args.tiles * args.size) ** 2
    print(f"mosaic: {args.tiles} x {args.tiles} tiles of {args.size} x {args.size} cells ({cells / 1e6:.1f} M cells), "
          f"5 products")
    print(f"gistools terrain (one pass):  {ours:7.2f} s")
    print(f"gdaldem (5 runs):             {theirs:7.2f} s")
    print(f"gistools / gdaldem:           {ours / theirs:7.2f}")
    return 0 if ours <= theirs or smoke() else 2


if __name__ == "__main__":
    raise SystemExit(main())
