"""Maps and figures (matplotlib, imported lazily)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rasterio

from .lidar.shrub import CLASS_STYLE
from .units import LinearUnit

__all__ = ["SHRUB_COLOURS", "map_parameters", "shrub_map"]

SHRUB_COLOURS = CLASS_STYLE  # the dissertation's legend (lidar/shrub.py)


def map_frame_ticks(ax, bounds) -> float:
    """The map's frame on ``bounds`` (west, south, east, north): coordinates every round length on all four
    sides, in CRS units with thousands separators; returns that length."""
    from matplotlib.ticker import FuncFormatter, MultipleLocator

    west, south, east, north = bounds
    ax.set_xlim(west, east)
    ax.set_ylim(south, north)
    step = _nice_length((east - west) / 5)
    fmt = FuncFormatter(lambda v, _pos: f"{v:,.0f}")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MultipleLocator(step))
        axis.set_major_formatter(fmt)
    ax.tick_params(labelsize=7, top=True, right=True, labeltop=True, labelright=True)
    return step


def _nice_length(target: float) -> float:
    exp = 10 ** np.floor(np.log10(target))
    for m in (1, 2, 5, 10):
        if m * exp >= target:
            return float(m * exp)
    return float(10 * exp)


def plain_axes(ax) -> None:
    """Axis labels as plain numbers with thousands separators (no "1e6" offset: map coordinates are read whole)."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    fmt = FuncFormatter(lambda v, _pos: f"{v:,.0f}")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(fmt)
        axis.set_major_locator(MaxNLocator(4))  # room for seven-digit labels


def new_figure(figsize):
    """A matplotlib Figure with its own Agg canvas: drawing and saving it leave pyplot and the process's backend
    alone (inside the QGIS desktop, ``matplotlib.use`` would switch QGIS's own)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def axes_3d(fig):
    """A 3D axes on ``fig``, or None where this matplotlib cannot make one: its ``mpl_toolkits`` shadowed by another
    matplotlib's (Debian's python3-matplotlib on QGIS's path beside a newer one: "'3d' is not a valid value for
    projection")."""
    try:
        return fig.add_subplot(projection="3d")
    except Exception:  # ValueError (no "3d" projection), or the other copy's mplot3d failing on this matplotlib
        for ax in list(fig.axes):
            fig.delaxes(ax)
        return None


def oblique_surfaces(ax, surfaces, colours, *, azimuth: float = -60.0, elevation: float = 30.0) -> None:
    """Triangulated surfaces (``[(label, x, y, z, triangles)]``) drawn as an oblique view on a 2D axes, without
    mpl_toolkits: rotated by ``azimuth`` about z, tilted by ``elevation`` (degrees, matplotlib's default 3D view),
    vertical exaggerated to a third of the horizontal extent, triangles painted far to near."""
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    xs = np.concatenate([s[1] for s in surfaces])
    ys = np.concatenate([s[2] for s in surfaces])
    zs = np.concatenate([s[3] for s in surfaces])
    cx, cy = xs.mean(), ys.mean()
    span = max(np.ptp(xs), np.ptp(ys), 1e-9)
    zscale = span / 3 / max(np.ptp(zs), 1e-9)
    a, e = np.radians(azimuth), np.radians(elevation)
    polys, depth, faces = [], [], []
    for k, (_label, x, y, z, tri) in enumerate(surfaces):
        u = (x - cx) * np.cos(a) + (y - cy) * np.sin(a)  # across the view
        d = -(x - cx) * np.sin(a) + (y - cy) * np.cos(a)  # into the view
        v = (z - zs.min()) * zscale * np.cos(e) + d * np.sin(e)
        polys.append(np.stack([u[tri], v[tri]], axis=-1))
        depth.append((d[tri].mean(axis=1) * np.cos(e)) - (z[tri].mean(axis=1) - zs.min()) * zscale * np.sin(e))
        faces.append(np.full(len(tri), k))
    polys, depth, faces = np.concatenate(polys), np.concatenate(depth), np.concatenate(faces)
    order = np.argsort(-depth)  # far first
    colour = np.array([colours[k] for k in range(len(surfaces))])[faces[order]]
    ax.add_collection(PolyCollection(polys[order], facecolors=colour, edgecolors="none", alpha=0.6))
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.legend(handles=[Patch(color=colours[k], label=s[0]) for k, s in enumerate(surfaces)], loc="upper right")


