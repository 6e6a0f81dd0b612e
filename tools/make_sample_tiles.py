#!/usr/bin/env python3
"""Write sample_tiles/: a 2 x 2 block of synthetic tiles shaped like the Levy County delivery.

LAS 1.1, point format 1, EPSG:2882 (NAD83(HARN) / Florida West, US survey feet) in
the header as GeoTIFF keys, classes 1 / 2 / 9, up to 4 returns per pulse, 4 ft
pulse spacing; one tile LAZ. Beside them ``breaklines.gpkg`` (FOOTPRINT,
ROADBREAKLINE, HYDROGRAPHICFEATURE, WATERBODY, WETLAND) and ``truth.gpkg``
(the generator's shrub patches with cover and band, roads, water, trees, buildings).
Deterministic: the same seed writes the same points.

    python tools/make_sample_tiles.py [--out sample_tiles] [--seed 35712]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import geopandas as gpd
import laspy
import numpy as np
import pyproj
import shapely
from shapely.geometry import box

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from gistools.synthetic import COVER  # noqa: E402
from gistools.datasets.examples import SAMPLE_TILE_IDS, write_sample_block  # noqa: E402

CRS = pyproj.CRS.from_epsg(2882)
LAZ_TILE = 35813  # the one LAZ tile (the block: gistools/datasets/examples.py write_sample_block)
TILES = tuple(SAMPLE_TILE_IDS.values())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="sample_tiles")
    ap.add_argument("--seed", type=int, default=35712)
    args = ap.parse_args(argv)
    out = Path(args.out)
    mine = {f"{t}.{'laz' if t == LAZ_TILE else 'las'}" for t in TILES} | {"breaklines.gpkg", "truth.gpkg", "README.md"}
    if out.exists():
        others = sorted(p.name for p in out.iterdir() if p.name not in mine and not p.name.endswith(".aux.xml"))
        if others:  # never delete what this tool did not write
            sys.exit(f"make_sample_tiles: {out} holds files this tool did not write ({', '.join(others[:5])}); "
                     "choose another --out or move them")
        for name in mine:
            (out / name).unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    scene, footprints = write_sample_block(out, seed=args.seed, laz=(LAZ_TILE,))
    for f in footprints:
        print(f"{f['FILENAME']}: {laspy.read(out / f['FILENAME']).header.point_count:,} points")
    block = box(*scene.bounds)
    truth = out / "truth.gpkg"
    gpd.GeoDataFrame(
        {"cover": [p.cover for p in scene.shrubs], "band": [p.band for p in scene.shrubs],
         "cover_fraction": [COVER[p.cover] for p in scene.shrubs],
         "crown_area": [p.crown_union.area for p in scene.shrubs]},
        geometry=[p.geometry for p in scene.shrubs], crs=CRS).to_file(truth, layer="SHRUB_TRUTH")
    crowns = [(p.band, p.cover, g) for p in scene.shrubs for g in [p.crown_union]]
    gpd.GeoDataFrame({"band": [b for b, _, _ in crowns], "cover": [c for _, c, _ in crowns]},
                     geometry=[g for _, _, g in crowns], crs=CRS).to_file(truth, layer="SHRUB_CROWNS")
    gpd.GeoDataFrame({"kind": ["road"]}, geometry=[scene.road_union.intersection(block)], crs=CRS).to_file(
        truth, layer="ROAD_TRUTH")
    gpd.GeoDataFrame({"kind": ["water"]}, geometry=[scene.water_union.intersection(block)], crs=CRS).to_file(
        truth, layer="WATER_TRUTH")
    t = np.array(scene.trees)
    gpd.GeoDataFrame({"height_ft": t[:, 3], "crown_radius_ft": t[:, 2]},
                     geometry=shapely.buffer(shapely.points(t[:, :2]), t[:, 2]), crs=CRS).to_file(truth, layer="TREE_TRUTH")
    gpd.GeoDataFrame({"roof_height_ft": [h for _, h in scene.buildings]},
                     geometry=[b for b, _ in scene.buildings], crs=CRS).to_file(truth, layer="BUILDING_TRUTH")
    total = sum(f.stat().st_size for f in out.iterdir())
    print(f"wrote {out}/ ({total / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
