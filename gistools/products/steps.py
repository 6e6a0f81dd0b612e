"""The shrub steps (the dissertation's ModelBuilder steps S3-S11), raster file in, raster file out.

The one implementation of each step: ``gistools shrub`` runs them on each tile (reading the
neighbours through the VRT mosaic where a step needs a halo), the step commands ``gistools
bands / clip / density / classify`` through the chain, and the QGIS algorithms ``gistools:ndsm /
bands / breaklines / clip / density / classify`` on a tile or a mosaic. Each step is a pure
function of a window from ``gistools.lidar`` (arrays in, arrays out) run by the blockwise runner
of ``gistools.io.blocks``: inputs read in blocks of ``block`` x ``block`` cells, one tiled
GeoTIFF written block by block, atomically, so memory stays flat whatever the extent.

Lengths take a unit ("25ft", "0.1m") or are in the raster's CRS units.
"""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import numpy as np
import pyproj
import shapely

from ..docstrings import shared_sections
from ..parameters import default_for
from ..errors import InputError
from ..grid import affine_apply
from ..io.atomic import atomic_path
from ..io.blocks import (BLOCK, PolygonMask, check_outputs_are_not_inputs, open_raster, raster_crs, read_window,
                         run_blockwise, same_grid, windows)
from ..io.raster import NODATA
from ..io.styles import write_polygon_style
from ..io.vector import GPKG_OPTIONS, check_crs, check_field, read_layer, verify_gpkg, write_layer
from ..lidar.bands import (BAND_NAMES, BAND_NODATA, add_nodata_causes, band_thresholds, height_bands,
                           nodata_cause_shares)
from ..lidar.density import halo_cells
from ..lidar.gridding import ndsm_from
from ..lidar.shrub import (CLASS_NAMES, CLASS_NODATA, CLASS_STYLE, breaks_from_sample, lattice_sample, sample_step,
                            shrub_classes)
from ..lidar.vegetation import VEG_NODATA, VEG_ROAD, VEG_WATER, vegetation, vegetation_cover
from ..progress import ProgressCallback, report
from ..units import LinearUnit, horizontal_unit, length_to_crs_units, unit_from_word
from ..vector.breaklines import road_polygons, water_polygons
from ..vector.regions import class_polygons
from ..validation import check_breaks, check_length
from ..lidar.accumulate import GROUNDISH
from .settings import DEFAULTS

__all__ = ["ndsm_from_rasters", "bands_from_ndsm", "breakline_polygons", "clip_bands", "density_from_vegetation",
           "classes_from_cover", "class_summary", "band_summary", "nodata_causes", "BLOCK"]


def _z_unit(src, path, z_unit) -> LinearUnit:
    if isinstance(z_unit, LinearUnit):
        return z_unit
    if z_unit:
        return unit_from_word(z_unit, name="z unit")
    word = (src.units or (None,))[0] or src.tags().get("GISTOOLS_Z_UNIT")
    if not word:
        raise InputError("raster carries no vertical unit", path=path,
                         hint="Give its vertical unit (m, ft or ftUS): z_unit from Python, 'Vertical unit of the nDSM' "
                              "in QGIS")
    return unit_from_word(word, name=f"{path}: vertical unit")


# ---------------------------------------------------------------- the steps

def ndsm_from_rasters(dsm, dem, out, *, overwrite: bool = True, block: int = BLOCK,
                      progress: ProgressCallback | None = None) -> Path:
    """nDSM = DSM - DEM (heights above ground) on the DSM's grid; nodata where either has no value.

    Parameters
    ----------
    dsm : str or path
        The DSM raster (GeoTIFF or VRT).
    dem : str or path
        The DEM raster, on the DSM's grid.
    out : str or path
        The nDSM GeoTIFF written (float32, heights in the vertical unit).
    overwrite : bool
        Replace ``out`` when it exists.
    block : int
        Rows and columns computed at a time (bounds memory).
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    InputError
        The rasters are not on one grid, or ``out`` is one of them.

    Examples
    --------
    >>> from gistools import ndsm_from_rasters, rasters_from_tiles
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> ndsm_from_rasters("rasters/dsm.vrt", "rasters/dem.vrt", "ndsm.tif")  # doctest: +SKIP
    PosixPath('ndsm.tif')
    """
    check_outputs_are_not_inputs({"out": out}, [dsm, dem])
    with open_raster(dsm, "DSM") as s_dsm, open_raster(dem, "DEM") as s_dem:
        same_grid(s_dsm, dsm, s_dem, dem)
        unit = (s_dsm.units or (None,))[0] or (s_dem.units or (None,))[0] or s_dsm.tags().get("GISTOOLS_Z_UNIT")

        def compute(win):
            return {"ndsm": ndsm_from(read_window(s_dsm, s_dsm, win), read_window(s_dem, s_dsm, win))}

        tags = {"GISTOOLS_PRODUCT": "ndsm", **({"GISTOOLS_Z_UNIT": unit, "units": unit} if unit else {})}
        return run_blockwise(s_dsm, {"ndsm": (out, "float32", NODATA, tags)}, compute, progress=progress, label="nDSM",
                          overwrite=overwrite, block=block)["ndsm"]