def map_parameters(classes_path, cover_path, unit: LinearUnit) -> str:
    """The map's caption of what made it: cell size, density radius (from the cover raster's tags) and the cover
    breaks (from the class raster's tags), in the data's units."""
    import json

    with rasterio.open(classes_path) as src:
        cell = src.transform.a
        breaks = src.tags().get("GISTOOLS_CLASS_BREAKS")
        if breaks is None and src.files[1:]:  # a VRT: its first tile has the tags
            with rasterio.open(src.files[1]) as tile:
                breaks = tile.tags().get("GISTOOLS_CLASS_BREAKS")
    radius = None
    if cover_path is not None and Path(cover_path).exists():
        with rasterio.open(cover_path) as src:
            radius = src.tags().get("GISTOOLS_RADIUS")
            if radius is None and src.files[1:]:
                with rasterio.open(src.files[1]) as tile:
                    radius = tile.tags().get("GISTOOLS_RADIUS")
    parts = [f"cell {cell:.4g} {unit.short}"]
    if radius is not None:
        parts.append(f"density radius {float(radius):.4g} {unit.short}")
    if breaks:
        b1, b2 = json.loads(breaks)
        parts.append(f"cover: light <= {b1:.2f} < medium <= {b2:.2f} < heavy")
    return "; ".join(parts)


def scale_bar(ax, bounds, unit: LinearUnit, fontsize: float = 10) -> float:
    """A scale bar of a round length about a fifth of the width, lower left, in map units; returns its length."""
    from matplotlib import patheffects

    west, south, east, north = bounds
    length = _nice_length((east - west) / 5)
    x0, y0 = west + 0.05 * (east - west), south + 0.05 * (north - south)
    halo = [patheffects.withStroke(linewidth=7, foreground="white")]  # reads over any class, hides none
    ax.plot([x0, x0 + length], [y0, y0], color="black", linewidth=4, solid_capstyle="butt", zorder=4,
            path_effects=[patheffects.Stroke(linewidth=7, foreground="white"), patheffects.Normal()])
    ax.text(x0 + length / 2, y0 + 0.015 * (north - south), f"{length:g} {unit.short}", ha="center", va="bottom", zorder=4,
            path_effects=halo, fontsize=fontsize)
    return length


def north_arrow(ax, size: float = 14) -> None:
    """A north arrow, upper right (north-up maps)."""
    ax.annotate("N", xy=(0.93, 0.93), xytext=(0.93, 0.83), xycoords="axes fraction", ha="center",
                arrowprops=dict(facecolor="black", width=4, headwidth=12), fontsize=size, fontweight="bold")


def crs_label(crs) -> str:
    """A rasterio CRS's name (its PROJ name where it parses)."""
    if not crs:
        return "no CRS"
    try:
        import pyproj

        return pyproj.CRS.from_wkt(crs.to_wkt()).name
    except Exception:
        return crs.to_string()


def class_rgb(data: np.ndarray) -> np.ndarray:
    """RGBA image (opaque) of a class raster (the map's colours; 255 no data in light grey). RGBA, not RGB:
    matplotlib adds the alpha channel to an RGB image itself, copying it, each time it draws it (0.3 s of a
    2000 x 2000 map's PNG and PDF); the pixels are the same."""
    import matplotlib

    lut = np.full((256, 4), 255, np.uint8)  # class code -> RGBA, one gather for the whole image
    for code, (_, colour) in SHRUB_COLOURS.items():
        lut[code, :3] = np.round(np.array(matplotlib.colors.to_rgb(colour)) * 255)
    lut[255, :3] = round(0.85 * 255)
    return lut[data]


