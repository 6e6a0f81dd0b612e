"""The picture of the documentation's "Fire: canopy fuels" page (docs/fuels.png): gistools fuels on the synthetic
stand of gistools.synthetic (cone and half-ellipsoid crowns, Beer-Lambert returns) against the stand's known
answers, and the leaf area density profile of one cell.

    python tools/make_fuels_figure.py [docs/fuels.png]
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import rasterio  # noqa: E402

from gistools.products.fuels import FuelsSettings, fuels_from_tiles  # noqa: E402
from gistools.synthetic import make_stand, stand_points, stand_truth, write_stand  # noqa: E402


def main(target: Path) -> None:
    st = make_stand(shape=(5, 4), seed=7)
    truth = stand_truth(st)
    with tempfile.TemporaryDirectory() as tmp:
        write_stand(st, stand_points(st, seed=1), tmp)
        fuels_from_tiles(Path(tmp) / "stand.las", Path(tmp) / "f", FuelsSettings())
        got = {}
        for name in ("cbh", "cbd", "cover", "height"):
            with rasterio.open(Path(tmp) / "f" / f"{name}.vrt") as src:
                a = src.read(1)
                got[name] = np.array([a[src.index(st.origin[0] + (c + 0.5) * st.cell, st.origin[1] + (r + 0.5) * st.cell)]
                                      for c, r, *_ in st.cells])
    canopy = st.cells[:, 5] > 0
    fig, axes = plt.subplots(1, 4, figsize=(13, 3.4))
    panels = (("cbh", "canopy base height (m)", truth["cbh"]), ("cbd", "canopy bulk density (kg/m³)", truth["cbd"]),
              ("cover", "canopy cover (%)", truth["cover"]), ("height", "canopy height (m)", truth["height"]))
    for ax, (name, label, want) in zip(axes, panels):
        dome = st.cells[:, 7] == 1
        ax.scatter(want[canopy & dome], got[name][canopy & dome], s=18, label="half-ellipsoid crowns")
        ax.scatter(want[canopy & ~dome], got[name][canopy & ~dome], s=18, marker="^", label="cone crowns")
        top = max(want.max(), np.nanmax(got[name])) * 1.08
        ax.plot([0, top], [0, top], color="grey", lw=0.8)
        ax.set(xlim=(0, top), ylim=(0, top), xlabel=f"truth: {label}", ylabel="gistools fuels")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("gistools fuels on the synthetic stand (19 canopy cells of 30 m, 20 pulses/m²) against its known answers")
    fig.tight_layout()
    fig.savefig(target, dpi=110)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "docs" / "fuels.png")