@shared_sections
def bands_from_ndsm(ndsm, out, *, top_class=None, preset: str = DEFAULTS.bands, breaks_m=None, thresholds=None,
                    noise_floor: str | float = DEFAULTS.noise_floor, z_unit: str | None = None, points_out=None, overwrite: bool = True,
                    block: int = BLOCK, progress: ProgressCallback | None = None) -> dict:
    """Height bands of an nDSM raster: 0 (B0, up to the noise floor), 1-3 (B1-B3), 4 (above T3), 255 nodata.

    Thresholds in metres (``preset``, or ``breaks_m``) are converted to the nDSM's vertical unit, read from the raster
    (or ``z_unit``); or ``thresholds`` gives T1, T2, T3 in that unit.

    Parameters
    ----------
    ndsm : str or path
        The nDSM raster (heights above ground).
    out : str or path
        The bands GeoTIFF written (uint8).
    top_class : str or path, optional
        The raster of each cell's highest first return's class (``topclass``): cells topped by a ground or water
        point are B0.
    preset : str
        ``"exact"`` (1, 2, 6 m) or ``"text_literal"``.
    breaks_m : sequence of float, optional
        Three band breaks in metres, instead of the preset.
    thresholds : sequence of float, optional
        T1, T2, T3 in the nDSM's vertical unit, instead of the above.
    noise_floor : str or float
        Heights up to this are B0: text with its unit (``"0.1m"``), or a number in the vertical unit.
    z_unit : str, optional
        The nDSM's vertical unit (``"m"``, ``"ft"``, ``"ftUS"``) when the raster does not say.
    points_out : str or path, optional
        Also write the cell-centre points of B0-B3 with their band and height (``grid_code``), a GeoPackage layer
        ``band_points``.
    {raster_run}

    Returns
    -------
    dict
        ``bands`` (the path), ``thresholds`` (T1, T2, T3 in the vertical unit), ``z_unit`` (its name) and, with
        ``points_out``, ``points``.

    Raises
    ------
    InputError
        An option is not valid, the vertical unit is unknown, or an output is an input.

    Examples
    --------
    >>> from gistools import bands_from_ndsm, rasters_from_tiles
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> result = bands_from_ndsm("rasters/ndsm.vrt", "bands.tif", breaks_m=(1, 2, 6))  # doctest: +SKIP
    >>> result["z_unit"]  # doctest: +SKIP
    'US survey foot'
    """
    check_length(noise_floor, "noise floor", allow_equal=True, example="0.1m")
    if breaks_m is not None:
        check_breaks(breaks_m, "band breaks", count=3, low=0, high=float("inf"), low_open=True, example="1,2,6")
    check_outputs_are_not_inputs({"out": out, "points": points_out}, [ndsm, top_class])
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(open_raster(ndsm, "nDSM"))
        top = stack.enter_context(open_raster(top_class, "top class")) if top_class else None
        if top is not None:
            same_grid(src, ndsm, top, top_class)
        unit = _z_unit(src, ndsm, z_unit)
        thresholds = tuple(thresholds) if thresholds is not None else band_thresholds(unit, preset, breaks_m)
        floor = length_to_crs_units(noise_floor, unit, name="noise floor")
        crs = raster_crs(src, ndsm)
        writer = _PointWriter(points_out, crs, overwrite) if points_out else None
        if writer:
            stack.enter_context(writer)

        def compute(win):
            h = read_window(src, src, win)
            ground = np.isin(read_window(top, src, win, fill=255), GROUNDISH) if top is not None else None
            codes = height_bands(h, thresholds, top_is_ground=ground, noise_floor=floor)
            if writer:
                writer.add(codes, h, src.window_transform(win))
            return {"bands": codes}

        tags = {"GISTOOLS_PRODUCT": "bands", "GISTOOLS_BAND_THRESHOLDS": json.dumps(list(thresholds)),
                "GISTOOLS_Z_UNIT": unit.short}
        paths = run_blockwise(src, {"bands": (out, "uint8", BAND_NODATA, tags)}, compute, progress=progress, label="bands",
                           overwrite=overwrite, block=block)
    result = {"bands": paths["bands"], "thresholds": thresholds, "z_unit": unit.name}
    if points_out:
        result["points"] = Path(points_out)
    return result


