"""The search-and-rescue and fire layers of the web map and the map book: the isochrones and points last seen of a
``gistools travel`` folder, the viewshed of a ``gistools viewshed`` folder and the canopy base height of a
``gistools fuels`` folder, each read from the folder the user names (``--travel``, ``--viewshed``, ``--fuels``).

The web map gets them in WGS84 (polygons and points as GeoJSON) or, for the rasters, warped to Web Mercator (the
map's own projection, so an image overlay and a grid of minutes line up with the polygons) at a bounded size.
"""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError
from ..parameters import option
from ..plot import VIEWSHED_RGBA  # the cells seen: cyan, semi-transparent; hidden ones are left clear

__all__ = ["check_folders", "plan_frames", "plan_web", "travel_frames", "travel_web", "minutes_grid", "viewshed_png", "cbh_web", "cbh_classes_on",
           "viewshed_on", "rounded", "cbh_class", "cbh_features", "CBH_CLASSES", "MAX_GRID_SIDE", "MAX_IMAGE_SIDE",
           "VIEWSHED_RGBA"]

MAX_GRID_SIDE = 400  # the grid of minutes inlined for the cursor readout: at most 400 x 400 values (about 0.6 MB)
COORD_DIGITS = 7  # decimal degrees: 1 cm
MAX_IMAGE_SIDE = 1024  # the viewshed's image overlay: at most 1024 pixels a side
NEEDS = {"travel": ("travel.gpkg", "travel_minutes.tif"), "viewshed": ("viewshed.tif",), "fuels": ("cbh.vrt",),
         "plan": ("segments.gpkg", "routes.gpkg")}
MAKER = {"travel": "gistools travel", "viewshed": "gistools viewshed", "fuels": "gistools fuels",
         "plan": "gistools search-plan"}


def rounded(coords):
    """GeoJSON coordinates to :data:`COORD_DIGITS` decimals (degrees: 1 cm)."""
    if isinstance(coords, (list, tuple)) and coords and isinstance(coords[0], (int, float)):
        return [round(float(c), COORD_DIGITS) for c in coords]
    return [rounded(c) for c in coords]


# canopy base height classes (metres): code -> (name, colour, upper limit)
CBH_CLASSES = {1: ("canopy base below 4 m (crown fire starts easily)", "#d7301f", 4.0),
               2: ("canopy base 4-8 m", "#fdae61", 8.0),
               3: ("canopy base above 8 m", "#1a9641", np.inf)}


def cbh_class(cbh_m: np.ndarray) -> np.ndarray:
    """0 (no canopy fuel layer: CBH 0 or no data), 1, 2, 3 by :data:`CBH_CLASSES` of CBH in metres."""
    cbh = np.nan_to_num(np.asarray(cbh_m, np.float64), nan=0.0)
    return np.where(cbh > 0, 1 + (cbh >= 4.0) + (cbh >= 8.0), 0).astype(np.uint8)


def cbh_features(cbh_vrt, *, z_metres: float, xy_metres: float) -> list[dict]:
    """GeoJSON features (WGS84) of the canopy base height classes of a CBH mosaic (in the data's vertical unit);
    ``area`` in square metres."""
    import rasterio
    import rasterio.features
    import shapely
    from pyproj import Transformer

    with rasterio.open(cbh_vrt) as src:
        cls = cbh_class(src.read(1, masked=True).filled(np.nan) * z_metres)
        transform, crs = src.transform, src.crs
    to_wgs = Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True)
    features = []
    for geom, code in rasterio.features.shapes(cls, mask=cls > 0, transform=transform, connectivity=4):
        shape = shapely.geometry.shape(geom)
        area_m2 = shape.area * xy_metres ** 2
        wgs = shapely.transform(shape, lambda c: np.column_stack(to_wgs.transform(c[:, 0], c[:, 1]))).__geo_interface__
        name = CBH_CLASSES[int(code)][0]
        features.append({"type": "Feature", "geometry": {"type": wgs["type"], "coordinates": rounded(wgs["coordinates"])},
                         "properties": {"tile": "all", "class_code": int(code), "class": name, "area": area_m2,
                                        "area_acres": area_m2 / 4046.8564224, "area_ha": area_m2 / 1e4}})
    return features


def check_folders(**folders) -> dict:
    """{name: Path} of the folders given (None left out), each checked to hold its command's outputs."""
    found = {}
    for name, folder in folders.items():
        if folder is None or str(folder) == "":
            continue
        path = Path(folder)
        missing = [f for f in NEEDS[name] if not (path / f).exists()]
        if not path.is_dir() or missing:
            what = "no such folder" if not path.is_dir() else f"no {', '.join(missing)} in it"
            raise InputError(f"{option(name, str(folder))}: {what}",
                             hint=f"Give the output folder of {MAKER[name]}")
        if name == "travel":
            _isochrones(path)  # its layers and columns, before anything is read or written
        if name == "plan":
            plan_frames(path)
        found[name] = path
    return found


