"""Draw docs/travel.png: the travel time of a walker on the sample from a point last seen, its isochrones and the
1-hour isochrone, over a hillshade of the DEM (the worked example of docs/search_and_rescue.md).

    python tools/travel_figure.py            # runs gistools shrub and gistools travel on sample_tiles/ in a temporary folder

Every figure quoted on the page is printed here.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
LAST_SEEN = (431000.0, 1811000.0)
ISOCHRONES = (2.0, 4.0, 6.0, 60.0)


def main(target: Path = ROOT / "docs" / "travel.png") -> None:
    import geopandas as gpd
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import rasterio
    from matplotlib.colors import BoundaryNorm, ListedColormap

    from gistools.products.shrub import shrub_from_tiles
    from gistools.products.travel import TravelSettings, travel_from_dem

    sample = ROOT / "sample_tiles"
    b = sample / "breaklines.gpkg"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        shrub_from_tiles(sample, out, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                         waterbodies=f"{b}:WATERBODY", wetlands=f"{b}:WETLAND", tile_index=f"{b}:FOOTPRINT",
                         make_map=False)
        rep = travel_from_dem(out, out / "travel", "{:.0f},{:.0f}".format(*LAST_SEEN), TravelSettings(isochrones=ISOCHRONES))
        with rasterio.open(out / "dem.vrt") as src:
            dem = src.read(1, masked=True).filled(np.nan).astype(float)
            w, s, e, n = src.bounds
            cell = src.res[0]
        with rasterio.open(out / "travel" / "travel_minutes.tif") as src:
            minutes = src.read(1, masked=True).filled(np.nan).astype(float)
        iso = gpd.read_file(out / "travel" / "travel.gpkg", layer="isochrones")
        print(f"reached {rep['reached_share']:.1%} of the cells; farthest {rep['max_minutes']:.2f} min")
        for row in rep["isochrones"]:
            print(f"within {row['minutes']:g} min: {row['area']:,.0f} sq ftUS, {row['hectares']:.2f} ha, "
                  f"{row['acres']:.2f} acres")
    gy, gx = np.gradient(np.nan_to_num(dem, nan=np.nanmean(dem)), cell)
    shade = np.clip(0.6 + 0.4 * (-gx - gy) / np.sqrt(1 + gx ** 2 + gy ** 2) * 3, 0, 1)  # light from the north-west
    fig, ax = plt.subplots(figsize=(7.5, 6.4), dpi=110)
    extent = (w, e, s, n)
    ax.imshow(shade, cmap="gray", extent=extent, vmin=0, vmax=1)
    edges = [0, *ISOCHRONES[:3], np.nanmax(minutes) + 1]
    cmap = ListedColormap(["#1a9850", "#91cf60", "#fee08b", "#fc8d59"])
    im = ax.imshow(minutes, cmap=cmap, norm=BoundaryNorm(edges, cmap.N), alpha=0.55, extent=extent)
    for _, row in iso.iterrows():
        style = {"color": "black", "linewidth": 2.2} if row["minutes"] == 60 else {"color": "#333333", "linewidth": 0.8}
        gpd.GeoSeries([row.geometry]).boundary.plot(ax=ax, **style)
    ax.plot(*LAST_SEEN, marker="*", color="red", markersize=16, markeredgecolor="black")
    ax.set_xlim(w, e)
    ax.set_ylim(s, n)
    ax.set_title("Walker's travel time from the point last seen (red star)\n"
                 "thin lines: 2, 4, 6 min; thick: the 1-hour isochrone (all land the walker can reach)", fontsize=9)
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x (EPSG:2882, US survey feet)", fontsize=8)
    bar = fig.colorbar(im, ax=ax, shrink=0.8)
    bar.set_label("minutes", fontsize=8)
    fig.tight_layout()
    fig.savefig(target)
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