class _PointWriter:
    """Cell-centre points of bands B0-B3 appended block by block to a GeoPackage layer, renamed into place at the end."""

    def __init__(self, path, crs, overwrite):
        self.path, self.crs, self.overwrite = Path(path), crs, overwrite
        self.layer = "band_points"
        self._ctx = None
        self.count = 0

    def __enter__(self):
        self._ctx = atomic_path(self.path, overwrite=self.overwrite, keep_suffix=True, verify=verify_gpkg)
        self.gpkg = self.tmp = self._ctx.__enter__()
        return self

    def add(self, codes, h, transform):
        import geopandas as gpd
        import pyogrio

        rows, cols = np.nonzero(codes <= 3)
        xs, ys = affine_apply(transform, (cols + 0.5, rows + 0.5))
        gdf = gpd.GeoDataFrame({"band": np.asarray(BAND_NAMES)[codes[rows, cols]], "grid_code": h[rows, cols]},
                               geometry=shapely.points(xs, ys), crs=self.crs)
        pyogrio.write_dataframe(gdf, self.gpkg, layer=self.layer, driver="GPKG", append=self.count > 0,
                                dataset_options=None if self.count > 0 else GPKG_OPTIONS)
        self.count += len(gdf)

    def __exit__(self, *exc):
        try:
            if exc[0] is None and self.count == 0:
                import geopandas as gpd

                gpd.GeoDataFrame({"band": [], "grid_code": []}, geometry=[], crs=self.crs).to_file(
                    self.gpkg, layer=self.layer, driver="GPKG", **GPKG_OPTIONS)
        except BaseException:
            self._ctx.__exit__(*sys.exc_info())
            raise
        return self._ctx.__exit__(*exc)


