#!/usr/bin/env python3
"""Time of the whole aquifer model (``gistools aquifer model``) on 4 layers x --points contacts (target < 30 s).

The contacts follow the design spec's analytic aquifer (section 3b: LS, AU, AD, AQ over a 30 x 30 km
square, EPSG:3003) at --points random positions per layer, plus the four corners; written once to
--workdir as a CSV. The model (outliers, TINs, boundaries, matching, walls, meshes, exact overlay
volumes, thickness rasters, GeoPackage, figures, report.json) runs in a fresh process; the script
prints its wall time, the per-stage share from the run's own timer, and the volume errors against
the analytic values over the square.

    python benchmarks/bench_aquifer.py [--points 100000] [--workdir /tmp/gistools-bench-aquifer]

GISTOOLS_BENCH_SMOKE=1 (benchmarks/_smoke.py): 2,000 contacts per layer.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _smoke import announce, scaled, workdir  # noqa: E402


def make_contacts(path: Path, n: int, seed: int = 2012) -> None:
    from gistools.aquifer.synthetic import E0, N0, ID_BASE, LAYERS, surfaces_uv

    rng = np.random.default_rng(seed)
    frames = []
    corners = np.array([[0, 0], [30, 0], [30, 30], [0, 30]], float)
    for layer in LAYERS:
        uv = np.vstack([rng.uniform(0, 30, (n, 2)), corners])
        z = surfaces_uv(uv[:, 0], uv[:, 1])[layer]
        frames.append(pd.DataFrame({"id": ID_BASE[layer] * 1000 + 1 + np.arange(len(uv)), "x": E0 + 1000 * uv[:, 0],
                                    "y": N0 + 1000 * uv[:, 1], "z": z, "layer": layer}))
    tmp = path.with_suffix(".partial")
    pd.concat(frames).to_csv(tmp, index=False)
    tmp.replace(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=scaled(100_000, 2_000), help="contacts per layer")
    ap.add_argument("--workdir", type=Path, default=Path(workdir("/tmp/gistools-bench-aquifer")))
    args = ap.parse_args()
    announce("bench_aquifer")
    args.workdir.mkdir(parents=True, exist_ok=True)
    contacts = args.workdir / f"contacts_{args.points}.csv"
    if not contacts.exists():
        t = time.perf_counter()
        make_contacts(contacts, args.points)
        print(f"wrote {contacts} ({4 * (args.points + 4):,} contacts) in {time.perf_counter() - t:.1f} s")
    out = args.workdir / "model"
    cmd = [sys.executable, "-m", "gistools.cli.main", "aquifer", "model", str(contacts), "--layers", "LS,AU,AD,AQ",
           "--crs", "EPSG:3003", "--out", str(out), "--overwrite", "-q"]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t
    rep = json.loads((out / "report.json").read_text())
    exact = {"LS/AU": 3.375e10, "AU/AD": 2.7e9, "AD/AQ": 4.8375e10}
    print(f"aquifer model, 4 layers x {args.points:,} contacts: {wall:.1f} s wall (model {rep['seconds']:.1f} s); "
          f"target < 30 s: {'met' if wall < 30 else 'NOT met'}")
    for name, u in rep["units"].items():
        print(f"  {name}: volume {u['volume']:.6e} m3, analytic {exact[name]:.6e}, error {100 * (u['volume'] / exact[name] - 1):+.4f} %")
    for layer, info in rep["layers"].items():
        print(f"  {layer}: {info['points']:,} points, {info['triangles']:,} triangles, flags {info['flags']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
