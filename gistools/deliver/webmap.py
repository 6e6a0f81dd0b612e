"""The offline web map of a shrub chain's output folder (``gistools webmap OUT``, ``gistools shrub --web-map``,
``gistools:webmap``): ``OUT/shrub_map.html``, one file that works from a USB stick or a tablet with no network.

The class polygons (``OUT/shrub_classes.gpkg``) are simplified within half a cell in their CRS, reprojected to WGS84
and inlined as GeoJSON with Leaflet's script and style (gistools/web/vendor, the npm package leaflet@1.9.4); a
county whose polygons pass ``split_mb`` is split by tile into parts of at most that size, ``shrub_map.html`` then
linking them (``shrub_map_01.html`` ...). Given the folders of ``gistools travel``, ``viewshed`` or ``fuels``, the
page also draws their layers (gistools.deliver.layers): the isochrones and points last seen with the travel time
under the cursor, the cells seen, the canopy base height classes.
"""

from __future__ import annotations

import json
import logging
import time
from importlib import resources
from pathlib import Path

import numpy as np

from .._version import __version__
from ..docstrings import shared_sections
from ..errors import InputError, OutputExistsError
from ..io.outdir import claim_output, output_folder
from ..io.atomic import atomic_path
from ..lidar.shrub import CLASS_STYLE
from ..parameters import option
from ..web.page import web_map_html
from .layers import COORD_DIGITS, check_folders, rounded as _rounded  # noqa: F401 (COORD_DIGITS: where it was)
from ..engine.record import add_run, read_folder_report

__all__ = ["web_map", "check_options", "GENERATOR"]

log = logging.getLogger("gistools.deliver.webmap")

GENERATOR = "<meta name='generator' content='gistools web map'>"  # the mark of a page gistools wrote


def _leaflet() -> tuple[str, str]:
    vendor = resources.files("gistools.web") / "vendor"
    return (vendor / "leaflet.js").read_text(encoding="utf-8"), (vendor / "leaflet.css").read_text(encoding="utf-8")


def check_options(basemap=None, split_mb=40.0) -> None:
    """``basemap`` (an XYZ tile URL) and ``split_mb`` (> 0), before anything is read or written."""
    if basemap is not None and (not str(basemap).startswith(("https://", "http://")) or
                                not all(k in str(basemap) for k in ("{z}", "{x}", "{y}"))):
        raise InputError(f"{option('basemap')} {basemap!r} is not an XYZ tile URL",
                         hint=f"e.g. {option('basemap', 'https://tile.openstreetmap.org/{z}/{x}/{y}.png')} (the page "
                              "then needs the network)")
    if not (isinstance(split_mb, (int, float)) and split_mb > 0):
        raise InputError(f"{option('split_mb')} {split_mb!r} must be a positive number of megabytes",
                         hint=f"e.g. {option('split_mb', '40')}")


def _features(gdf, tolerance: float) -> list[dict]:
    """GeoJSON features of the class polygons: simplified within ``tolerance`` (CRS units), in WGS84."""
    import shapely

    geoms = shapely.simplify(np.asarray(gdf.geometry.values), tolerance, preserve_topology=True)
    wgs = gdf.set_geometry(geoms).to_crs(4326)
    feats = []
    for row, geom in zip(wgs.drop(columns="geometry").to_dict("records"), wgs.geometry):
        if geom is None or geom.is_empty:
            continue
        g = geom.__geo_interface__
        props = {"tile": str(row.get("tile", "")), "class_code": int(row["class_code"]), "class": str(row["class"]),
                 "area": float(row["area"]), "area_acres": float(row["area_acres"]), "area_ha": float(row["area_ha"])}
        feats.append({"type": "Feature", "properties": props,
                      "geometry": {"type": g["type"], "coordinates": _rounded(g["coordinates"])}})
    return feats