@shared_sections
def breakline_polygons(*, roads=None, hydro=None, waterbodies=None, tile_index=None, tile_field: str = DEFAULTS.tile_field,
                       road_out=None, water_out=None, crs=None, reproject: bool = False, snap: str | float = DEFAULTS.snap,
                       max_road_width: str | float = DEFAULTS.max_road_width,
                       max_hydro_width: str | float = DEFAULTS.max_hydro_width,
                       single_line_width: str | float = DEFAULTS.single_line_width, overwrite: bool = True,
                       progress: ProgressCallback | None = None) -> dict:
    """Road and water polygons from breaklines: split by each tile footprint, noded, polygonised.

    All layers must share one CRS (``crs``, else the first layer's) unless ``reproject``. Without a tile index the lines'
    extent is one frame. One polygon is written per tile and kind, with the tile number in ``tile_field``.

    Parameters
    ----------
    {breaklines_in}
    tile_index : str, optional
        Tile footprints, likewise.
    tile_field : str
        The tile index's field holding the tile number.
    road_out : str or path, optional
        The road polygons' GeoPackage written.
    water_out : str or path, optional
        The water polygons' GeoPackage written.
    crs : str, optional
        The CRS of the layers (e.g. ``"EPSG:2882"``); None: the first layer's.
    reproject : bool
        Reproject layers in another CRS (else they are refused).
    snap : str or float, optional
        Line ends this close are joined: text with its unit (``"0.2ft"``) or a number in CRS units; None: the default
        in the data's unit.
    max_road_width : str or float, optional
        Widest road polygon, likewise.
    max_hydro_width : str or float, optional
        Widest water polygon between hydro lines, likewise.
    single_line_width : str or float, optional
        Width given to a single hydro line, likewise.
    overwrite : bool
        Replace outputs that exist.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.

    Returns
    -------
    dict
        ``road`` and ``water`` (the paths written, or None) and ``crs`` (its WKT).

    Raises
    ------
    InputError
        A length is not valid, or the layers are in different CRSs.
    DataFileError
        A layer cannot be read.

    Examples
    --------
    >>> from gistools import breakline_polygons
    >>> B = "sample_tiles/breaklines.gpkg"
    >>> result = breakline_polygons(roads=f"{B}:ROADBREAKLINE", waterbodies=f"{B}:WATERBODY",
    ...                             tile_index=f"{B}:FOOTPRINT", road_out="roads.gpkg",
    ...                             water_out="water.gpkg")  # doctest: +SKIP
    >>> str(result["road"]), str(result["water"])  # doctest: +SKIP
    ('roads.gpkg', 'water.gpkg')
    """
    if snap is not None:
        check_length(snap, "snap", allow_equal=True, example="0.2ft")
    for value, name in ((max_road_width, "max road width"), (max_hydro_width, "max hydro width"),
                        (single_line_width, "single-line hydro width")):
        if value is not None:
            check_length(value, name, example="60ft")
    layers = {"roads": roads, "hydro": hydro, "waterbodies": waterbodies, "tile index": tile_index}
    loaded, target = _breakline_layers(layers, crs, reproject)
    unit = horizontal_unit(target)
    feet = unit.is_foot  # the lengths left to the data's unit: their default in it
    snap, max_road_width, max_hydro_width, single_line_width = (
        default_for(name, feet) if value is None else value
        for name, value in (("snap", snap), ("max_road_width", max_road_width), ("max_hydro_width", max_hydro_width),
                            ("single_line_width", single_line_width)))
    length = lambda v, n: length_to_crs_units(v, unit, name=n)  # noqa: E731
    p = dict(snap=length(snap, "snap"), max_road=length(max_road_width, "max road width"),
             max_hydro=length(max_hydro_width, "max hydro width"), single=length(single_line_width, "single-line hydro width"))
    geoms = {k: [g for g in gdf.geometry if g is not None and not g.is_empty] for k, gdf in loaded.items()}
    frames = _breakline_frames(loaded, geoms, tile_field, tile_index, p["snap"])
    trees = {k: shapely.STRtree(v) for k, v in geoms.items()}

    def near(kind, frame):
        return [geoms[kind][i] for i in trees[kind].query(frame)] if kind in trees else []

    rows = {"road": [], "water": []}
    for i, (tile, frame) in enumerate(frames):
        report(progress, i / max(len(frames), 1), f"breaklines: tile {tile} ({i + 1} of {len(frames)})")
        road = road_polygons(near("roads", frame), frame, snap=p["snap"], max_width=p["max_road"])
        water = water_polygons(near("hydro", frame), near("waterbodies", frame), frame, snap=p["snap"],
                               max_width=p["max_hydro"], single_line_width=p["single"])
        for kind, geom in (("road", road), ("water", water)):
            if not geom.is_empty:
                rows[kind].append({tile_field: tile, "geometry": geom})
    report(progress, 1.0, "breaklines: writing")
    result = {"crs": target.to_wkt()}
    for kind, path in (("road", road_out), ("water", water_out)):
        if path is not None:
            result[kind], result[f"{kind}_count"] = _write_kind(rows[kind], path, target, tile_field, overwrite)
    return result


def _breakline_layers(layers: dict, crs, reproject) -> tuple[dict, pyproj.CRS]:
    """The given layers, checked for geometry type and read in one CRS: the tile index's (the tiles' grid),
    else ``crs``, else the first layer's."""
    kinds = {"roads": ("line",), "hydro": ("line",), "waterbodies": ("polygon",), "tile index": ("polygon",)}
    loaded = {k: read_layer(v, kinds[k], k) for k, v in layers.items() if v}
    if not loaded:
        raise InputError("no breakline layer given", hint="Give road lines and/or hydro lines or water bodies")
    first = "tile index" if "tile index" in loaded else next(iter(loaded))
    target = pyproj.CRS.from_user_input(crs) if crs else pyproj.CRS.from_user_input(loaded[first].crs)
    against = "the given" if crs else f"the {first} layer's ({layers[first]})"
    return {k: check_crs(g, target, str(layers[k]), reproject=reproject, against=against) for k, g in loaded.items()}, target


