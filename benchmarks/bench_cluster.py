"""What a dask.distributed cluster costs a run per tile: a scheduler and ten single-thread workers (separate
processes on loopback, as on a cluster's machines) make 100 small synthetic tiles with ``gistools rasters
--scheduler``; the same tiles run on this machine (``--jobs 1``) for comparison, and empty tasks measure Dask's own
round trip.

    python benchmarks/bench_cluster.py [--tiles 100] [--workers 10]

The scheduling cost per tile is the cores' time a run on warm workers spends beside the tiles' own work (their
seconds in the local run's report) and the run's own costs (the local run's wall time beyond its tiles), shared
over the tiles: ((wall - the run's own costs) x the cores the workers share - the tiles' seconds) / tiles; it
counts a core left idle as spent. The first run on the cluster also pays each worker's import of gistools. Every
run's rasters are compared with the local run's (they must be equal).
"""

from __future__ import annotations

import argparse
import json
import math
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _smoke import announce, scaled  # noqa: E402

X0, Y0 = 500_000.0, 1_300_000.0  # US survey feet, inside EPSG:2882 (Florida West), Citrus County


def make_tiles(folder: Path, n: int, points: int = 4000) -> None:
    """``n`` tiles of 100 ft a side on a rolling surface, ``points`` each (ground and a few higher returns)."""
    import laspy
    import numpy as np
    import pyproj

    folder.mkdir(parents=True)
    side = math.ceil(math.sqrt(n))
    rng = np.random.default_rng(0)
    for k in range(n):
        c, r = k % side, k // side
        header = laspy.LasHeader(point_format=1, version="1.2")
        header.scales, header.offsets = [0.01] * 3, [X0, Y0, 0]
        header.add_crs(pyproj.CRS(2882))
        las = laspy.LasData(header)
        x = X0 + c * 100.0 + rng.uniform(0, 100, points)
        y = Y0 + r * 100.0 + rng.uniform(0, 100, points)
        ground = 100 + 5 * np.sin(x / 40.0) + 3 * np.cos(y / 55.0)
        high = rng.random(points) < 0.2
        las.x, las.y, las.z = x, y, ground + np.where(high, rng.uniform(1, 30, points), 0.0)
        las.classification = np.where(high, 1, 2).astype(np.uint8)
        las.write(folder / f"{k:04d}.las")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_cluster(workers: int):
    """(address, processes): a scheduler and ``workers`` single-thread workers on loopback."""
    from dask.distributed import Client

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).parent / "dask")
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              **quiet)]
    time.sleep(1.5)
    procs += [subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-dashboard"], **quiet)
              for _ in range(workers)]
    with Client(address, timeout=60) as client:
        client.wait_for_workers(workers, timeout=300)
    return address, procs


def stop_cluster(procs) -> None:
    for p in procs[::-1]:
        p.terminate()
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def run(tiles: Path, out: Path, *extra) -> tuple[float, float]:
    """(wall seconds, the sum of the tiles' own seconds from report.json) of one ``gistools rasters`` run."""
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "gistools.cli.main", "rasters", str(tiles), "--out", str(out), "-q",
                    "--cell-size", "3ft", *extra], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - started
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    return wall, sum(float(t.get("seconds") or 0.0) for t in report.get("tiles", []))


def empty_round_trip(address: str, tasks: int) -> float:
    """Seconds a task of Dask's own (nothing to do), submitted all at once and gathered, on this cluster."""
    from dask.distributed import Client

    with Client(address, timeout=60) as client:
        started = time.perf_counter()
        client.gather(client.map(int, range(tasks), pure=False))
        return (time.perf_counter() - started) / tasks


def same_rasters(a: Path, b: Path) -> bool:
    import numpy as np

    from gistools.io.raster import read_raster

    return all(np.array_equal(read_raster(a / f"{p}.vrt")[0], read_raster(b / f"{p}.vrt")[0], equal_nan=True)
               for p in ("dsm", "dem", "ndsm"))


def main(argv=None) -> int:
    announce("bench_cluster")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tiles", type=int, default=scaled(100, 6))
    ap.add_argument("--workers", type=int, default=scaled(10, 2))
    args = ap.parse_args(argv)
    try:
        import distributed  # noqa: F401
    except ImportError:
        print("bench_cluster needs dask.distributed: pip install 'gistools[dask]'", file=sys.stderr)
        return 1
    from gistools.machine import usable_cpus

    cores = min(args.workers, usable_cpus())
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        make_tiles(tmp / "tiles", args.tiles)
        local_wall, local_work = run(tmp / "tiles", tmp / "local", "--jobs", "1")
        address, procs = start_cluster(args.workers)
        try:
            cold, _ = run(tmp / "tiles", tmp / "cold", "--scheduler", address)  # each worker imports gistools
            warm, _ = run(tmp / "tiles", tmp / "warm", "--scheduler", address)
            task = empty_round_trip(address, 1000 if args.tiles > 10 else 20)
        finally:
            stop_cluster(procs)
        equal = all(same_rasters(tmp / "local", tmp / name) for name in ("cold", "warm"))
    print(f"{args.tiles} tiles, {args.workers} single-thread workers sharing {cores} cores")
    print(f"{'run':48s} {'wall s':>8s} {'s / tile':>9s}")
    print(f"{'this machine, --jobs 1 (the tiles alone: %.2f s)' % local_work:48s} {local_wall:8.2f} "
          f"{local_wall / args.tiles:9.3f}")
    print(f"{'the cluster, first run (workers import gistools)':48s} {cold:8.2f} {cold / args.tiles:9.3f}")
    print(f"{'the cluster, next run':48s} {warm:8.2f} {warm / args.tiles:9.3f}")
    fixed = local_wall - local_work  # a run's own costs (start, planning, mosaics, report), paid once either way
    cost = ((warm - fixed) * cores - local_work) / args.tiles
    print(f"scheduling cost per tile: {cost * 1000:.0f} ms of the cores' time beside the tile's own work "
          f"(Dask's empty task, 1000 at once: {task * 1000:.1f} ms each); the workers' start: {cold - warm:.1f} s; "
          f"rasters equal to the local run's: {equal}")
    return 0 if equal else 1


if __name__ == "__main__":
    sys.exit(main())
