#!/usr/bin/env python3
"""gistools beside the fastest peers, product by product, on the same tiles, cores and cell size.

Runs each product with gistools (its defaults: ``--jobs auto``) and with lasR (r-lidar/lasR, when ``Rscript`` can
load it; ``../shared/tools/build_lasr.sh`` builds it), alternately, ``--repeat`` times, each run a fresh process
timed from start to exit (the interpreter and library start included, as a user waits for them), and prints the
medians and the ratio lasR / gistools (above 1: gistools is faster).

Products (lasR's equivalent in brackets):

* rasters: DSM (highest first return) + DEM (TIN of the ground points) + nDSM
  [``rasterize(res, "max", filter = keep_first())`` + ``triangulate(filter = keep_ground())`` + ``rasterize(res, tin)``:
  lasR writes no nDSM];
* normalize: heights above the ground TIN, LAS out [``normalize()`` + ``write_las()``];
* metrics: count, z_max, z_mean, z_sd, z_p95 per cell [``rasterize(res, c(...))``];
* chm: gistools' pit-free CHM (Khosravipour et al. 2014, several TINs of the first returns' heights) [lasR's
  spike-free CHM of the same authors (Khosravipour et al. 2016), ``normalize()`` + ``spikefree(res, freeze)``, the
  freeze distance 3 x the pulse spacing as lasR advises];
* chm-p2r: the highest first return's height in each cell, both [``normalize()`` + ``rasterize(res, "max",
  filter = keep_first())``];
* ground: gistools' default ground filter, LAS out [``classify_with_csf()`` + ``write_las()``].

The tiles are read from copies in ``--workdir`` (lasR writes a ``.lax`` index beside the files it reads).
Cases: the sample tiles (4 LAS tiles, US survey feet, 5 ft cells), ``../shared/data``'s autzen tile alone and as a
2 x 2 block of copies side by side, a forest delivery's block (``forest``: 4 LAZ tiles, each 4 x 4 copies of
lidR's MixedConifer survey, 2.4 M real forest returns, metres, 1 m cells), and the synthetic Levy-density block (4
tiles of 5,000 ft, 6.8 M points) and a 16-tile block of its copies (27 M points), generated once into
``--workdir``.

A folder of real tiles of your own is a case too (``--delivery DIR``, 1 m cells): lasR's ``inst/extdata/bcts``
holds 4 LAZ tiles of a British Columbia forest delivery (2.8 M points), which the performance page shows.

    python benchmarks/bench_peers.py [--repeat 3] [--cases delivery,sample,autzen,autzen4,forest,levy,levy16]
                                     [--delivery DIR]
                                     [--products rasters,normalize,metrics,chm,chm-p2r,ground] [--jobs-table]

``--jobs-table`` also times ``gistools rasters`` with ``--jobs 1`` and ``--jobs 2`` beside the default (auto).

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): the sample case alone, the rasters alone, one repeat, without lasR.
"""

from __future__ import annotations

import argparse
import copy
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, smoke, workdir  # noqa: E402

SHARED = ROOT.parent / "shared" / "data" / "lidar"
PY = sys.executable
FEET = 1 / 0.3048  # every case is in feet (international or US survey: the same to 2 ppm)
CORES = 2