def _breakline_frames(loaded: dict, geoms: dict, tile_field: str, tile_index, snap: float) -> list:
    """(tile, footprint) of each tile of the index, or one frame around every line."""
    if "tile index" not in loaded:
        every = [g for k in ("roads", "hydro", "waterbodies") for g in geoms.get(k, [])]
        return [("all", shapely.box(*shapely.total_bounds(every)).buffer(snap * 10, join_style="mitre"))]
    idx = loaded["tile index"]
    check_field(idx, tile_field, tile_index)
    return [(str(t), g) for t, g in zip(idx[tile_field], idx.geometry) if g is not None and not g.is_empty]


def _write_kind(rows: list, path, crs, tile_field: str, overwrite: bool):
    import geopandas as gpd

    gdf = gpd.GeoDataFrame(rows, geometry="geometry", crs=crs) if rows else \
        gpd.GeoDataFrame({tile_field: []}, geometry=gpd.GeoSeries([], crs=crs), crs=crs)
    gdf["area"] = gdf.geometry.area
    return write_layer(gdf, path, Path(path).stem, overwrite=overwrite), len(gdf)


def _polygon_mask(spec, crs, reproject, against) -> PolygonMask:
    """The cell mask of a polygon layer (path or ``file.gpkg:LAYER``), or of a list of shapely polygons in ``crs``."""
    if not spec:
        return PolygonMask([])
    if isinstance(spec, (list, tuple)):
        return PolygonMask(spec)
    gdf = check_crs(read_layer(spec, ("polygon",), "polygon layer"), crs, str(spec), reproject=reproject, against=against)
    return PolygonMask(list(gdf.geometry))


def _band_tally(stats: dict, codes, veg_codes, cell_area: float) -> None:
    """Add a window's band areas, nodata cells and wetland vegetation area to ``stats``."""
    for i, name in enumerate(BAND_NAMES):
        stats["band_area"][name] += float(np.count_nonzero(codes == i) * cell_area)
    stats["nodata_cells"] += int(np.count_nonzero(codes == BAND_NODATA))
    stats["cells"] += codes.size
    if veg_codes is not None:
        stats["wetland_vegetation_area"] += float(np.count_nonzero((veg_codes >= 1) & (veg_codes <= 3)) * cell_area)


def _new_band_stats() -> dict:
    return {"band_area": {n: 0.0 for n in BAND_NAMES}, "nodata_cells": 0, "cells": 0, "wetland_vegetation_area": 0.0}


def _band_stats_result(stats: dict) -> dict:
    return {"band_area": stats["band_area"], "nodata_share": stats["nodata_cells"] / max(stats["cells"], 1),
            "wetland_vegetation_area": stats["wetland_vegetation_area"]}