def legend_handles(data: np.ndarray) -> list:
    from matplotlib.patches import Patch

    handles = [Patch(facecolor=c, edgecolor="black", label=n) for _, (n, c) in SHRUB_COLOURS.items()]
    if (data == 255).any():  # the legend lists "no data" only where the map shows some
        handles.append(Patch(facecolor=(0.85, 0.85, 0.85), edgecolor="black", label="no data"))
    return handles


def plain(text) -> str:
    """Text shown as it is: a "$" in a folder's name (cost_$5_$10) is not taken for matplotlib's math markup."""
    return str(text).replace("$", r"\$")


def shrub_map(classes_path, out_stem, *, title: str, unit: LinearUnit, max_pixels: int = 2000, dpi: int = 150,
              probes=(), parameters: str = "") -> dict:
    """A printable shrub density map of a class raster: PNG and PDF, legend, scale bar, north arrow, CRS note.

    Returns {"paths": [png, pdf], "probes": [(col, row) pixel of the PNG for each (x, y) of ``probes``]};
    files are written atomically.
    """
    from .io.raster import atomic_path

    with rasterio.open(classes_path) as src:
        scale = max(1, int(np.ceil(max(src.width, src.height) / max_pixels)))
        data = src.read(1, out_shape=(max(1, src.height // scale), max(1, src.width // scale)),
                        resampling=rasterio.enums.Resampling.mode)
        west, south, east, north = src.bounds
        crs = src.crs
    rgba = class_rgb(data)
    aspect = (north - south) / max(east - west, 1e-9)
    fig = new_figure((11.0, float(np.clip(8.0 * aspect + 1.8, 4.5, 14.0))))
    ax = fig.subplots()
    ax.imshow(rgba, extent=(west, east, south, north), interpolation="nearest")
    ax.set_title(plain(title))
    ax.set_xlabel(f"x ({unit.name})")
    ax.set_ylabel(f"y ({unit.name})")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.legend(handles=legend_handles(data), loc="upper left", bbox_to_anchor=(1.01, 1.0), title="Shrub density")
    scale_bar(ax, (west, south, east, north), unit)
    north_arrow(ax)
    crs_name = crs_label(crs)
    caption = f"CRS: {crs_name}; units: {unit.name}. Classes from vegetation cover within the density radius."
    if parameters:  # a second line: what made the map
        caption += f"\n{parameters}."
    fig.text(0.01, 0.01, plain(caption), fontsize=8, va="bottom")
    # a fixed frame, not tight_layout: with an equal-aspect image it clipped the legend (outside the axes, right)
    ax.set_position([0.1, 0.08, 0.7, 0.85])
    ax.set_anchor("W")
    if probes:  # pixel positions need the final layout drawn once
        fig.canvas.draw()
    height_px = fig.get_size_inches()[1] * dpi
    pixels = []
    for x, y in probes:
        px, py = ax.transData.transform((x, y)) * (dpi / fig.dpi)
        pixels.append((int(round(px)), int(round(height_px - py))))
    written = []
    for suffix in (".png", ".pdf"):
        path = Path(str(out_stem) + suffix)
        with atomic_path(path, overwrite=True) as tmp:
            fig.savefig(tmp, format=suffix[1:], dpi=dpi)
        written.append(path)
    return {"paths": written, "probes": pixels}


PAPER_IN = {"letter": (11.0, 8.5), "a4": (11.69, 8.27), "tabloid": (17.0, 11.0)}  # landscape, inches
MAP_FRAME = (0.06, 0.08, 0.62, 0.84)  # the map's axes on a map book page (figure fractions)


def map_frame_inches(paper: str) -> tuple[float, float]:
    """The width and height (inches) of the map frame of a map book page."""
    w, h = PAPER_IN[paper]
    return w * MAP_FRAME[2], h * MAP_FRAME[3]


def mapbook_page(data: np.ndarray, bounds, *, title: str, unit: LinearUnit, crs, scale: float, locator: np.ndarray,
                 locator_bounds, pages: list, page_index: int, parameters: str, paper: str = "letter",
                 travel=None, seen: np.ndarray | None = None, segment=None):
    """One map book page (a matplotlib Figure): the classes of ``data`` (a class raster over ``bounds``) at 1:``scale``,
    a grid with coordinates, a locator map (``locator``: the whole area's classes, ``pages``: every page's bounds,
    this one outlined), legend, scale bar, north arrow and what made the map. ``travel``: (isochrone bands, points
    last seen), GeoDataFrames in the page's CRS (gistools.deliver.layers.travel_frames), drawn over the classes;
    ``seen``: the cells seen of a viewshed on ``data``'s grid, a semi-transparent cyan; ``segment``: (a search
    segment's outline, the route to it or None), shapely geometries in the page's CRS."""
    from matplotlib.patches import Rectangle

    fig = new_figure(PAPER_IN[paper])
    ax = fig.add_axes(MAP_FRAME)
    west, south, east, north = bounds
    ax.imshow(class_rgb(data), extent=(west, east, south, north), interpolation="nearest")
    handles = legend_handles(data)
    if seen is not None:
        from matplotlib.patches import Patch

        wash = np.zeros(seen.shape + (4,), np.uint8)
        wash[seen] = VIEWSHED_RGBA
        ax.imshow(wash, extent=(west, east, south, north), interpolation="nearest")
        handles.append(Patch(facecolor=np.array(VIEWSHED_RGBA) / 255, edgecolor="black", label="seen (viewshed)"))
    if travel is not None:
        handles += draw_travel(ax, *travel)
    if segment is not None:
        handles += draw_segment(ax, *segment)
    step = map_frame_ticks(ax, bounds)
    plt_y = ax.get_yticklabels()
    for label in plt_y:
        label.set_rotation(90)
        label.set_va("center")
    ax.grid(True, color="black", linewidth=0.4, alpha=0.5)
    ax.set_title(plain(title), fontsize=12, pad=18)
    scale_bar(ax, bounds, unit, fontsize=8)
    north_arrow(ax, size=12)
    # locator map, upper right of the page
    loc = fig.add_axes((0.72, 0.55, 0.25, 0.36))
    lw, ls, le, ln = locator_bounds
    loc.imshow(class_rgb(locator), extent=(lw, le, ls, ln), interpolation="nearest")
    for i, (pw, ps, pe, pn) in enumerate(pages):
        loc.add_patch(Rectangle((pw, ps), pe - pw, pn - ps, fill=i == page_index, facecolor=(0, 0, 0, 0.25),
                                edgecolor="black" if i == page_index else (0, 0, 0, 0.35),
                                linewidth=1.6 if i == page_index else 0.4))
    loc.set_xlim(lw, le)
    loc.set_ylim(ls, ln)
    loc.set_xticks([])
    loc.set_yticks([])
    loc.set_title(f"page {page_index + 1} of {len(pages)}", fontsize=8)
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.72, 0.52), title="Shrub density",
               fontsize=8, title_fontsize=9, frameon=False)
    fig.text(0.72, 0.08, plain(f"Scale 1:{scale:,.0f} on {paper} paper\nCRS: {crs_label(crs)}\nunits: {unit.name}\n"
                               f"grid every {step:g} {unit.short}\n{parameters}"), fontsize=7, va="bottom", wrap=True)
    return fig