# the layers of travel.gpkg (gistools travel) and the number columns each must have
TRAVEL_LAYERS = {"isochrones": ("minutes", "hectares", "acres"), "last_seen": ()}
TRAVEL_HINT = "Give the output folder of gistools travel as it wrote it (or run gistools travel again)"


def _travel_layer(path: Path, layer: str):
    """A layer of a travel folder's GeoPackage, checked (``checked_layer``), the isochrones not empty."""
    return checked_layer(path, layer, TRAVEL_LAYERS[layer], TRAVEL_HINT, nonempty=layer == "isochrones")


def checked_layer(path: Path, layer: str, columns, hint: str, nonempty: bool = False):
    """A layer of a GeoPackage a gistools command wrote, checked: there, with a CRS, its number ``columns`` numbers
    (as floats), features in it when ``nonempty``; else one line naming the file and the layer or column."""
    import geopandas as gpd
    import pyogrio

    try:
        names = [str(n) for n, _kind in pyogrio.list_layers(path)]
        gdf = gpd.read_file(path, layer=layer) if layer in names else None
    except Exception as err:  # noqa: BLE001 - not a GeoPackage, damaged: its reader's own words, on one line
        raise DataFileError(f"cannot read layer {layer} ({' '.join(str(err).split())})", path=path,
                            hint=hint) from None
    if gdf is None:
        raise InputError(f"no layer {layer} (its layers: {', '.join(names) or 'none'})", path=path, hint=hint)
    if gdf.crs is None:
        raise InputError(f"layer {layer} has no CRS", path=path, hint=hint)
    if nonempty and len(gdf) == 0:
        raise InputError(f"layer {layer} has no features", path=path, hint=hint)
    for column in columns:
        gdf[column] = _number_column(gdf, column, path, layer, hint)
    return gdf


def _number_column(gdf, column: str, path: Path, layer: str, hint: str = TRAVEL_HINT, finite: bool = True):
    """The column ``column`` of ``gdf`` as floats (``finite``: all finite); else one line naming the file, layer
    and column."""
    import pandas as pd

    if column not in gdf.columns:
        raise InputError(f"layer {layer} has no {column} column", path=path, hint=hint)
    values = pd.to_numeric(gdf[column], errors="coerce").astype("float64")
    bad = ~np.isfinite(values.to_numpy())
    if finite and bad.any():
        raise InputError(f"layer {layer}, column {column}: {gdf[column].iloc[int(np.argmax(bad))]!r} is not a "
                         "finite number", path=path, hint=hint)
    return values


def _isochrones(folder: Path):
    """(isochrones by minutes, points last seen) of a travel folder's travel.gpkg, checked (_travel_layer)."""
    path = Path(folder) / "travel.gpkg"
    iso = _travel_layer(path, "isochrones").sort_values("minutes")
    return iso, _travel_layer(path, "last_seen")


def travel_frames(folder: Path, crs=None):
    """(bands, last seen): GeoDataFrames of a travel folder, in ``crs`` when given. ``bands``: one polygon per
    isochrone band (the cells reached between the previous isochrone and this one), with ``minutes``, ``name``
    ("2-4 min") and ``colour`` (gistools travel's band colours)."""
    import geopandas as gpd
    import shapely

    from ..products.travel import band_categories

    iso, seen = _isochrones(folder)
    minutes = [float(m) for m in iso["minutes"]]
    cats = band_categories(minutes)
    rows, inner = [], None
    for i, (m, geom) in enumerate(zip(minutes, iso.geometry)):
        geom = geom if geom is not None else shapely.MultiPolygon()
        band = geom if inner is None else geom.difference(inner)
        rows.append({"minutes": m, "name": cats[i + 1][0], "colour": cats[i + 1][1], "hectares": float(iso["hectares"].iloc[i]),
                     "acres": float(iso["acres"].iloc[i]), "geometry": band})
        inner = geom
    bands = gpd.GeoDataFrame(rows, geometry="geometry", crs=iso.crs)
    if crs is not None:
        import pyproj

        if not pyproj.CRS.from_user_input(crs).equals(iso.crs):
            bands, seen = bands.to_crs(crs), seen.to_crs(crs)
    return bands, seen


def _cell(path) -> float:
    import rasterio

    with rasterio.open(path) as src:
        return abs(src.transform.a)


