#!/usr/bin/env python3
"""Time of the whole structure reconstruction (``gistools structure``) on F4 scaled to about 100,000 points
(target < 30 s).

F4 is the spec's CCTV-like building (52 levels, podium, two leaning towers, bridge); --step 1.25 puts its
outline and plate points every 1.25 m instead of 10 m (93,860 points). Written once to --workdir as ``ID X Y Z``
text; the CLI (read, checks, voxel orders, parameters, levels, clusters, loops, matching, envelope, PLY,
OBJ, GeoPackage, figure, report) runs in a fresh process with its estimated parameters; the script prints
its wall time, the counts and the volume error.

    python benchmarks/bench_structure.py [--step 1.25] [--workdir /tmp/gistools-bench-structure]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): points every 10 m (the spec's own F4).
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
    ap.add_argument("--step", type=float, default=scaled(1.25, 10.0),
                    help="point spacing (m) along outlines and on plates")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-structure")))
    args = ap.parse_args()
    announce("bench_structure")
    args.workdir.mkdir(parents=True, exist_ok=True)
    src = args.workdir / f"f4_{args.step:g}.txt"
    if not src.exists():
        from gistools.structure.fixtures import building

        pts, _ = building("F4", step=args.step)
        tmp = src.with_suffix(".partial")
        tmp.write_text("\n".join(f"{i} {x:.4f} {y:.4f} {z:.4f}" for i, x, y, z in pts.itertuples(index=False)))
        tmp.replace(src)
        print(f"wrote {src} ({len(pts):,} points)")
    out = args.workdir / "out"
    cmd = [sys.executable, "-m", "gistools.cli.main", "structure", str(src), "--out", str(out), "--overwrite", "-q"]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t
    rep = json.loads((out / "report.json").read_text())
    print(f"structure, F4 at {args.step:g} m: {wall:.1f} s wall (pipeline {rep['seconds']:.1f} s); target < 30 s: "
          f"{'met' if wall < 30 else 'NOT met'}")
    print(f"  {rep['levels']} levels, {rep['clusters']} clusters ({rep['sowns']} sown), {rep['matched_pairs']} pairs, "
          f"{rep['triangles']:,} triangles, watertight {rep['watertight']}, Euler {rep['euler']}, "
          f"volume {rep['volume']:,.1f} m3 (error {100 * (rep['volume'] / 3_352_000 - 1):+.6f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