GISTOOLS = {
    "rasters": lambda src, out, cell: ["rasters", src, "--out", out, "--cell-size", cell],
    "normalize": lambda src, out, cell: ["normalize", src, "--out", out, "--format", "las"],
    "metrics": lambda src, out, cell: ["metrics", src, "--out", out, "--cell-size", cell, "--metrics",
                                       "count,z_max,z_mean,z_sd,z_p95"],
    "chm": lambda src, out, cell: ["chm", src, "--out", out, "--cell-size", cell],
    "chm-p2r": lambda src, out, cell: ["chm", src, "--out", out, "--cell-size", cell, "--method", "p2r"],
    "ground": lambda src, out, cell: ["ground", src, "--out", out, "--format", "las"],
}
LASR = {
    "rasters": 'reader() + rasterize({res}, "max", filter = keep_first(), ofile = file.path(out, "*_dsm.tif")) + '
               '(tri <- triangulate(filter = keep_ground())) + rasterize({res}, tri, ofile = file.path(out, "*_dtm.tif"))',
    "normalize": 'reader() + normalize() + write_las(file.path(out, "*.las"))',
    "metrics": 'reader() + rasterize({res}, c("count", "z_max", "z_mean", "z_sd", "z_p95"), '
               'ofile = file.path(out, "*_metrics.tif"))',
    # a CHM is heights above ground: lasR normalises first as gistools does
    "chm": 'reader() + normalize() + spikefree({res}, freeze_distance = {freeze}, ofile = file.path(out, "*_chm.tif"))',
    "chm-p2r": 'reader() + normalize() + rasterize({res}, "max", filter = keep_first(), '
               'ofile = file.path(out, "*_chm.tif"))',
    # CSF's lengths (0.5 m cloth, 0.5 m threshold) in the data's unit: {m} is a metre in CRS units
    "ground": 'reader() + classify_with_csf(cloth_resolution = 0.5 * {m}, class_threshold = 0.5 * {m}) + '
              'write_las(file.path(out, "*.las"))',
}


def lasr_available() -> bool:
    if not shutil.which("Rscript"):
        return False
    return subprocess.run(["Rscript", "-e", "library(lasR)"], capture_output=True).returncode == 0


def timed(cmd: list, env=None) -> float:
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    seconds = time.perf_counter() - t
    if proc.returncode != 0:
        raise SystemExit(f"bench_peers: {' '.join(map(str, cmd))[:200]} failed:\n{(proc.stderr or proc.stdout)[-1500:]}")
    return seconds


def gistools_cmd(product: str, src: Path, out: Path, cell: str, jobs: str | None = None) -> list:
    args = [PY, "-m", "gistools.cli.main", *GISTOOLS[product](str(src), str(out), cell), "--overwrite", "--quiet"]
    return args + (["--jobs", jobs] if jobs else [])


def pulse_spacing(files: list[Path]) -> float:
    """The mean distance between pulses (CRS units): the square root of the area per first return, from the
    headers (their extents and their counts of first returns)."""
    import laspy

    area = pulses = 0.0
    for path in files:
        with laspy.open(path) as f:
            h = f.header
            area += (h.maxs[0] - h.mins[0]) * (h.maxs[1] - h.mins[1])
            pulses += h.number_of_points_by_return[0] or h.point_count
    return (area / max(pulses, 1.0)) ** 0.5


def lasr_cmd(product: str, files: list[Path], out: Path, res: float, metre: float) -> list:
    strategy = f"concurrent_files({CORES})" if len(files) > 1 else f"concurrent_points({CORES})"
    freeze = round(3 * pulse_spacing(files), 3) if product == "chm" else 0
    script = (f'suppressMessages(library(lasR)); out <- "{out}"; dir.create(out, showWarnings = FALSE); '
              f'f <- c({", ".join(repr(str(p)) for p in files)}); '
              f'pipeline <- {LASR[product].format(res=res, m=metre, freeze=freeze)}; '
              f'invisible(exec(pipeline, on = f, ncores = {strategy}, progress = FALSE))')
    return ["Rscript", "-e", script]


def laspy_count(path: Path) -> int:
    import laspy

    with laspy.open(path) as f:
        return int(f.header.point_count)


def tiles_of(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in (".las", ".laz"))


def shifted_copies(sources: list[Path], into: Path, nx: int, ny: int) -> Path:
    """``nx`` x ``ny`` copies of the block ``sources`` side by side (each copy's x, y shifted by the block's
    extent), as LAS, unless already there."""
    import laspy
    import numpy as np

    into.mkdir(parents=True, exist_ok=True)
    if len(tiles_of(into)) == len(sources) * nx * ny:
        return into
    headers = [laspy.open(p).header for p in sources]
    west, south = min(h.mins[0] for h in headers), min(h.mins[1] for h in headers)
    east, north = max(h.maxs[0] for h in headers), max(h.maxs[1] for h in headers)
    width, height = np.ceil(east - west + 1), np.ceil(north - south + 1)
    for p in sources:
        las = laspy.read(p)
        for i in range(nx):
            for j in range(ny):  # the same integer records, the offsets moved by whole copies of the block
                header = copy.deepcopy(las.header)
                header.offsets = np.array(las.header.offsets) + np.array([i * width, j * height, 0])
                shifted = laspy.LasData(header)
                shifted.points = laspy.ScaleAwarePointRecord(las.points.array.copy(), header.point_format,
                                                             header.scales, header.offsets)
                shifted.write(into / f"{p.stem}_{i}{j}.las")
    return into


