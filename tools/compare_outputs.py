#!/usr/bin/env python3
"""Every output of the chain, of each step and of the other commands, as a manifest of content digests.

A restructuring must leave every output bit-identical: record a manifest with the code before the change,
check it after.

    python tools/compare_outputs.py record /tmp/before.json
    python tools/compare_outputs.py check /tmp/before.json     # exit 1 and the files that differ
    python tools/compare_outputs.py check /tmp/before.json --cells   # the same, metadata changes allowed

With ``--cells`` a change of GeoTIFF tags or GeoPackage layer names only is listed but allowed (an
intended metadata change); cells, geometries and attributes must still be identical.

What is compared: GeoTIFFs by their decoded cells, transform, CRS, nodata and tags; GeoPackages by every
layer's features (geometry WKB and attributes); JSON with run times, file stamps (``made``: the sizes and times of
inputs and outputs) and absolute paths left out; PNG by its pixels; CSV / PLY / OBJ / VRT byte for byte (VRT paths are relative). PDFs hold a creation date: left out.
Runs on sample_tiles/, the real files of ../shared/data (when present) and the synthetic aquifer, runway and
structure inputs.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_tiles"
SHARED = ROOT.parent / "shared" / "data"
B = SAMPLE / "breaklines.gpkg"
VECTORS = ["--roads", f"{B}:ROADBREAKLINE", "--hydro", f"{B}:HYDROGRAPHICFEATURE", "--waterbodies", f"{B}:WATERBODY",
           "--wetlands", f"{B}:WETLAND", "--tile-index", f"{B}:FOOTPRINT"]


def gistools(*args) -> None:
    proc = subprocess.run([sys.executable, "-m", "gistools.cli.main", *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"gistools {' '.join(map(str, args))} failed:\n{proc.stdout}{proc.stderr}")


def _scrub(value, root: str):
    if isinstance(value, dict):
        return {k: _scrub(v, root) for k, v in value.items() if k not in ("seconds", "scratch_peak_tiles", "finished", "stamps", "stage_seconds", "made")}
    if isinstance(value, list):
        return [_scrub(v, root) for v in value]
    if isinstance(value, str):
        return value.replace(root, "<out>").replace(str(ROOT), "<repo>")
    return value


def digest(path: Path, root: Path) -> list | None:
    """[digest of everything, digest of the content without metadata (tags, layer names)], or None (not compared)."""
    h = hashlib.sha256()
    suffix = path.suffix.lower()
    if suffix == ".tif":
        import rasterio

        with rasterio.open(path) as src:
            h.update(src.read().tobytes())
            h.update(repr((tuple(src.transform), src.crs.to_wkt() if src.crs else None, src.nodata, src.dtypes)).encode())
            cells = h.copy()
            h.update(repr((sorted(src.tags().items()), src.units, src.descriptions)).encode())
        return [h.hexdigest(), cells.hexdigest()]
    if suffix == ".gpkg":
        import pyogrio

        cells = hashlib.sha256()
        for layer in sorted(str(n) for n, _ in pyogrio.list_layers(path)):
            df = pyogrio.read_dataframe(path, layer=layer)
            h.update(layer.encode())
            for part in [repr(list(df.columns)).encode()] + [
                    repr(tuple(v.wkb if hasattr(v, "wkb") else v for v in row)).encode() for row in df.itertuples(index=False)]:
                h.update(part)
                cells.update(part)
        return [h.hexdigest(), cells.hexdigest()]
    elif suffix == ".json":
        h.update(json.dumps(_scrub(json.loads(path.read_text()), str(root)), sort_keys=True).encode())
    elif suffix == ".png":
        import matplotlib.image

        h.update(matplotlib.image.imread(path).tobytes())
    elif suffix == ".pdf" or path.name == ".gistools.lock":
        return None
    else:
        h.update(path.read_bytes())
    return [h.hexdigest(), h.hexdigest()]


def run_all(work: Path) -> dict:
    """Run every case into ``work``; {case/relative path: digest}."""
    cases = {}
    chain = work / "chain"
    gistools("shrub", SAMPLE, "--out", chain, "-q", "--band-points", *VECTORS)
    cases["chain"] = chain
    steps = work / "steps"
    gistools("shrub", SAMPLE, "--out", steps, "-q", *VECTORS)
    gistools("bands", steps, "-q", "--noise-floor", "0.05m")
    gistools("clip", steps, "-q", *VECTORS, "--max-road-width", "40ft")
    gistools("density", steps, "-q", "--radius", "30ft")
    cases["steps"] = steps
    for method in ("jenks", "quantile"):
        out = work / f"classify_{method}"
        gistools("shrub", SAMPLE, "--out", out, "-q", *VECTORS)
        gistools("classify", out, "-q", "--classify", method)
        cases[f"classify_{method}"] = out
    rasters = work / "rasters_max"
    gistools("rasters", SAMPLE, "--out", rasters, "-q", "--dem-method", "max", "--dsm-classes", "1,2",
             "--products", "dsm,dem,ndsm,topclass", "--cell-size", "1.5m")
    cases["rasters_max"] = rasters
    for name, path in (("autzen", SHARED / "lidar" / "autzen" / "autzen_trim.las"),
                       ("megaplot", SHARED / "lidar" / "megaplot" / "Megaplot.laz")):
        if path.exists():
            out = work / name
            gistools("rasters", path, "--out", out, "-q")
            cases[name] = out
    from gistools.aquifer.synthetic import synthetic_aquifer
    from gistools.runway.synthetic import synthetic_runway
    from gistools.structure.fixtures import building

    src = work / "inputs"
    src.mkdir()
    synthetic_aquifer(2012)[0].to_csv(src / "contacts.csv", index=False)
    gistools("aquifer", "model", src / "contacts.csv", "--layers", "LS,AU,AD,AQ", "--crs", "EPSG:3003", "--out",
             work / "aquifer", "-q", "--densify")
    cases["aquifer"] = work / "aquifer"
    synthetic_runway(8)[0].to_csv(src / "survey.csv", index=False)
    gistools("runway", src / "survey.csv", "--code", "4E", "--crs", "EPSG:3003", "--spacing", "10m", "--out",
             work / "runway", "-q")
    cases["runway"] = work / "runway"
    pts, _ = building("F4")
    (src / "f4.txt").write_text("\n".join(f"{i} {x} {y} {z}" for i, x, y, z in pts.itertuples(index=False)))
    gistools("structure", src / "f4.txt", "--out", work / "structure", "-q", "--loop-mode", "catmull-rom")
    cases["structure"] = work / "structure"
    manifest = {}
    for case, root in cases.items():
        for p in sorted(root.rglob("*")):
            if p.is_file():
                d = digest(p, root)
                if d is not None:
                    manifest[f"{case}/{p.relative_to(root)}"] = d
    return manifest


def main() -> int:
    cells_only = "--cells" in sys.argv[3:]
    if len(sys.argv) not in (3, 4) or sys.argv[1] not in ("record", "check"):
        print(__doc__)
        return 2
    sys.path.insert(0, str(ROOT))
    with tempfile.TemporaryDirectory(prefix="gistools-compare-") as tmp:
        manifest = run_all(Path(tmp))
    target = Path(sys.argv[2])
    if sys.argv[1] == "record":
        target.write_text(json.dumps(manifest, indent=1, sort_keys=True))
        print(f"{len(manifest)} outputs recorded in {target}")
        return 0
    before = json.loads(target.read_text())
    both = before.keys() & manifest.keys()
    differ = sorted(k for k in both if before[k][1] != manifest[k][1])
    metadata = sorted(k for k in both if before[k][1] == manifest[k][1] and before[k][0] != manifest[k][0])
    gone, new = sorted(before.keys() - manifest.keys()), sorted(manifest.keys() - before.keys())
    for label, names in (("differ", differ), ("metadata differ", metadata), ("missing now", gone), ("new", new)):
        for name in names:
            print(f"{label}: {name}")
    print(f"{len(manifest)} outputs; {len(differ)} differ, {len(metadata)} differ in metadata only, {len(gone)} missing, "
          f"{len(new)} new")
    return 1 if differ or gone or new or (metadata and not cells_only) else 0


if __name__ == "__main__":
    sys.exit(main())
