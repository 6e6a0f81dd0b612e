#!/usr/bin/env python3
"""How the rasters' scheduling grows with the number of tiles (no tile is read).

For blocks of 1,000 / 10,000 / 100,000 synthetic square tiles (a square county of 5,000 ft tiles, one tile in
eight missing), the neighbour search (R-tree) and the two-pass schedule driven to the end as the engine does
(two tasks in flight, results in the order they were started), timed apart; then the growth exponent between
successive sizes (1.0 is linear, n log n reads a little above 1, all pairs would read 2).

With --resume N, the second figure: N tiny tiles (a few points each) made once with ``gistools rasters``, then
the rerun that finds every tile complete and has nothing to do, timed.

    python benchmarks/bench_schedule.py [--sizes 1000,10000,100000] [--resume 5000] [--workdir /tmp/gistools-bench-schedule]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): blocks of 100, 300 and 1,000 tiles; --resume makes 20 tiles.
"""

from __future__ import annotations

import argparse
import math
import random
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, workdir  # noqa: E402

from gistools.engine.schedule import TwoPassSchedule, neighbour_pairs  # noqa: E402

TILE = 5000.0  # ft
X0, Y0 = 500_000.0, 1_300_000.0  # ft: inside EPSG:2882 (Florida West, US survey feet), Citrus County


def block(n: int, seed: int = 0):
    side = math.ceil(math.sqrt(n * 8 / 7))
    rng = random.Random(seed)
    bounds = [(c * TILE, r * TILE, (c + 1) * TILE, (r + 1) * TILE) for r in range(side) for c in range(side)
              if rng.random() > 1 / 8][:n]
    return bounds


def schedule_block(bounds, buffer=100.0):
    names = [f"{i:07d}" for i in range(len(bounds))]
    t0 = time.perf_counter()
    pairs = neighbour_pairs(bounds, buffer)
    t1 = time.perf_counter()
    order = sorted(range(len(bounds)), key=lambda i: (-bounds[i][3], bounds[i][0]))
    deps = {names[i]: {names[i]} | {names[j] for j in pairs[i]} for i in range(len(bounds))}
    schedule = TwoPassSchedule([names[i] for i in order], set(names), deps)
    running, tasks = [], 0
    while True:
        while len(running) < 2 and (task := schedule.next_task(lambda n: False)) is not None:
            running.append(task)
        if not running:
            break
        schedule.done(*running.pop(0))
        schedule.releasable()
        tasks += 1
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, tasks, schedule.scratch_peak


def resume(n: int, workdir: Path) -> None:
    import laspy
    import numpy as np

    tiles = workdir / f"tiles{n}"
    out = workdir / f"out{n}"
    if not tiles.is_dir() or len(list(tiles.glob("*.las"))) != n:
        tiles.mkdir(parents=True, exist_ok=True)
        side = math.ceil(math.sqrt(n))
        for k in range(n):
            c, r = k % side, k // side
            header = laspy.LasHeader(point_format=1, version="1.2")
            header.scales, header.offsets = [0.01] * 3, [X0, Y0, 0]
            header.add_crs(__import__("pyproj").CRS(2882))
            las = laspy.LasData(header)
            xs = X0 + c * 100.0 + np.array([1.0, 50.0, 99.0, 50.0])
            ys = Y0 + r * 100.0 + np.array([1.0, 50.0, 1.0, 99.0])
            las.x, las.y, las.z = xs, ys, np.full(4, 10.0)
            las.classification = np.full(4, 2, np.uint8)
            las.write(tiles / f"{k:06d}.las")
    cmd = [sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles), "--out", str(out), "-q", "--cell-size", "10ft"]
    if not (out / "report.json").exists():
        t = time.perf_counter()
        subprocess.run(cmd, check=True)
        print(f"first run of {n} tiles: {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    subprocess.run(cmd, check=True)
    print(f"resuming the finished folder of {n} tiles (nothing to do): {time.perf_counter() - t:.1f} s")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default=scaled("1000,10000,100000", "100,300,1000"))
    ap.add_argument("--resume", type=int, default=0, help="also time resuming a finished folder of this many tiles")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-schedule")))
    args = ap.parse_args()
    announce("bench_schedule")
    if args.resume:
        args.resume = scaled(args.resume, 20)
    rows = []
    print(f"{'tiles':>8} {'neighbours s':>13} {'schedule s':>11} {'tasks':>8} {'scratch peak':>13}")
    for n in (int(v) for v in args.sizes.split(",")):
        search, schedule, tasks, peak = schedule_block(block(n))
        rows.append((n, search + schedule))
        print(f"{n:>8,} {search:>13.3f} {schedule:>11.3f} {tasks:>8,} {peak:>13,}")
    for (n0, t0), (n1, t1) in zip(rows, rows[1:]):
        print(f"growth {n0:,} -> {n1:,}: exponent {math.log(t1 / t0) / math.log(n1 / n0):.2f} (1 linear, 2 all pairs)")
    if args.resume:
        resume(args.resume, args.workdir)


if __name__ == "__main__":
    main()
