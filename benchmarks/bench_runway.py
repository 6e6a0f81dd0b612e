#!/usr/bin/env python3
"""Time of the whole runway pipeline (``gistools runway``) on a 3 km runway surveyed every 2 m (target < 20 s).

The survey is the design spec's synthetic runway (T8: lights every 15 m with planted anomalies, ground =
ICAO 4E template + 0.2 m + 0.5 sin(2 pi x / 1000) + noise) over 3 km, ground points every --grid m out to
+-300 m (about 450,000 points at 2 m), rotated to Monte Mario coordinates and written once to --workdir
as a CSV. The CLI (read, checks, frame, TIN ground, design, sections, volumes, Brueckner, GeoPackage,
design GeoTIFF, section CSV, diagrams, report) runs in a fresh process; the script prints its wall time.

    python benchmarks/bench_runway.py [--grid 2] [--workdir /tmp/gistools-bench-runway]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): ground every 20 m.
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--grid", type=float, default=scaled(2.0, 20.0), help="ground survey spacing (m)")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-runway")))
    args = ap.parse_args()
    announce("bench_runway")
    args.workdir.mkdir(parents=True, exist_ok=True)
    survey = args.workdir / f"survey_{args.grid:g}m.csv"
    if not survey.exists():
        from gistools.runway.synthetic import synthetic_runway

        t = time.perf_counter()
        points, _ = synthetic_runway(8, grid=args.grid, x_end=3005.0, half_width=300.0, lights=201)
        tmp = survey.with_suffix(".partial")
        points.to_csv(tmp, index=False)
        tmp.replace(survey)
        print(f"wrote {survey} ({len(points):,} points) in {time.perf_counter() - t:.1f} s")
    out = args.workdir / "out"
    cmd = [sys.executable, "-m", "gistools.cli.main", "runway", str(survey), "--code", "4E", "--crs", "EPSG:3003",
           "--out", str(out), "--overwrite", "-q"]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t
    rep = json.loads((out / "report.json").read_text())
    n = rep["points"]["lights"] + rep["points"]["other"]
    print(f"runway pipeline, 3 km x {args.grid:g} m survey ({n:,} points kept): {wall:.1f} s wall "
          f"(pipeline {rep['seconds']:.1f} s); target < 20 s: {'met' if wall < 20 else 'NOT met'}")
    print(f"  {rep['stations']} stations every {rep['spacing']:.2f} m; cut {rep['cut']:,.0f} m3, fill {rep['fill']:,.0f} m3, "
          f"removed {rep['removed']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