@shared_sections
def clip_bands(bands, out, *, road_polygons=None, water_polygons=None, wetlands=None, wetland_out=None,
               reproject: bool = False, overwrite: bool = True, block: int = BLOCK,
               progress: ProgressCallback | None = None) -> dict:
    """Vegetation = bands minus road minus water, and vegetation inside wetlands, by cell centre.

    Codes: 0 none, 1-3 band, 4 road, 5 water, 255 nodata.

    Parameters
    ----------
    bands : str or path
        The bands raster (`bands_from_ndsm`).
    out : str or path
        The vegetation GeoTIFF written (uint8).
    road_polygons : str, path or list, optional
        Road polygons: a layer (`breakline_polygons`' output, path or ``file.gpkg:LAYER``) or shapely polygons in
        the bands' CRS.
    water_polygons : str, path or list, optional
        Water polygons, likewise.
    wetlands : str, path or list, optional
        Wetland polygons, likewise.
    wetland_out : str or path, optional
        The GeoTIFF of vegetation inside wetlands, written with ``wetlands``.
    reproject : bool
        Reproject layers in another CRS than the bands' (else they are refused).
    {raster_run}

    Returns
    -------
    dict
        ``veg`` (and ``wetveg``) paths, ``band_area`` ({band: area in CRS area units}), ``nodata_share`` (share of
        cells without a value) and ``wetland_vegetation_area`` (CRS area units).

    Raises
    ------
    InputError
        A layer is in another CRS, or an output is an input.

    Examples
    --------
    >>> from gistools import bands_from_ndsm, breakline_polygons, clip_bands, rasters_from_tiles
    >>> B = "sample_tiles/breaklines.gpkg"
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> result = bands_from_ndsm("rasters/ndsm.vrt", "bands.tif")  # doctest: +SKIP
    >>> polygons = breakline_polygons(roads=f"{B}:ROADBREAKLINE", road_out="roads.gpkg")  # doctest: +SKIP
    >>> sorted(clip_bands("bands.tif", "veg.tif", road_polygons="roads.gpkg")["band_area"])  # doctest: +SKIP
    ['B0', 'B1', 'B2', 'B3']
    """
    check_outputs_are_not_inputs({"out": out, "wet": wetland_out}, [bands])
    with open_raster(bands, "band") as src:
        crs = raster_crs(src, bands)
        masks = {k: _polygon_mask(v, crs, reproject, f"the band raster's ({bands})") for k, v in
                 (("road", road_polygons), ("water", water_polygons), ("wetland", wetlands))}
        stats, cell_area = _new_band_stats(), src.transform.a ** 2

        def compute(win):
            b = read_window(src, src, win)
            veg, wetveg = vegetation(b, masks["road"](src, win), masks["water"](src, win), masks["wetland"](src, win))
            _band_tally(stats, b, wetveg, cell_area)
            return {"veg": veg, "wetveg": wetveg}

        outputs = {"veg": (out, "uint8", VEG_NODATA, {"GISTOOLS_PRODUCT": "veg"}),
                   "wetveg": (wetland_out, "uint8", VEG_NODATA, {"GISTOOLS_PRODUCT": "wetveg"})}
        paths = run_blockwise(src, outputs, compute, progress=progress, label="clip", overwrite=overwrite, block=block)
    return {**paths, **_band_stats_result(stats)}


def nodata_causes(dsm, dem, top_class, *, block: int = BLOCK) -> dict:
    """Why cells have no height band, as shares of all cells (lidar.bands.add_nodata_causes), from the rasters' files.
    The chain takes them from the rasters stage instead where it made the rasters in the same run."""
    with contextlib.ExitStack() as stack:
        s_dsm = stack.enter_context(open_raster(dsm, "DSM"))
        s_dem = stack.enter_context(open_raster(dem, "DEM"))
        s_top = stack.enter_context(open_raster(top_class, "top class"))
        counts: dict = {}

        def compute(win):
            add_nodata_causes(counts, np.isnan(read_window(s_dsm, s_dsm, win)), np.isnan(read_window(s_dem, s_dsm, win)),
                              read_window(s_top, s_dsm, win, fill=255))
            return {}

        run_blockwise(s_dsm, {}, compute, block=block)
    return nodata_cause_shares(counts)


def band_summary(bands, wetveg=None, *, block: int = BLOCK) -> dict:
    """Band areas, nodata share and wetland vegetation area of written rasters (as ``clip_bands`` returns them)."""
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(open_raster(bands, "band"))
        wsrc = stack.enter_context(open_raster(wetveg, "wetland vegetation")) if wetveg else None
        stats, cell_area = _new_band_stats(), src.transform.a ** 2

        def compute(win):
            w = read_window(wsrc, src, win, fill=VEG_NODATA) if wsrc is not None else None
            _band_tally(stats, read_window(src, src, win), w, cell_area)
            return {}

        run_blockwise(src, {}, compute, block=block)
    return _band_stats_result(stats)