def travel_web(folder: Path) -> dict:
    """The isochrone bands (GeoJSON in WGS84, simplified within half a cell) and the points last seen, for the page."""
    import shapely
    from pyproj import Transformer

    bands, seen = travel_frames(folder)
    half = _cell(folder / "travel_minutes.tif") / 2
    bands = bands.set_geometry(shapely.simplify(np.asarray(bands.geometry.values), half, preserve_topology=True))
    bands = bands.to_crs(4326)
    to_wgs = Transformer.from_crs(seen.crs, "EPSG:4326", always_xy=True)  # point by point: one point is a scalar
    feats = []
    for row, geom in zip(bands.drop(columns="geometry").to_dict("records"), bands.geometry):
        if geom is None or geom.is_empty:
            continue
        g = geom.__geo_interface__
        feats.append({"type": "Feature", "geometry": {"type": g["type"], "coordinates": rounded(g["coordinates"])},
                      "properties": {"minutes": row["minutes"], "name": str(row["name"]), "colour": row["colour"],
                                     "hectares": row["hectares"], "acres": row["acres"]}})
    points = []
    for p, src in zip(seen.geometry, seen["source"] if "source" in seen else [""] * len(seen)):
        if p is not None and not p.is_empty:
            lon, lat = to_wgs.transform(float(p.x), float(p.y))
            points.append({"lon": round(lon, COORD_DIGITS), "lat": round(lat, COORD_DIGITS), "label": str(src)})
    legend = [{"name": str(f["properties"]["name"]), "colour": f["properties"]["colour"]} for f in feats]
    return {"isochrones": {"type": "FeatureCollection", "features": feats}, "last_seen": points, "legend": legend}


def _warped(path, max_side: int, resampling):
    """(array, [[south, west], [north, east]], (west, north, dx, dy) in metres of Web Mercator) of a raster's first
    band warped to EPSG:3857 with at most ``max_side`` cells a side; no-data cells NaN."""
    import rasterio
    from pyproj import Transformer
    from rasterio.transform import from_origin
    from rasterio.warp import calculate_default_transform, reproject

    with rasterio.open(path) as src:
        data = src.read(1, masked=True).astype("float64").filled(np.nan)
        transform, width, height = calculate_default_transform(src.crs, "EPSG:3857", src.width, src.height, *src.bounds)
        k = max(1.0, max(width, height) / max_side)
        width, height = max(1, math.ceil(width / k)), max(1, math.ceil(height / k))
        dx, dy = transform.a * k, -transform.e * k
        west, north = transform.c, transform.f
        dst_transform = from_origin(west, north, dx, dy)
        out = np.full((height, width), np.nan)
        reproject(data, out, src_transform=src.transform, src_crs=src.crs, src_nodata=np.nan, dst_transform=dst_transform,
                  dst_crs="EPSG:3857", dst_nodata=np.nan, resampling=resampling)
    to_wgs = Transformer.from_crs("EPSG:3857", "EPSG:4326", always_xy=True)
    lon0, lat0 = to_wgs.transform(west, north - dy * height)
    lon1, lat1 = to_wgs.transform(west + dx * width, north)
    return out, [[lat0, lon0], [lat1, lon1]], (west, north, dx, dy)


def minutes_grid(folder: Path, max_side: int = MAX_GRID_SIDE) -> dict:
    """The travel minutes on a coarse Web Mercator grid (nearest cell; at most ``max_side`` a side) for the readout
    under the cursor: ``values`` in tenths of a minute, row by row from the north-west, -1 where no path reaches."""
    from rasterio.enums import Resampling

    grid, _bounds, (west, north, dx, dy) = _warped(folder / "travel_minutes.tif", max_side, Resampling.nearest)
    tenths = np.where(np.isfinite(grid), np.round(grid * 10), -1).astype(np.int64)
    return {"west": west, "north": north, "dx": dx, "dy": dy, "cols": int(grid.shape[1]), "rows": int(grid.shape[0]),
            "values": tenths.ravel().tolist()}


def viewshed_png(folder: Path, max_side: int = MAX_IMAGE_SIDE) -> dict:
    """The viewshed as a PNG (data: URL) warped to Web Mercator, seen cells in :data:`VIEWSHED_RGBA`, the rest clear;
    with its bounds in latitude / longitude."""
    from PIL import Image
    from rasterio.enums import Resampling

    seen, bounds, _ = _warped(folder / "viewshed.tif", max_side, Resampling.nearest)
    rgba = np.zeros(seen.shape + (4,), np.uint8)
    rgba[seen == 1] = VIEWSHED_RGBA
    buf = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(buf, format="PNG", optimize=True)
    return {"url": "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii"), "bounds": bounds}


def _z_metres(folder: Path, which: str = "vertical_unit") -> float:
    from ..engine.record import read_folder_report
    from ..units import unit_from_word

    report = read_folder_report(folder) or {}
    word = (report.get("units") or {}).get(which) or report.get(which)
    if not word:
        raise InputError(f"{option('fuels', str(folder))}: its report.json has no {which.replace('_', ' ')}",
                         hint="Run gistools fuels into it again")
    return unit_from_word(word).metres


