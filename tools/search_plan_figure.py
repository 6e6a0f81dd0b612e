"""Draw docs/search_plan.png: the search plan of the sample for a child of 1-3 years last seen in its middle (the
worked example of docs/search_and_rescue.md): the probability of area with the rings, the segments ranked, the
barriers, and the routes from the staging point.

    python tools/search_plan_figure.py       # runs gistools shrub and gistools search-plan on sample_tiles/

Every figure quoted on the page is printed here.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
LAST_SEEN, STAGING = "431000,1811000", "431200,1810600"


def main(target: Path = ROOT / "docs" / "search_plan.png") -> None:
    import geopandas as gpd
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import rasterio
    from matplotlib.colors import LogNorm

    from gistools.products.search_plan import SearchSettings, search_plan
    from gistools.products.shrub import shrub_from_tiles

    sample = ROOT / "sample_tiles"
    b = sample / "breaklines.gpkg"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        shrub_from_tiles(sample, out, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                         waterbodies=f"{b}:WATERBODY", wetlands=f"{b}:WETLAND", tile_index=f"{b}:FOOTPRINT",
                         make_map=False)
        plan = out / "plan"
        rep = search_plan(out, plan, LAST_SEEN, "child_1_3", SearchSettings(segment_size="10ac"), staging=STAGING)
        with rasterio.open(plan / "poa.tif") as src:
            poa = src.read(1, masked=True).filled(np.nan)
            w, s, e, n = src.bounds
        seg = gpd.read_file(plan / "segments.gpkg", layer="segments")
        rings = gpd.read_file(plan / "segments.gpkg", layer="rings")
        barriers = gpd.read_file(plan / "barriers.gpkg", layer="barriers")
        routes = gpd.read_file(plan / "routes.gpkg", layer="routes")
        litter = gpd.read_file(plan / "routes.gpkg", layer="litter")
        print("rings (m):", ", ".join(f"{r:.0f}" for r in rep["rings_m"]))
        print(f"on the DEM {1 - rep['rest_of_world']:.1%}, rest of the world {rep['rest_of_world']:.1%}")
        print(f"{rep['segments']} segments, {rep['segment_area_ha']:.1f} ha; ranked {rep['ranked']}")
        for _, r in seg.sort_values("rank").head(3).iterrows():
            print(f"segment {r['segment']}: {r['area_ha']:.2f} ha, POA {r['poa']:.3f}, {r['vegetation']}, "
                  f"W {r['sweep_width_m']:.1f} m, {r['minutes_from_staging']:.1f} min from staging")
        if rep["litter"]:
            print(f"litter: {rep['litter']['minutes']:.1f} min, {rep['litter']['length_m']:.0f} m")
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5.4), dpi=110)
    extent = (w, e, s, n)
    shown = np.where(poa > 0, poa, np.nan)
    im = left.imshow(shown, extent=extent, cmap="magma_r", norm=LogNorm(vmin=np.nanmin(shown),
                                                                        vmax=np.nanmax(shown)))
    rings.boundary.plot(ax=left, color="#2166ac", linewidth=1.2)
    barriers[barriers["kind"] == "water"].plot(ax=left, color="#1f78b4")
    left.set_title("Probability of area (per cell) and the rings")
    fig.colorbar(im, ax=left, shrink=0.8)
    colours = {"water": "#1f78b4", "thicket": "#1b5e20", "cliff": "#6a3d9a"}
    for kind, colour in colours.items():
        part = barriers[barriers["kind"] == kind]
        if len(part):
            part.plot(ax=right, color=colour, alpha=0.8)
    seg.boundary.plot(ax=right, color="black", linewidth=0.8)
    for _, r in seg.iterrows():
        p = r.geometry.representative_point()
        right.annotate(str(r["rank"]), (p.x, p.y), ha="center", va="center", fontsize=8, weight="bold")
    routes.plot(ax=right, color="#e08214", linewidth=1.2)
    if len(litter):
        litter.plot(ax=right, color="#b2182b", linewidth=2.0, linestyle="--")
    for ax in (left, right):
        sx, sy = (float(v) for v in LAST_SEEN.split(","))
        ax.plot(sx, sy, marker="*", color="red", markersize=12)
        tx, ty = (float(v) for v in STAGING.split(","))
        ax.plot(tx, ty, marker="s", color="black", markersize=7)
        ax.set_xlim(w, e)
        ax.set_ylim(s, n)
        ax.set_xticks([])
        ax.set_yticks([])
    right.set_title("Segments by rank, barriers, routes (litter dashed)")
    fig.tight_layout()
    fig.savefig(target)
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