def _parameters(report: dict, n_features: int) -> dict:
    settings = report.get("settings") or {}
    unit = report.get("horizontal_unit") or ""
    acres = report.get("class_area_acres") or {}
    out = {"CRS": report.get("crs"), "cell size": f"{report.get('cell_size')} {unit}",
           "density radius": f"{report.get('density_radius')} {unit}",
           "height bands": settings.get("bands", "exact"), "class breaks": report.get("class_breaks"),
           "class method": report.get("class_method"), "polygons": n_features}
    for name in ("light", "medium", "heavy", "road", "water"):
        if name in acres:
            out[f"{name} (acres)"] = f"{acres[name]:,.1f}"
    out["made by"] = f"gistools {__version__}, {time.strftime('%Y-%m-%d')}"
    return {k: v for k, v in out.items() if v not in (None, "None ")}


def _write_page(path: Path, text: str) -> None:
    if path.exists() and GENERATOR not in path.read_text(errors="ignore", encoding="utf-8")[:4000]:
        raise OutputExistsError("a file gistools did not write is in the way", path=path,
                                hint="Move it, or write the map into another folder")
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _parts(features: list[dict], limit: int) -> list[list[dict]]:
    """Features grouped by tile into parts of at most about ``limit`` bytes of GeoJSON (a tile is never split)."""
    by_tile: dict = {}
    for f in features:
        by_tile.setdefault(f["properties"]["tile"], []).append(f)
    parts, current, size = [], [], 0
    for tile in sorted(by_tile):
        n = len(json.dumps(by_tile[tile]))
        if current and size + n > limit:
            parts.append(current)
            current, size = [], 0
        current += by_tile[tile]
        size += n
    if current:
        parts.append(current)
    return parts


@shared_sections
def web_map(out, *, travel=None, viewshed=None, fuels=None, plan=None, basemap: str | None = None,
            basemap_attribution: str | None = None, split_mb: float = 40.0) -> dict:
    """One HTML file of a shrub chain's outputs, for a tablet in the field: ``gistools webmap``.

    Writes ``out/shrub_map.html`` (and parts by tile past ``split_mb``): the class polygons, the legend and the
    parameters, working without a network.

    Parameters
    ----------
    out : str or path
        The folder of a shrub chain run.
    travel : str or path, optional
        The output folder of ``gistools travel``: its isochrone bands (a legend in minutes) and points last seen are
        drawn, and the travel time under the cursor is shown (from a grid of at most 400 x 400 cells).
    viewshed : str or path, optional
        The output folder of ``gistools viewshed``: the cells seen, a semi-transparent image overlay.
    fuels : str or path, optional
        The output folder of ``gistools fuels``: its canopy base height classes (below 4 m, 4-8 m, above 8 m).
    plan : str or path, optional
        The output folder of ``gistools search-plan``: its segments, shaded by their probability of area, with the
        segment's rank, POA, POD, hours and area under the cursor, and the routes and the litter carry.
    basemap : str, optional
        An XYZ tile URL drawn under the polygons, for users who are online. None: no basemap, and the page makes no
        request to any network address.
    basemap_attribution : str, optional
        The basemap's attribution text.
    split_mb : float
        Above this many megabytes of polygons the map is split by tile into parts, with an index page.

    Returns
    -------
    dict
        ``html`` (the path, as text), ``bytes``, ``features``, ``parts`` and ``warnings`` (a layer of ``travel``,
        ``viewshed`` or ``fuels`` that does not overlap the map's polygons: drawn off the map; each also logged).

    {deliverable_raise}

    Examples
    --------
    >>> from gistools import shrub_from_tiles, web_map
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> web_map("shrub")["html"]  # doctest: +SKIP
    'shrub/shrub_map.html'
    """
    import time

    started = time.time()
    check_options(basemap, split_mb)  # every option before the folder is touched
    layers = check_folders(travel=travel, viewshed=viewshed, fuels=fuels, plan=plan)
    out = output_folder(out)
    if not out.is_dir():
        raise InputError(f"{out}: no such folder", hint="Run gistools shrub into it first")
    with claim_output(out, "gistools webmap"):  # the folder's lock; a killed run's partial file is removed first
        result = _web_map(out, basemap=basemap, basemap_attribution=basemap_attribution, split_mb=split_mb, **layers)
        add_run(out, {"tool": "gistools webmap", "seconds": round(time.time() - started, 3),
                      "settings": {"basemap": basemap, "split_mb": split_mb,
                                   **{k: str(v) for k, v in layers.items()}}, "warnings": result["warnings"]})
    return result