def forest_tiles(source: Path, into: Path, per_side: int = 4) -> Path:
    """A forest delivery's block from a real forest survey: 2 x 2 LAZ tiles, each ``per_side`` x ``per_side``
    copies of ``source`` side by side (its returns and provider classes; x, y shifted by whole copies), unless
    already there."""
    import laspy
    import numpy as np

    into.mkdir(parents=True, exist_ok=True)
    if len(tiles_of(into)) == 4:
        return into
    las = laspy.read(source)
    lo, hi = las.header.mins, las.header.maxs
    step = np.ceil(hi[:2] - lo[:2] + 1)  # whole metres: the shifted records stay on the file's lattice
    x, y = np.asarray(las.x), np.asarray(las.y)
    for a in range(2):
        for b in range(2):
            header = copy.deepcopy(las.header)
            tile = laspy.LasData(header)
            cells = [(a * per_side + i, b * per_side + j) for i in range(per_side) for j in range(per_side)]
            tile.points = laspy.ScaleAwarePointRecord(np.concatenate([las.points.array] * len(cells)),
                                                      header.point_format, header.scales, header.offsets)
            tile.x = np.concatenate([x + i * step[0] for i, _ in cells])
            tile.y = np.concatenate([y + j * step[1] for _, j in cells])
            tile.write(into / f"{source.stem}_{a}{b}.laz")
    return into


def delivery_case(folder: Path, work: Path) -> tuple[str, tuple]:
    """A folder of real tiles given with ``--delivery`` (lasR's ``inst/extdata/bcts``: 4 LAZ tiles of a forest
    delivery), copied into ``work`` (lasR writes its index beside the files), at 1 m cells."""
    from gistools.io.points import read_tile_info

    into = work / "delivery"
    into.mkdir(parents=True, exist_ok=True)
    tiles = tiles_of(folder)
    for tile in tiles:
        if not (into / tile.name).exists():
            shutil.copy(tile, into / tile.name)
    metre = 1 / read_tile_info(tiles[0]).unit.metres
    points = sum(laspy_count(p) for p in tiles)
    kind = tiles[0].suffix[1:].upper()
    name = f"delivery, {len(tiles)} real {kind} tiles ({folder.name}), {points / 1e6:.1f} M points, 1 m"
    return name, (into, "1m", metre, metre)