@shared_sections
def density_from_vegetation(veg, out, *, density_out=None, radius: str | float = DEFAULTS.radius,
                            density_bands=DEFAULTS.density_bands,
                            like=None, overwrite: bool = True, block: int = BLOCK,
                            progress: ProgressCallback | None = None) -> dict:
    """Cover (0-1) and density of vegetation cells over a circle of ``radius`` around each cell.

    Blocks read a halo of the radius, so block edges do not show.

    Parameters
    ----------
    veg : str or path
        The vegetation raster (`clip_bands`).
    out : str or path
        The cover GeoTIFF written (float32, 0-1).
    density_out : str or path, optional
        Also write the density GeoTIFF (vegetation cells per CRS area unit).
    radius : str or float, optional
        The circle's radius: text with its unit (``"25ft"``) or a number in CRS units; None: 25 ft on data in feet,
        7.5 m in metres.
    density_bands : sequence of int
        The bands (1-3) whose vegetation counts.
    like : str or path, optional
        A raster on the same lattice (a tile) whose grid the outputs take, ``veg`` then being the mosaic holding its
        neighbours, so tile edges do not show either.
    {raster_run}

    Returns
    -------
    dict
        ``cover`` (and ``density``) paths and ``radius`` (in CRS units).

    Raises
    ------
    InputError
        The radius or the bands are not valid, or an output is an input.

    Examples
    --------
    >>> from gistools import density_from_vegetation, shrub_from_tiles
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> density_from_vegetation("shrub/veg.vrt", "cover.tif", radius="50ft")["radius"]  # doctest: +SKIP
    50.0
    """
    if radius is not None:
        check_length(radius, "density radius", example="25ft")
    check_outputs_are_not_inputs({"out": out, "density": density_out}, [veg, like])
    if not density_bands or any(b not in (1, 2, 3) for b in density_bands):
        raise InputError(f"density bands {tuple(density_bands)} must be among 1, 2, 3", hint="e.g. 1,2,3")
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(open_raster(veg, "vegetation"))
        base = stack.enter_context(open_raster(like, "tile")) if like else src
        if like:
            same_grid(src, veg, base, like)
        unit = horizontal_unit(raster_crs(src, veg))
        radius = default_for("radius", unit.is_foot) if radius is None else radius  # 25 ft, or 7.5 m
        r = length_to_crs_units(radius, unit, name="density radius")
        cs = src.transform.a
        halo = halo_cells(r, cs)

        def compute(win):
            big = read_window(src, base, win, halo=halo, fill=0)
            density, cover = vegetation_cover(big, cs, r, tuple(density_bands), halo)
            return {"cover": cover, "density": density}

        outputs = {"cover": (out, "float32", NODATA, {"GISTOOLS_PRODUCT": "cover", "GISTOOLS_RADIUS": r}),
                   "density": (density_out, "float32", NODATA, {"GISTOOLS_PRODUCT": "density"})}
        paths = run_blockwise(base, outputs, compute, progress=progress, label="density", overwrite=overwrite, block=block)
    return {**paths, "radius": r}


def class_breaks(cover, method: str = DEFAULTS.classify, breaks=DEFAULTS.class_breaks, *, block: int = BLOCK) -> tuple[float, float]:
    """The class breaks: ``breaks`` as given, or quantile / Jenks breaks of a cover raster (a tile, a mosaic)
    on the sample lattice (lidar.shrub.lattice_sample), read block by block: the same cells and breaks
    whatever the tiling and the block size."""
    if method not in ("breaks", "quantile", "jenks"):
        raise InputError(f"classification {method!r} is not one of breaks, quantile, jenks")
    if method == "breaks":
        check_breaks(breaks, "class breaks", count=2, low=0, high=1, example="0.3,0.7")
        return tuple(breaks)  # type: ignore[return-value]
    with open_raster(cover, "cover") as src:
        step = sample_step(src.width * src.height)
        cs = src.transform.a
        keys, values = [], []
        for win in windows(src.width, src.height, block):
            t = src.window_transform(win)
            k, v = lattice_sample(read_window(src, src, win), int(round(t.c / cs)), int(round(t.f / cs)), step)
            keys.append(k)
            values.append(v)
    return breaks_from_sample(keys, values, method)


def _class_tally(codes, transform, cell_area: float, area: dict, polys: list | None) -> None:
    """Add a window's class areas (and class polygons, one per class and window) to ``area`` / ``polys``."""
    for code, name in CLASS_NAMES.items():
        area[name] += float(np.count_nonzero(codes == code) * cell_area)
    if polys is not None:
        polys.extend(class_polygons(codes, transform, mask=(codes >= 1) & (codes <= 5)).items())


