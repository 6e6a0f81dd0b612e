"""Vector layers: GeoPackage layers (``file.gpkg:LAYER``) and shapefiles, through geopandas / pyogrio."""

from __future__ import annotations

import logging
from pathlib import Path

import geopandas as gpd
import numpy as np
import pyproj

from ..errors import CRSMismatchError, DataFileError, InputError
from ..parameters import option, render
from ..validation import check_geometry_types
from .points import crs_label

log = logging.getLogger(__name__)

__all__ = ["absolute_spec", "read_layer", "check_crs", "write_layer", "write_layers", "split_layer_spec"]


VECTOR_SUFFIXES = (".gpkg", ".shp", ".geojson", ".json", ".fgb", ".gml", ".kml", ".sqlite", ".gdb", ".parquet", ".tab")


def _qgis_options(text: str) -> dict[str, str]:
    """The ``|key=value`` options of a layer as QGIS names it (keys lower-cased)."""
    return {key.strip().lower(): value for key, _, value in (item.partition("=") for item in text.split("|")[1:])}


def _qgis_layer_spec(text: str) -> tuple[Path, str | int | None]:
    """``file.gpkg|layername=LAYER`` or ``file.gpkg|layerid=N`` (QGIS's forms; a layer id is the layer's index in
    the file, returned as an int); other ``|key=value`` options are left out."""
    options = _qgis_options(text)
    path = Path(text.partition("|")[0])
    if "layername" in options:
        return path, options["layername"]
    if options.get("layerid", "").strip().isdigit():
        return path, int(options["layerid"])
    return path, None


def split_layer_spec(spec) -> tuple[Path, str | int | None]:
    """(file, layer) of a layer as the user names it: ``file.gpkg:LAYER`` (the command line's form),
    ``file.gpkg|layername=LAYER`` or ``file.gpkg|layerid=N`` (QGIS's), or a file alone. A Windows drive
    (``C:\\data\\b.gpkg``) is part of the path, and a layer name may hold ":" (``b.gpkg:ROADS:2020``): the file is the
    first part ending in a vector file's suffix (or naming a file that exists), the layer all after it. This is the
    one place a layer's name is parsed."""
    text = str(spec)
    if "|" in text:
        return _qgis_layer_spec(text)
    if Path(text).exists():
        return Path(text), None
    cuts = [i for i, c in enumerate(text) if c == ":" and not _is_drive(text, i)]
    for i in cuts:
        left = text[:i]
        if left.lower().endswith(VECTOR_SUFFIXES) or Path(left).is_file():
            return Path(left), text[i + 1:] or None
    return Path(text), None


def _is_drive(text: str, i: int) -> bool:
    """The ":" at ``i`` ends a Windows drive letter (``C:\\...``, ``C:/...``, ``C:``)."""
    return i == 1 and text[0].isalpha() and (len(text) == 2 or text[2] in "\\/")


_split = split_layer_spec


def absolute_spec(spec) -> str:
    """``path`` or ``path:LAYER`` with the path made absolute (to record where a layer came from)."""
    path, layer = _split(spec)
    if isinstance(layer, int):
        return f"{path.resolve()}|layerid={layer}"
    return str(path.resolve()) + (f":{layer}" if layer is not None else "")


def read_layer(spec, kinds: tuple[str, ...] | None = None, what: str = "layer") -> gpd.GeoDataFrame:
    """A vector layer from ``path`` or ``path:LAYER`` (GeoPackage layer); DataFileError naming it otherwise.

    ``kinds``: the geometry families the layer may hold (point, line, polygon); another one is refused,
    naming the layer as ``what`` (e.g. "--roads"). Invalid polygons (self-intersecting rings, bow ties) are
    repaired with shapely.make_valid, as QGIS's Fix Geometries does, with a warning naming each feature."""
    gdf = _read_layer(spec)
    if kinds is not None and len(gdf) == 0:
        log.warning("%s: the %s layer has no features; nothing of it is used", spec, render(what))
        return gdf
    if kinds is not None:
        check_geometry_types(gdf.geometry.geom_type, kinds, what, str(spec))
        gdf = _repaired(gdf, str(spec), what)
    return gdf


def _repaired(gdf: gpd.GeoDataFrame, spec: str, what: str) -> gpd.GeoDataFrame:
    import shapely

    geoms = gdf.geometry.to_numpy()
    if len(geoms) == 0:
        return gdf
    present = np.array([g is not None for g in geoms])
    bad = np.flatnonzero(present & ~shapely.is_valid(np.where(present, geoms, None)))
    if bad.size == 0:
        return gdf
    fixed = geoms.copy()
    for i in bad:
        reason = shapely.is_valid_reason(geoms[i])
        g = shapely.make_valid(geoms[i])
        if geoms[i].geom_type in ("Polygon", "MultiPolygon"):  # keep the polygonal parts
            parts = [p for p in shapely.get_parts(g) if p.geom_type in ("Polygon", "MultiPolygon")]
            g = shapely.union_all(parts) if parts else shapely.Polygon()
        fixed[i] = g
        log.warning("%s: %s feature %s is not valid (%s); repaired with make_valid", spec, render(what), gdf.index[i],
                    reason)
    out = gdf.copy()
    out[out.geometry.name] = gpd.GeoSeries(fixed, index=gdf.index, crs=gdf.crs)
    return out