def cbh_web(folder: Path) -> dict:
    """The canopy base height classes of a fuels folder as GeoJSON polygons in WGS84 and their legend."""
    feats = cbh_features(folder / "cbh.vrt", z_metres=_z_metres(folder), xy_metres=_z_metres(folder, "horizontal_unit"))
    return {"cbh": {"type": "FeatureCollection", "features": feats},
            "legend": [{"name": n, "colour": c} for n, c, _top in CBH_CLASSES.values()]}


def _on_grid(path, crs, bounds, shape) -> np.ndarray:
    """A raster's first band on a grid of ``shape`` over ``bounds`` in ``crs`` (nearest cell; no data NaN)."""
    import rasterio
    from rasterio.enums import Resampling
    from rasterio.transform import from_bounds
    from rasterio.warp import reproject

    with rasterio.open(path) as src:
        data = src.read(1, masked=True).astype("float64").filled(np.nan)
        out = np.full(shape, np.nan)
        reproject(data, out, src_transform=src.transform, src_crs=src.crs, src_nodata=np.nan,
                  dst_transform=from_bounds(*bounds, shape[1], shape[0]), dst_crs=crs, dst_nodata=np.nan,
                  resampling=Resampling.nearest)
    return out


def cbh_classes_on(folder: Path, crs, bounds, shape) -> np.ndarray:
    """The canopy base height classes (0 none, 1, 2, 3: :data:`CBH_CLASSES`) of a fuels folder on a grid of
    ``shape`` over ``bounds`` in ``crs`` (nearest cell)."""
    return cbh_class(_on_grid(folder / "cbh.vrt", crs, bounds, shape) * _z_metres(folder))


def viewshed_on(folder: Path, crs, bounds, shape) -> np.ndarray:
    """The cells seen (True) of a viewshed folder on a grid of ``shape`` over ``bounds`` in ``crs`` (nearest cell)."""
    return _on_grid(folder / "viewshed.tif", crs, bounds, shape) == 1


# the layers of a search plan folder (gistools search-plan) and the columns the deliverables read
PLAN_LAYERS = {("segments.gpkg", "segments"): ("segment", "rank", "area_ha", "poa", "pod", "hours", "sweep_width_m"),
               ("routes.gpkg", "routes"): ("minutes", "length_m"), ("routes.gpkg", "litter"): ("minutes", "length_m")}
PLAN_HINT = "Give the output folder of gistools search-plan as it wrote it (or run gistools search-plan again)"


def plan_frames(folder: Path, crs=None) -> dict:
    """{"segments", "routes", "litter"}: the GeoDataFrames of a search plan folder, checked (the layers there, with
    a CRS, their number columns numbers), in ``crs`` when given."""
    frames = {}
    for (name, layer), columns in PLAN_LAYERS.items():
        gdf = checked_layer(Path(folder) / name, layer, columns, PLAN_HINT)
        if crs is not None:
            import pyproj

            if not pyproj.CRS.from_user_input(crs).equals(gdf.crs):
                gdf = gdf.to_crs(crs)
        frames[layer] = gdf
    return frames


def _web_features(gdf, keys) -> list[dict]:
    """GeoJSON features (WGS84, rounded) of ``gdf`` with the properties ``keys`` (NaN: None)."""
    out = []
    for row, geom in zip(gdf.drop(columns="geometry").to_dict("records"), gdf.to_crs(4326).geometry):
        if geom is None or geom.is_empty:
            continue
        g = geom.__geo_interface__
        props = {k: (None if isinstance(row.get(k), float) and not math.isfinite(row[k]) else row.get(k))
                 for k in keys}
        out.append({"type": "Feature", "geometry": {"type": g["type"], "coordinates": rounded(g["coordinates"])},
                    "properties": {k: (str(v) if isinstance(v, str) else v) for k, v in props.items()}})
    return out


def plan_web(folder: Path) -> dict:
    """The segments (with their POA, POD, rank, hours, area and minutes from staging) and routes of a search plan
    folder, as GeoJSON in WGS84 for the page."""
    frames = plan_frames(folder)
    seg = frames["segments"].sort_values("segment")
    top = float(seg["poa"].max()) if len(seg) else 0.0
    seg = seg.assign(share=seg["poa"] / top if top > 0 else 0.0)
    keys = ("segment", "rank", "area_ha", "poa", "pod", "hours", "minutes_from_staging", "vegetation", "share")
    routes = frames["routes"].assign(litter=False)
    litter = frames["litter"].assign(litter=True)
    return {"segments": {"type": "FeatureCollection", "features": _web_features(seg, keys)},
            "routes": {"type": "FeatureCollection",
                       "features": _web_features(routes, ("kind", "target", "minutes", "length_m", "litter"))
                       + _web_features(litter, ("kind", "target", "minutes", "length_m", "litter"))}}