def _layers(travel=None, viewshed=None, fuels=None, plan=None) -> dict:
    """The page's extra layers from the folders given (see gistools.deliver.layers)."""
    from . import layers

    extra = {}
    if travel is not None:
        extra.update(layers.travel_web(travel), minutes=layers.minutes_grid(travel))
    if viewshed is not None:
        extra["viewshed"] = layers.viewshed_png(viewshed)
    if fuels is not None:
        cbh = layers.cbh_web(fuels)
        extra.update(cbh=cbh["cbh"], cbh_legend=cbh["legend"])
    if plan is not None:
        extra.update(layers.plan_web(plan))
    return extra


def _web_map(out, *, basemap: str | None = None, basemap_attribution: str | None = None, split_mb: float = 40.0,
             travel=None, viewshed=None, fuels=None, plan=None) -> dict:
    """Write ``out/shrub_map.html`` (and parts, for a county past ``split_mb`` megabytes) from the chain's outputs in
    ``out``; returns {"html", "bytes", "features", "parts"}. ``basemap``: an XYZ tile URL for users who are online
    (off by default: the page then makes no request to any network address)."""
    import geopandas as gpd

    check_options(basemap, split_mb)
    out = output_folder(out)
    gpkg = out / "shrub_classes.gpkg"
    report = read_folder_report(out) or {}
    if not gpkg.exists() or report.get("cell_size") is None:
        raise InputError(f"{out}: no shrub classes (shrub_classes.gpkg and report.json) to map",
                         hint="Run gistools shrub into this folder first")
    gdf = gpd.read_file(gpkg)
    features = _features(gdf, float(report["cell_size"]) / 2)
    classes = [{"code": c, "name": name, "colour": colour} for c, (name, colour) in CLASS_STYLE.items() if c > 0]
    js, css = _leaflet()
    title = report.get("map_title") or f"Shrub density - {out.name}"
    params = _parameters(report, len(features))
    extra = _layers(travel, viewshed, fuels, plan)
    warnings = _off_the_map(features, extra, {"travel": travel, "viewshed": viewshed, "fuels": fuels, "plan": plan})
    common = dict(classes=classes, leaflet_js=js, leaflet_css=css, basemap=basemap,
                  basemap_attribution=basemap_attribution, layers=extra)
    size = len(json.dumps({"type": "FeatureCollection", "features": features}))
    parts = _parts(features, int(split_mb * 1e6)) if size > split_mb * 1e6 else [features]
    written = []
    if len(parts) > 1:
        names = [f"shrub_map_{i + 1:02d}.html" for i in range(len(parts))]
        labels = [f"part {i + 1}: tiles {p[0]['properties']['tile']} - {p[-1]['properties']['tile']}"
                  for i, p in enumerate(parts)]
        for i, (part, name) in enumerate(zip(parts, names)):
            page = web_map_html(title=f"{title} ({labels[i]})", geojson={"type": "FeatureCollection", "features": part},
                                parameters=params, pages=list(zip(labels, names)), **common)
            _write_page(out / name, page.replace("<head>\n", "<head>\n" + GENERATOR + "\n", 1))
            written.append(str(out / name))
        index = [_footprint(p, i + 1) for i, p in enumerate(parts)]
        page = web_map_html(title=title, geojson={"type": "FeatureCollection", "features": index}, parameters=params,
                            pages=list(zip(labels, names)), **common)
    else:
        page = web_map_html(title=title, geojson={"type": "FeatureCollection", "features": features}, parameters=params,
                            **common)
    html_path = out / "shrub_map.html"
    text = page.replace("<head>\n", "<head>\n" + GENERATOR + "\n", 1)
    _write_page(html_path, text)
    return {"html": str(html_path), "bytes": len(text.encode("utf-8")), "features": len(features), "parts": written,
            "warnings": warnings}