def _read_layer(spec) -> gpd.GeoDataFrame:
    path, layer = _split(spec)
    if "subset" in _qgis_options(str(spec)):
        raise InputError("a QGIS filter (|subset=...) is not applied outside QGIS", path=spec,
                         hint="Save the filtered features as their own layer and give that one")
    if not path.exists():
        raise DataFileError("file not found", path=path, hint="Check the path (GeoPackage layers are written file.gpkg:LAYER)")
    try:
        gdf = gpd.read_file(path, layer=layer) if layer is not None else gpd.read_file(path)
    except Exception as err:
        raise DataFileError(f"cannot read layer {'(first)' if layer is None else layer} ({err})", path=path,
                            hint="Name an existing layer, e.g. breaklines.gpkg:ROADBREAKLINE") from None
    if not isinstance(gdf, gpd.GeoDataFrame):  # a table (a CSV, a GeoPackage attribute table): no geometry
        raise InputError(f"layer {'(first)' if layer is None else layer} is a table without geometry", path=spec,
                         hint="Give a point, line or polygon layer (a contacts or survey table: the CSV file itself)")
    if gdf.crs is None:
        raise InputError("layer has no CRS", path=spec, hint="Assign one in QGIS or with ogr2ogr -a_srs")
    return gdf


def check_crs(gdf: gpd.GeoDataFrame, crs: pyproj.CRS, name: str, *, reproject: bool | None = False,
              against: str = "the points'") -> gpd.GeoDataFrame:
    """``gdf`` in ``crs``: refused when they differ, unless ``reproject``. ``against`` names what ``crs`` belongs to.
    ``reproject`` None: the command has no option to reproject (the message gives ogr2ogr's)."""
    layer_crs = pyproj.CRS.from_user_input(gdf.crs)
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if layer_crs.equals(horizontal, ignore_axis_order=True) or layer_crs.equals(crs, ignore_axis_order=True):
        return gdf
    if reproject:
        return gdf.to_crs(horizontal)
    raise CRSMismatchError(
        f"layer CRS {crs_label(layer_crs)} differs from {against} CRS {crs_label(crs)}",
        path=name,
        hint=(f"Reproject the layer, or have gistools do it: {option('reproject_vectors')}" if reproject is not None
              else f"Reproject the layer: ogr2ogr -t_srs {_srs(horizontal)} reprojected.gpkg {_source(name)}"),
    )


def _srs(crs: pyproj.CRS) -> str:
    code = crs.to_authority()
    return ":".join(code) if code else "'" + crs.to_proj4() + "'"


def _source(name: str) -> str:
    """The layer's file, as ogr2ogr takes it (the ``:LAYER`` / ``|layername=`` part left out)."""
    import shlex

    return shlex.quote(str(name).split("|")[0])


def check_field(gdf: gpd.GeoDataFrame, field: str, spec, what: str = "the tile index") -> None:
    """Refuse a layer without ``field`` (one line naming the layer and its fields)."""
    if field not in gdf.columns:
        fields = ", ".join(str(c) for c in gdf.columns if c != gdf.geometry.name)
        raise InputError(f"{what} has no field {field!r} (fields: {fields})", path=str(spec),
                         hint=f"Name the tile-number field ({option('tile_field')})")


# the GeoPackage version every GeoPackage is written in: 1.2 opens without a warning in every GDAL a supported QGIS
# links (GDAL 3.6 of QGIS 3.22 warns "user_version ... may only be partially supported" on the 1.4 of GDAL >= 3.7)
GPKG_OPTIONS = {"VERSION": "1.2"}


def write_layer(gdf: gpd.GeoDataFrame, path, layer: str, *, overwrite: bool = True) -> Path:
    """Write one layer of a GeoPackage atomically (the whole file is replaced)."""
    from .raster import atomic_path

    path = Path(path)
    with atomic_path(path, overwrite=overwrite, keep_suffix=True, verify=verify_gpkg) as tmp:
        gdf.to_file(tmp, layer=layer, driver="GPKG", **GPKG_OPTIONS)
    return path


def write_layers(layers: dict, path, *, overwrite: bool = True, spatial_index_max: int = 100_000,
                 styles: dict | None = None) -> Path:
    """Write several layers ({name: GeoDataFrame}) into one GeoPackage, atomically (all or nothing); ``styles``
    ({layer: QML}): each layer's default QGIS style, stored in the file (``layer_styles``).

    Layers of more than ``spatial_index_max`` features get no R-tree index: building it row by row
    costs GDAL < 3.7 more than the write itself (QGIS can add it: Layer Properties > Create Spatial Index).
    """
    import pyogrio

    from .raster import atomic_path

    path = Path(path)
    with atomic_path(path, overwrite=overwrite, keep_suffix=True, verify=verify_gpkg) as tmp:
        for k, (name, gdf) in enumerate(layers.items()):
            index = "YES" if len(gdf) <= spatial_index_max else "NO"
            pyogrio.write_dataframe(gdf, tmp, layer=name, driver="GPKG", append=k > 0,
                                    layer_options={"SPATIAL_INDEX": index},
                                    dataset_options=None if k > 0 else GPKG_OPTIONS)
        if styles:
            from .styles import add_layer_styles

            add_layer_styles(tmp, styles)
    return path


def verify_gpkg(tmp: Path) -> None:
    """A written GeoPackage opens and lists its layers (SQLite reports a full disk only on some writes)."""
    import pyogrio

    from .atomic import check_nonempty, raise_output_error, unreadable_output

    check_nonempty(tmp)
    try:
        for name, _ in pyogrio.list_layers(tmp):
            pyogrio.read_info(tmp, layer=name)
    except Exception as err:
        raise_output_error(err, tmp)
        raise unreadable_output(tmp, "GeoPackage", err) from None