def cases(work: Path, wanted: list[str], delivery: Path | None = None) -> dict:
    """{case: (folder of tiles, cell size text, cell size in CRS units, a metre in CRS units)}; in a smoke run the
    sample alone."""
    wanted = scaled(wanted, ["sample"])
    found = {}
    if delivery is not None and "delivery" in wanted:
        name, case = delivery_case(delivery, work)
        found[name] = case
    if "sample" in wanted:  # copies: lasR writes a .lax index beside the files it reads
        sample = work / "sample"
        sample.mkdir(parents=True, exist_ok=True)
        for tile in tiles_of(ROOT / "sample_tiles"):
            if not (sample / tile.name).exists():
                shutil.copy(tile, sample / tile.name)
        found["sample (4 tiles, 0.3 M points)"] = (sample, "5ft", 5.0, FEET)
    autzen = SHARED / "autzen" / "autzen_trim.las"
    if autzen.exists() and "autzen" in wanted:
        one = work / "autzen1"
        one.mkdir(parents=True, exist_ok=True)
        if not (one / autzen.name).exists():
            shutil.copy(autzen, one / autzen.name)
        found["autzen, 1 real tile"] = (one, "5ft", 5.0, FEET)
    if autzen.exists() and "autzen4" in wanted:
        found["autzen, 2 x 2 copies"] = (shifted_copies([autzen], work / "autzen4", 2, 2), "5ft", 5.0, FEET)
    conifer = SHARED / "lidr" / "MixedConifer.laz"
    if conifer.exists() and "forest" in wanted:
        block = forest_tiles(conifer, work / "forest")
        points = sum(laspy_count(p) for p in tiles_of(block))
        found[f"forest, 4 LAZ tiles of MixedConifer copies, {points / 1e6:.1f} M points, 1 m"] = (block, "1m", 1.0, 1.0)
    if "levy" in wanted or "levy16" in wanted:
        import bench_rasters

        info = bench_rasters.generate_levy(work)
        if "levy" in wanted:
            found[f"Levy density, 4 tiles, {info['points'] / 1e6:.1f} M points"] = (work / "levy_las", "5ft", 5.0, FEET)
        if "levy16" in wanted:
            block = shifted_copies(tiles_of(work / "levy_las"), work / "levy16", 2, 2)
            found[f"Levy density, 16 tiles, {4 * info['points'] / 1e6:.1f} M points"] = (block, "5ft", 5.0, FEET)
    return found


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", default="delivery,sample,autzen,autzen4,forest,levy,levy16")
    ap.add_argument("--delivery", type=Path, default=None, help="A folder of real tiles for the delivery case "
                    "(e.g. lasR's inst/extdata/bcts: 4 LAZ tiles of a forest delivery, 2.8 M points).")
    ap.add_argument("--products", default="rasters,normalize,metrics,chm,chm-p2r,ground")
    ap.add_argument("--workdir", default=workdir("/tmp/gistools-bench"))
    ap.add_argument("--jobs-table", action="store_true")
    args = ap.parse_args(argv)
    announce("bench_peers")
    args.repeat = scaled(args.repeat, 1)
    args.products = scaled(args.products, "rasters")
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    peers = not smoke() and lasr_available()
    if not peers:
        print("smoke run: gistools alone" if smoke() else
              "lasR is not installed (Rscript -e 'library(lasR)' fails): gistools alone", flush=True)
    products = args.products.split(",")
    print(f"{CORES} cores; medians of {args.repeat} alternating runs; seconds from start to exit", flush=True)
    print("| case | product | gistools (auto) | lasR | lasR / gistools |", flush=True)
    print("|---|---|---:|---:|---:|", flush=True)
    jobs_rows = []
    for case, (folder, cell, res, metre) in cases(work, args.cases.split(","), args.delivery).items():
        files = tiles_of(folder)
        for product in products:
            ours, theirs = [], []
            for _ in range(args.repeat):
                ours.append(timed(gistools_cmd(product, folder, work / f"out_gistools_{product}", cell)))
                if peers:
                    out = work / f"out_lasr_{product}"
                    shutil.rmtree(out, ignore_errors=True)
                    theirs.append(timed(lasr_cmd(product, files, out, res, metre)))
            mo = statistics.median(ours)
            mt = statistics.median(theirs) if theirs else None
            print(f"| {case} | {product} | {mo:.2f} s | " + (f"{mt:.2f} s | {mt / mo:.2f}x |" if mt else "- | - |"),
                  flush=True)
        if args.jobs_table:
            runs = {"auto": [], "1": [], "2": []}
            for k in range(args.repeat):
                # the order turns each repeat: a run after the one-core run (--jobs 1) is faster than one after a
                # two-core run on this machine, by up to a tenth, whatever its own setting
                for jobs in [*runs][k % 3:] + [*runs][:k % 3]:
                    runs[jobs].append(timed(gistools_cmd("rasters", folder, work / "out_jobs", cell, jobs)))
            jobs_rows.append((case, {k: statistics.median(v) for k, v in runs.items()}))
    if jobs_rows:
        print("\n| case | rasters --jobs auto | --jobs 1 | --jobs 2 |\n|---|---:|---:|---:|")
        for case, m in jobs_rows:
            print(f"| {case} | {m['auto']:.2f} s | {m['1']:.2f} s | {m['2']:.2f} s |", flush=True)


if __name__ == "__main__":
    main()