@shared_sections
def classes_from_cover(cover, out, *, veg=None, polygons_out=None, method: str = DEFAULTS.classify,
                       breaks=DEFAULTS.class_breaks,
                       keep_polygons: bool = False, overwrite: bool = True, block: int = BLOCK,
                       progress: ProgressCallback | None = None) -> dict:
    """Shrub classes from cover: 0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water, 255 nodata.

    Parameters
    ----------
    cover : str or path
        The cover raster (`density_from_vegetation`).
    out : str or path
        The classes GeoTIFF written (uint8, with its colour table).
    veg : str or path, optional
        The vegetation raster (`clip_bands`), which marks road and water.
    polygons_out : str or path, optional
        Also write the classes as polygons (a GeoPackage; one feature per class and block, with its area).
    method : str
        ``"breaks"`` (``breaks`` on the cover fraction), ``"quantile"`` (equal areas) or ``"jenks"`` (Jenks natural
        breaks), the latter two found in a sample of the cover.
    breaks : sequence of float
        Two cover fractions (0-1) between light / medium and medium / heavy, with ``"breaks"``.
    keep_polygons : bool
        Return the polygons as ``[(code, polygon)]`` instead of writing them.
    {raster_run}

    Returns
    -------
    dict
        ``classes`` (the path), ``breaks`` (the two used), ``class_area`` ({class name: area in CRS area units}) and,
        with ``polygons_out`` or ``keep_polygons``, ``polygons``.

    Raises
    ------
    InputError
        An option is not valid, or an output is an input.

    Examples
    --------
    >>> from gistools import classes_from_cover, shrub_from_tiles
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> result = classes_from_cover("shrub/cover.vrt", "classes.tif", veg="shrub/veg.vrt", breaks=(0.2, 0.6))  # doctest: +SKIP
    >>> result["breaks"]  # doctest: +SKIP
    (0.2, 0.6)
    """
    use = class_breaks(cover, method, breaks, block=block)
    check_outputs_are_not_inputs({"out": out, "polygons": polygons_out}, [cover, veg])
    polys = [] if (polygons_out or keep_polygons) else None
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(open_raster(cover, "cover"))
        vsrc = stack.enter_context(open_raster(veg, "vegetation")) if veg else None
        if vsrc is not None:
            same_grid(src, cover, vsrc, veg)
        area = {name: 0.0 for name in CLASS_NAMES.values()}
        cell_area = src.transform.a ** 2

        def compute(win):
            c = read_window(src, src, win)
            v = read_window(vsrc, src, win, fill=VEG_NODATA) if vsrc is not None else None
            codes = shrub_classes(c, use, road=None if v is None else v == VEG_ROAD,
                                  water=None if v is None else v == VEG_WATER, nodata=np.isnan(c))
            _class_tally(codes, src.window_transform(win), cell_area, area, polys)
            return {"classes": codes}

        tags = {"GISTOOLS_PRODUCT": "classes", "GISTOOLS_CLASSES": json.dumps(CLASS_NAMES),
                "GISTOOLS_CLASS_BREAKS": json.dumps(list(use)), "categories": CLASS_STYLE}
        paths = run_blockwise(src, {"classes": (out, "uint8", CLASS_NODATA, tags)}, compute, progress=progress,
                              label="classes", overwrite=overwrite, block=block)
        crs = raster_crs(src, cover)
    result = {"classes": paths["classes"], "breaks": use, "class_area": area}
    if keep_polygons:
        result["polygons"] = polys
    elif polygons_out:
        import geopandas as gpd

        gdf = gpd.GeoDataFrame({"class_code": [c for c, _ in polys], "class": [CLASS_NAMES[c] for c, _ in polys]},
                               geometry=[g for _, g in polys], crs=crs)
        gdf["area"] = gdf.geometry.area
        result["polygons"] = write_layer(gdf, polygons_out, Path(polygons_out).stem, overwrite=overwrite)
        write_polygon_style(polygons_out, "class_code", {c: v for c, v in CLASS_STYLE.items() if c})
    return result


def class_summary(classes, *, block: int = BLOCK) -> dict:
    """Class areas and class polygons of a written class raster (as ``classes_from_cover`` returns them)."""
    with open_raster(classes, "classes") as src:
        area, polys, cell_area = {name: 0.0 for name in CLASS_NAMES.values()}, [], src.transform.a ** 2

        def compute(win):
            _class_tally(read_window(src, src, win), src.window_transform(win), cell_area, area, polys)
            return {}

        run_blockwise(src, {}, compute, block=block)
    return {"classes": Path(classes), "class_area": area, "polygons": polys}