VIEWSHED_RGBA = (0, 229, 255, 110)  # the cells seen: cyan, semi-transparent (as the web map's overlay)
LAST_SEEN = "#ff00ff"  # the points last seen: magenta, a colour no class or isochrone band has


SEGMENT_EDGE, ROUTE = "#08306b", "#e08214"  # a search segment's outline, the route to it (as the web map)


def draw_segment(ax, outline, route) -> list:
    """A search segment's outline (dark blue) and the route to it (orange) on ``ax``; their legend handles."""
    from matplotlib.lines import Line2D

    for part in getattr(outline, "geoms", [outline]):
        for ring in [part.exterior, *part.interiors]:
            x, y = ring.xy
            ax.plot(x, y, color=SEGMENT_EDGE, linewidth=2.0)
    handles = [Line2D([], [], color=SEGMENT_EDGE, linewidth=2.0, label="search segment")]
    if route is not None and not route.is_empty:
        for line in getattr(route, "geoms", [route]):
            x, y = line.xy
            ax.plot(x, y, color=ROUTE, linewidth=1.8)
        handles.append(Line2D([], [], color=ROUTE, linewidth=1.8, label="route from staging"))
    return handles


def draw_travel(ax, bands, seen) -> list:
    """The isochrones (each band's outline in its colour, over a light wash of it) and the points last seen
    (magenta dots) on ``ax``; returns their legend handles."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path
    from shapely.geometry.polygon import orient

    handles = []
    for geom, colour, name in zip(bands.geometry, bands["colour"], bands["name"]):
        if geom is None or geom.is_empty:
            continue
        for poly in getattr(geom, "geoms", [geom]):
            if poly.geom_type != "Polygon":
                continue
            poly = orient(poly)  # holes wound against the exterior: the wash leaves them clear
            rings = [np.asarray(r.coords) for r in (poly.exterior, *poly.interiors)]
            codes = np.concatenate([[Path.MOVETO] + [Path.LINETO] * (len(r) - 2) + [Path.CLOSEPOLY] for r in rings])
            ax.add_patch(PathPatch(Path(np.concatenate(rings), codes), facecolor=colour, alpha=0.2, linewidth=0))
            for r in rings:
                ax.plot(r[:, 0], r[:, 1], color=colour, linewidth=1.6)
        handles.append(Line2D([], [], color=colour, linewidth=2.5, label=plain(name)))
    pts = [(p.x, p.y) for p in seen.geometry if p is not None and not p.is_empty]
    if pts:
        xs, ys = zip(*pts)
        ax.plot(xs, ys, linestyle="none", marker="o", markersize=9, markerfacecolor=LAST_SEEN, markeredgecolor="black",
                markeredgewidth=1.2)
        handles.append(Line2D([], [], linestyle="none", marker="o", markersize=8, markerfacecolor=LAST_SEEN,
                              markeredgecolor="black", label="point last seen"))
    return handles


def fuels_page(cbh_classes: np.ndarray, bounds, *, title: str, unit: LinearUnit, crs, classes: dict, parameters: str,
               paper: str = "letter"):
    """The map book's fuels page (a matplotlib Figure): the canopy base height classes of ``cbh_classes`` (0 none,
    codes of ``classes`` = {code: (name, colour, top)}) over ``bounds``, a grid, legend, scale bar and north arrow."""
    import matplotlib
    from matplotlib.patches import Patch

    fig = new_figure(PAPER_IN[paper])
    ax = fig.add_axes(MAP_FRAME)
    west, south, east, north = bounds
    lut = np.full((256, 4), 255, np.uint8)
    for code, (_name, colour, _top) in classes.items():
        lut[code, :3] = np.round(np.array(matplotlib.colors.to_rgb(colour)) * 255)
    ax.imshow(lut[cbh_classes], extent=(west, east, south, north), interpolation="nearest")
    step = map_frame_ticks(ax, bounds)
    ax.grid(True, color="black", linewidth=0.4, alpha=0.5)
    ax.set_title(plain(title), fontsize=12, pad=18)
    scale_bar(ax, bounds, unit, fontsize=8)
    north_arrow(ax, size=12)
    import textwrap

    handles = [Patch(facecolor=c, edgecolor="black", label=plain("\n".join(textwrap.wrap(n, 30))))
               for n, c, _top in classes.values()]
    handles.append(Patch(facecolor="white", edgecolor="black", label="no canopy fuel layer"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.72, 0.9), title="Canopy base height",
               fontsize=8, title_fontsize=9, frameon=False)
    fig.text(0.72, 0.08, plain(f"CRS: {crs_label(crs)}\nunits: {unit.name}\ngrid every {step:g} {unit.short}\n"
                               f"{parameters}"), fontsize=7, va="bottom", wrap=True)
    return fig