def _extent(coordinates) -> tuple | None:
    """(west, south, east, north) of GeoJSON coordinates (nested lists of [lon, lat]); None when there are none."""
    flat = np.asarray([c for c in _positions(coordinates)], dtype=np.float64).reshape(-1, 2)
    if not len(flat):
        return None
    return float(flat[:, 0].min()), float(flat[:, 1].min()), float(flat[:, 0].max()), float(flat[:, 1].max())


def _positions(coordinates):
    """The [lon, lat] positions of nested GeoJSON coordinates."""
    if len(coordinates) and isinstance(coordinates[0], (int, float)):
        yield coordinates[:2]
        return
    for c in coordinates:
        yield from _positions(c)


def _layer_extents(extra: dict) -> dict:
    """{folder option: (west, south, east, north) in degrees} of the page's extra layers."""
    extents = {}
    if "isochrones" in extra:
        extents["travel"] = _extent([f["geometry"]["coordinates"] for f in extra["isochrones"]["features"]]
                                    + [[p["lon"], p["lat"]] for p in extra["last_seen"]])
    if "viewshed" in extra:
        (south, west), (north, east) = extra["viewshed"]["bounds"]
        extents["viewshed"] = (west, south, east, north)
    if "cbh" in extra:
        extents["fuels"] = _extent([f["geometry"]["coordinates"] for f in extra["cbh"]["features"]])
    if "segments" in extra:
        extents["plan"] = _extent([f["geometry"]["coordinates"] for f in extra["segments"]["features"]])
    return extents


def _off_the_map(features: list[dict], extra: dict, folders: dict) -> list[str]:
    """A warning (logged, and returned) for each extra layer that does not overlap the map's class polygons: it
    would be drawn off the map, as a layer of another area does."""
    from ..parameters import render

    box = _extent([f["geometry"]["coordinates"] for f in features])
    warnings = []
    for name, ext in _layer_extents(extra).items():
        if box is None or ext is None or (ext[0] <= box[2] and box[0] <= ext[2] and ext[1] <= box[3]
                                          and box[1] <= ext[3]):
            continue
        text = render(f"{option(name, str(folders[name]))}: its layer (lon {ext[0]:.5f} to {ext[2]:.5f}, lat "
                      f"{ext[1]:.5f} to {ext[3]:.5f}) does not overlap the map's extent (lon {box[0]:.5f} to "
                      f"{box[2]:.5f}, lat {box[1]:.5f} to {box[3]:.5f}): it is drawn off the map; check it is "
                      "of the same area")
        log.warning(text)
        warnings.append(text)
    return warnings


def _footprint(part: list[dict], number: int) -> dict:
    """The bounding box of a part's polygons, as a grey feature of the index page."""
    xs, ys = [], []

    def walk(c):
        if isinstance(c[0], (int, float)):
            xs.append(c[0])
            ys.append(c[1])
        else:
            for k in c:
                walk(k)

    for f in part:
        walk(f["geometry"]["coordinates"])
    w, s, e, n = min(xs), min(ys), max(xs), max(ys)
    area_ha = sum(f["properties"]["area_ha"] for f in part)
    return {"type": "Feature", "properties": {"tile": f"part {number} (shrub_map_{number:02d}.html)", "class_code": 0,
                                              "class": f"part {number}", "area": 0.0, "area_acres": area_ha / 0.40468564224,
                                              "area_ha": area_ha},
            "geometry": {"type": "Polygon", "coordinates": [[[w, s], [e, s], [e, n], [w, n], [w, s]]]}}
