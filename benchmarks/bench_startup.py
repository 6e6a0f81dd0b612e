"""Start-up of the command line: the wall time of ``gistools --help``, ``gistools --version``, a command's
``--help`` and a run on one small tile, each a fresh interpreter (medians of repeats), beside the floor that no
command can go under: the interpreter alone and the imports of the libraries a run needs (numpy, rasterio,
pyproj, laspy).

    python benchmarks/bench_startup.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _smoke import announce, scaled  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TILE = ROOT / "sample_tiles" / "35813.laz"


def seconds(args: list[str], repeats: int) -> float:
    """The median wall time of running ``args``, in seconds."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        subprocess.run(args, check=True, capture_output=True, cwd=ROOT)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main(argv=None) -> int:
    announce("bench_startup")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=scaled(7, 1))
    args = ap.parse_args(argv)
    py = [sys.executable]
    gistools = py + ["-m", "gistools.cli.main"]
    with tempfile.TemporaryDirectory() as tmp:
        rows = [
            ("python -c pass (the interpreter)", py + ["-c", "pass"]),
            ("import numpy, rasterio, pyproj, laspy (a run's floor)",
             py + ["-c", "import numpy, rasterio, pyproj, laspy"]),
            ("gistools --help", gistools + ["--help"]),
            ("gistools --version", gistools + ["--version"]),
            ("gistools rasters --help", gistools + ["rasters", "--help"]),
            ("gistools rasters (one 64 k-point tile, 6 ft)",
             gistools + ["rasters", str(TILE), "--out", f"{tmp}/out", "--cell-size", "6ft", "-q", "--overwrite"]),
        ]
        print(f"{'what':58s} {'seconds':>8s}")
        for label, command in rows:
            print(f"{label:58s} {seconds(command, args.repeats):8.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
