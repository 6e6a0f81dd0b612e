"""Travel time of a walker from the points last seen (``gistools travel``, ``gistools:travel``): minutes to reach every
cell of a DEM, isochrone polygons and bands, for search and rescue.

Speed model (the documentation's "Search and rescue" page states it with its references):

* Tobler's hiking function on the slope along each step, uphill and downhill apart:
  ``v = a exp(-b |dz/dx + c|)`` km/h, ``a`` 6 km/h, ``b`` 3.5, ``c`` 0.05 (Tobler 1993);
* times a vegetation factor per shrub class of the shrub chain (none 1, light 0.92, medium 0.83, heavy 0.75; after
  Campbell, Dennison & Butler 2017: dense vegetation cut travel rates by up to about a quarter beyond the slope);
* road cells clear of shrub (or at a fixed ``road_speed``), water cells impassable (or waded at ``wade_speed``).

Algorithm: a directed graph of the grid (8 or 16 neighbours: the 16 add the knight moves), each step weighted by its
length times the mean of the two end cells' slowness on the step's slope (the slope seen from the step's start: up
one way, down the other), solved by ``scipy.sparse.csgraph.dijkstra(indices=sources, min_only=True)`` (the time from
the nearest source). The whole grid's graph (about ``BYTES_PER_CELL`` bytes a cell at 16 neighbours) when it fits
``max_memory``; else block by block (``plan_memory``): the cell arrays whole (``CELL_BYTES`` a cell), the graph of
one block and a halo of ``HALO`` cells at a time, solved again while a neighbour's solve lowers a time in it
(label-correcting, the block with the lowest lowered time first), to the same shortest paths. A grid whose cell
arrays pass ``max_memory`` is refused from the DEM's width and height, before any cell is read.

The DEM: a projected CRS (a geographic one is refused, naming the UTM zone to warp it to), no rotation (refused: warp
it north-up); a south-up (or east-to-west) DEM is read flipped, north-up. The outputs are one set: written in a
scratch folder, put in place together, report.json last (it records how each output was made, as
``gistools.engine.resume.made_record``), so a rerun keeps a complete set of the same settings, makes again one a
stopped run left, and refuses one of other settings naming both values.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError
from ..grid import affine_apply
from ..terrain.travel import (BYTES_PER_CELL, CELL_BYTES, CLASS_ROAD, CLASS_WATER, ISOCHRONES, NEIGHBOUR_BOUND,
                               SHRUB_FACTORS, TOBLER, neighbour_offsets, plan_memory, tobler_speed, travel_minutes)

log = logging.getLogger("gistools.products.travel")

__all__ = ["TravelSettings", "travel_minutes", "tobler_speed", "neighbour_offsets", "travel_from_dem", "SHRUB_FACTORS",
           "ISOCHRONES", "BYTES_PER_CELL", "CELL_BYTES", "NEIGHBOUR_BOUND", "plan_memory"]

# --- the command: a DEM, its shrub classes, roads and water, the points last seen -> rasters, polygons, report --------

ACRE_M2 = 4046.8564224
HECTARE_M2 = 10000.0
BAND_NODATA = 255
OUTPUTS = ("travel_minutes.tif", "isochrone_bands.tif", "travel.gpkg")
_RAMP = ("#1a9850", "#91cf60", "#fee08b", "#fc8d59", "#d73027", "#7f0000")  # green (soon) to dark red (late)


@dataclass(frozen=True)
class TravelSettings:
    """Parameters of ``gistools travel`` (declared in gistools.parameters.travel). Speeds in km/h; ``tobler``:
    (A km/h, B, C) of v = A exp(-B |s + C|); ``shrub_factors``: light, medium, heavy; ``road_speed`` None: Tobler's
    on the slope without shrub; ``wade_speed`` None: water impassable; ``isochrones`` in minutes; ``max_memory`` in
    GB. Breakline lengths (``snap`` ...) take a unit or are in CRS units; None: the shrub chain's defaults in the
    data's unit."""

    tobler: tuple = TOBLER
    shrub_factors: tuple = SHRUB_FACTORS
    road_speed: float | None = None
    wade_speed: float | None = None
    isochrones: tuple = ISOCHRONES
    neighbours: int | str = 16
    isotropic: bool = False
    max_memory: float = 4.0
    snap: str | float | None = None
    max_road_width: str | float | None = None
    max_hydro_width: str | float | None = None
    single_line_width: str | float | None = None
    reproject_vectors: bool = False

    def validate(self) -> None:
        from ..parameters import PARAMETERS, check, option

        check("isochrones", tuple(sorted(float(v) for v in self.isochrones)))
        for name, high in (("tobler", None), ("shrub_factors", 1.0)):  # three numbers, not a rising list
            values = tuple(getattr(self, name))
            if len(values) != 3 or not all(np.isfinite(v) and v >= 0 and (high is None or v <= high) for v in values):
                raise InputError(f"{option(name, values)}: give three numbers, each at least 0"
                                 + (f" and at most {high:g}" if high else ""),
                                 hint=f"e.g. {option(name, PARAMETERS[name].default)}")
        for name in ("road_speed", "wade_speed", "max_memory", "snap", "max_road_width", "max_hydro_width",
                     "single_line_width"):
            check(name, getattr(self, name))
        check("neighbours", str(self.neighbours))
        if self.tobler[0] <= 0:
            raise InputError(f"{option('tobler', tuple(self.tobler))}: the speed A must be above 0",
                             hint=f"e.g. {option('tobler', (6, 3.5, 0.05))}")
        _check_isochrones(tuple(self.isochrones))


MAX_ISOCHRONES = BAND_NODATA - 2  # codes 1 ... n within them and n + 1 beyond the last, all below the nodata 255


def _check_isochrones(values: tuple) -> None:
    """Isochrones are finite minutes above 0 (NaN and infinity are refused: report.json is JSON), at most
    ``MAX_ISOCHRONES`` of them (each a code of the uint8 bands raster, one more beyond the last, 255 no data)."""
    from ..parameters import option

    example = f"e.g. {option('isochrones', '30,60,120,240')}"
    given = ",".join(f"{float(v):g}" for v in values)
    if not all(math.isfinite(float(v)) for v in values):
        raise InputError(f"{option('isochrones', given)}: every isochrone must be a finite number of minutes "
                         "(not nan or inf)", hint=example)
    if not values or min(values) <= 0:
        raise InputError(f"{option('isochrones', given or 'none')}: give minutes above 0", hint=example)
    if len(values) > MAX_ISOCHRONES:
        raise InputError(f"{option('isochrones')}: {len(values)} isochrones need {len(values) + 1} band codes (one "
                         f"each and one beyond the last) but isochrone_bands.tif (uint8) has {MAX_ISOCHRONES + 1} "
                         f"(1-{MAX_ISOCHRONES + 1}; {BAND_NODATA} is no data)",
                         hint=f"Give at most {MAX_ISOCHRONES} isochrones")


def _point_text(text):
    """(x, y) of "X,Y", else None."""
    parts = str(text).replace(" ", "").split(",")
    if len(parts) != 2:
        return None
    try:
        return float(parts[0]), float(parts[1])
    except ValueError:
        return None


def _last_seen_points(last_seen, crs, reproject: bool) -> list[tuple[float, float, str]]:
    """(x, y, where from) of every point last seen: "X,Y" texts, (x, y) pairs or point layers."""
    from ..parameters import option

    items = [last_seen] if isinstance(last_seen, (str, Path)) else list(last_seen or [])
    if items and all(isinstance(v, (int, float)) for v in items) and len(items) == 2:
        items = [tuple(items)]
    points = [p for item in items for p in _points_of(item, crs, reproject)]
    if not points:
        raise InputError(f"no point last seen: give {option('last_seen')}",
                         hint=f"e.g. {option('last_seen', '431000,1811000')} (X,Y in the DEM's CRS) or a point layer")
    return points


FROM_HINT = "Give X,Y in the DEM's CRS (two numbers, e.g. {}) or a point layer (file.gpkg:LAYER)"


def _points_of(item, crs, reproject: bool) -> list[tuple[float, float, str]]:
    """The points last seen of one ``last_seen`` item: an (x, y) pair, an "X,Y" text or a point layer."""
    from ..io.vector import check_crs, read_layer, split_layer_spec
    from ..parameters import option

    if isinstance(item, (tuple, list)) and len(item) == 2:
        return [_finite_point(float(item[0]), float(item[1]), f"{item[0]},{item[1]}")]
    xy = _point_text(item)
    if xy is not None:
        return [_finite_point(*xy, str(item))]
    if not str(item).strip() or not split_layer_spec(item)[0].exists():  # "", "1,2,3", a file that is not there
        raise InputError(f"{option('last_seen', str(item))} is neither X,Y nor a point layer that exists",
                         hint=FROM_HINT.format(option('last_seen', '431000,1811000')))
    gdf = check_crs(read_layer(item, kinds=("point",), what=option("last_seen")), crs, str(item),
                    reproject=reproject, against="the DEM's")
    return [_finite_point(g.x, g.y, str(item)) for g in gdf.geometry.explode(index_parts=False)
            if g is not None and not g.is_empty]


def _finite_point(x: float, y: float, where: str) -> tuple[float, float, str]:
    from ..parameters import option

    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{option('last_seen', where)}: the coordinates must be finite numbers (not nan or inf)",
                         hint=FROM_HINT.format(option('last_seen', '431000,1811000')))
    return x, y, where


def _dem_inputs(dem, classes):
    """(DEM raster, classes raster or None) of a raster, or of a gistools output folder (its dem.vrt, classes.vrt)."""
    from ..parameters import option

    path = Path(dem)
    if not path.exists():
        raise DataFileError("not found", path=path, hint=f"Give {option('dem')} a DEM raster or VRT, or a gistools "
                            "rasters / shrub output folder")
    if path.is_dir():
        found = path / "dem.vrt"
        if not found.exists():
            raise InputError("the folder has no dem.vrt", path=path,
                             hint="Give the DEM raster, or the output folder of gistools rasters or gistools shrub")
        if classes is None and (path / "classes.vrt").exists():
            classes = path / "classes.vrt"
        path = found
    return path, (Path(classes) if classes is not None else None)


@dataclass(frozen=True)
class _Dem:
    """What travel knows of a DEM before reading its cells: its north-up grid, units, and how its rows and columns
    run (``flip_rows``: south-up, ``flip_cols``: east to west; read flipped to north-up)."""

    path: Path
    grid: object
    xy: object
    z: object
    flip_rows: bool
    flip_cols: bool


def _dem_meta(path) -> _Dem:
    """The DEM's grid (north-up), horizontal and vertical units, from its header: nothing of its cells is read.
    Refused: no CRS, a geographic CRS, a rotated geotransform, cells that are not square."""
    import rasterio
    from affine import Affine

    from ..grid import Grid
    from ..io.raster import crs_from_wkt
    from ..units import horizontal_unit, unit_from_word, vertical_unit

    try:
        with rasterio.open(path) as src:
            t, width, height, word = src.transform, src.width, src.height, (src.units or (None,))[0]
            crs = crs_from_wkt(src.crs.to_wkt()) if src.crs else None
    except rasterio.errors.RasterioError as err:
        raise DataFileError(f"cannot read the DEM ({err})", path=path) from None
    if crs is None:
        raise InputError("the DEM has no CRS", path=path, hint="Assign one (gdal_edit.py -a_srs) so its units are known")
    _refuse_geographic(path, crs, t, width, height)
    if t.b != 0 or t.d != 0:
        raise InputError(f"the DEM is rotated (geotransform rotation terms {t.b:g}, {t.d:g})", path=path,
                         hint="Warp it north-up first (gdalwarp)")
    if abs(abs(t.a) - abs(t.e)) > 1e-9 * abs(t.a):
        raise InputError(f"the DEM's cells are not square ({abs(t.a):g} x {abs(t.e):g})", path=path,
                         hint="Resample it to square cells (gdalwarp -tr)")
    west = t.c + min(0.0, t.a * width)
    north = t.f + max(0.0, t.e * height)
    grid = Grid(Affine(abs(t.a), 0.0, west, 0.0, -abs(t.e), north), width, height, crs)
    z = unit_from_word(word) if word else vertical_unit(crs)
    return _Dem(Path(path), grid, horizontal_unit(crs), z, bool(t.e > 0), bool(t.a < 0))


def _refuse_geographic(path, crs, t, width: int, height: int) -> None:
    """A DEM in degrees (latitude / longitude) is refused, naming the UTM zone of its centre to warp it to."""
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if not horizontal.is_geographic:
        return
    lon, lat = affine_apply(t, (width / 2, height / 2))
    epsg = "<the code of a projected CRS in metres or feet>"  # a centre off the globe: no zone to name
    if -180 <= lon <= 180 and -80 <= lat <= 84:
        epsg = f"{(32600 if lat >= 0 else 32700) + int((lon + 180) // 6) % 60 + 1} (its centre's UTM zone)"
    raise InputError(f"the DEM is in a geographic CRS ({horizontal.name}: degrees); travel needs a CRS in metres or "
                     "feet", path=path, hint=f"Warp it first: gdalwarp -t_srs EPSG:{epsg} {Path(path).name} "
                                             "dem_projected.tif")


def _read_heights(dem: _Dem) -> np.ndarray:
    """The DEM's heights (float64, NaN for nodata), rows north to south and columns west to east."""
    from ..io.raster import read_raster

    data, _grid, nodata = read_raster(dem.path)
    if not np.issubdtype(data.dtype, np.floating):
        data = data.astype(np.float64)
        if nodata is not None:
            data[data == nodata] = np.nan
    if dem.flip_rows:
        data = data[::-1]
    if dem.flip_cols:
        data = data[:, ::-1]
    return np.ascontiguousarray(data)


def _classes_on(path, grid) -> np.ndarray:
    """The classes raster on the DEM's grid (nearest cell; 255 outside it)."""
    import pyproj
    import rasterio
    from rasterio.enums import Resampling
    from rasterio.vrt import WarpedVRT

    try:
        with rasterio.open(path) as src:
            if src.crs is not None and grid.crs is not None and \
                    not pyproj.CRS.from_wkt(src.crs.to_wkt()).equals(grid.crs, ignore_axis_order=True):
                raise InputError("the classes raster's CRS differs from the DEM's", path=path,
                                 hint="Give the classes of the same survey (gistools shrub's classes.vrt)")
            with WarpedVRT(src, transform=grid.transform, width=grid.width, height=grid.height,
                           resampling=Resampling.nearest, nodata=BAND_NODATA) as vrt:
                return vrt.read(1)
    except rasterio.errors.RasterioError as err:
        raise DataFileError(f"cannot read the classes raster ({err})", path=path) from None


def _burn(geoms, grid) -> np.ndarray:
    """Cells whose centre is in ``geoms`` (as Polygon To Raster's cell-centre rule)."""
    from rasterio.features import rasterize

    geoms = [g for g in geoms if g is not None and not g.is_empty]
    if not geoms:
        return np.zeros((grid.height, grid.width), dtype=bool)
    return rasterize(geoms, out_shape=(grid.height, grid.width), transform=grid.transform, fill=0,
                     default_value=1, dtype="uint8").astype(bool)


def _lines_of(spec, crs, what, reproject, kinds):
    from ..io.vector import check_crs, read_layer

    if spec is None:
        return []
    gdf = check_crs(read_layer(spec, kinds=kinds, what=what), crs, str(spec), reproject=reproject, against="the DEM's")
    return [g for g in gdf.geometry if g is not None and not g.is_empty]


def speed_model(classes, road, water, settings: TravelSettings) -> tuple[np.ndarray, np.ndarray]:
    """(factor, fixed speed) arrays of the cells: the factor on Tobler's speed (shrub classes 1-3 their factors,
    water 0) and a fixed km/h (roads at ``road_speed``, water at ``wade_speed``; NaN elsewhere). A road cell over
    water is a bridge: road."""
    factor = np.ones(road.shape, dtype=np.float64)
    if classes is not None:
        for code, f in zip((1, 2, 3), settings.shrub_factors):
            factor[classes == code] = f
        road = road | (classes == CLASS_ROAD)
        water = water | (classes == CLASS_WATER)
    fixed = np.full(road.shape, np.nan)
    factor[water] = 0.0
    fixed[water] = np.nan if settings.wade_speed is None else settings.wade_speed
    factor[road] = 1.0  # a road over water is a bridge
    fixed[road] = np.nan if settings.road_speed is None else settings.road_speed
    return factor, fixed


def isochrone_bands(minutes: np.ndarray, isochrones) -> np.ndarray:
    """uint8 band of each cell: 1 within the first isochrone, 2 within the second, ..., len + 1 beyond the last,
    255 where no path reaches."""
    edges = np.asarray(sorted(isochrones), dtype=np.float64)
    band = (np.searchsorted(edges, minutes, side="left") + 1).astype(np.uint8)
    band[~np.isfinite(minutes)] = BAND_NODATA
    return band


def band_categories(isochrones) -> dict:
    """{code: (name, colour)} of the isochrone bands (the raster's colour table and category names)."""
    edges = [0.0, *sorted(isochrones)]
    cats = {}
    for i in range(1, len(edges)):
        cats[i] = (f"{edges[i - 1]:g}-{edges[i]:g} min", _RAMP[min(i - 1, len(_RAMP) - 2)])
    cats[len(edges)] = (f"over {edges[-1]:g} min", _RAMP[-1])
    return cats


def isochrone_polygons(minutes, grid, isochrones, xy_metres: float):
    """A GeoDataFrame: per isochrone the cells reached within it (dissolved), with ``minutes``, ``area`` (CRS units
    squared), ``hectares`` and ``acres``."""
    import geopandas as gpd
    import shapely
    from rasterio.features import shapes

    rows = []
    for t in sorted(isochrones):
        inside = np.isfinite(minutes) & (minutes <= t)
        polys = [shapely.geometry.shape(g) for g, v in shapes(inside.astype(np.uint8), mask=inside,
                                                              transform=grid.transform) if v == 1]
        geom = shapely.union_all(polys) if polys else shapely.MultiPolygon()
        if geom.geom_type == "Polygon":
            geom = shapely.MultiPolygon([geom])
        area = float(geom.area)
        m2 = area * xy_metres ** 2
        rows.append({"minutes": float(t), "area": area, "hectares": m2 / HECTARE_M2, "acres": m2 / ACRE_M2,
                     "geometry": geom})
    return gpd.GeoDataFrame(rows, geometry="geometry", crs=grid.crs.to_wkt())


def _start_cells(points, grid) -> list[tuple[int, int]]:
    """(row, column) of each point; a point outside the DEM is refused."""
    from ..parameters import option

    inv = ~grid.transform
    cells = []
    for x, y, where in points:
        col, row = affine_apply(inv, (x, y))
        r, c = int(math.floor(row)), int(math.floor(col))
        if not (0 <= r < grid.height and 0 <= c < grid.width):
            w, s, e, n = grid.bounds
            raise InputError(f"the point last seen {x:.3f},{y:.3f} ({where}) is outside the DEM "
                             f"({w:.3f},{s:.3f} - {e:.3f},{n:.3f})", hint=f"Give {option('last_seen')} in the DEM's CRS")
        cells.append((r, c))
    return cells


def _check_starts(points, cells, passable, water) -> None:
    """Refuse a point last seen on a cell the walker cannot be on."""
    from ..parameters import option

    for (x, y, where), (r, c) in zip(points, cells):
        if not passable[r, c]:
            why = "water (impassable)" if water[r, c] else "no DEM there"
            raise InputError(f"the point last seen {x:.3f},{y:.3f} ({where}) is on a cell the walker cannot be: {why}",
                             hint=f"Move it onto land, or let the walker wade: {option('wade_speed', 1.0)}"
                             if water[r, c] else "Move it onto the DEM's data")


def _roads_and_water(grid, roads, hydro, waterbodies, settings, lengths) -> tuple[np.ndarray, np.ndarray]:
    """Cells of the road and water polygons of the breaklines, made as the shrub chain makes them (whole DEM)."""
    from shapely.geometry import box

    from ..parameters import option
    from ..vector.breaklines import road_polygons, water_polygons

    frame = box(*grid.bounds)
    reproject = settings.reproject_vectors
    road = np.zeros(grid.shape, dtype=bool)
    if roads:
        road = _burn([road_polygons(_lines_of(roads, grid.crs, option("roads"), reproject, ("line",)), frame,
                                    snap=lengths["snap"], max_width=lengths["max_road_width"])], grid)
    water = np.zeros(grid.shape, dtype=bool)
    if hydro or waterbodies:
        lines = _lines_of(hydro, grid.crs, option("hydro"), reproject, ("line",))
        bodies = _lines_of(waterbodies, grid.crs, option("waterbodies"), reproject, ("polygon",))
        water = _burn([water_polygons(lines, bodies, frame, snap=lengths["snap"], max_width=lengths["max_hydro_width"],
                                      single_line_width=lengths["single_line_width"])], grid)
    return road, water


def _write_outputs(folder: Path, minutes, grid, settings, points, xy, top: float, style: bool = True):
    """The minutes raster and its style, the isochrone bands, the GeoPackage, in ``folder``; returns the isochrones'
    GeoDataFrame."""
    import geopandas as gpd
    import shapely

    from ..io.atomic import atomic_path
    from ..io.raster import write_raster
    from ..io.styles import pseudocolour_qml
    from ..io.vector import write_layers

    reached = np.isfinite(minutes)
    write_raster(folder / "travel_minutes.tif", np.where(reached, minutes, np.nan), grid, overwrite=True,
                 tags={"GISTOOLS_PRODUCT": "travel_minutes"}, description="travel time (minutes)", units="min")
    if style:
        with atomic_path(folder / STYLE, overwrite=True) as tmp:
            tmp.write_text(pseudocolour_qml(settings.isochrones, top, _RAMP, "min"), encoding="utf-8")
    write_raster(folder / "isochrone_bands.tif", isochrone_bands(minutes, settings.isochrones), grid,
                 nodata=BAND_NODATA, dtype="uint8", overwrite=True, tags={"GISTOOLS_PRODUCT": "isochrone_bands"},
                 description="isochrone band", categories=band_categories(settings.isochrones))
    iso = isochrone_polygons(minutes, grid, settings.isochrones, xy.metres)
    seen = gpd.GeoDataFrame({"source": [w for *_xy, w in points], "x": [p[0] for p in points],
                             "y": [p[1] for p in points]},
                            geometry=[shapely.Point(p[0], p[1]) for p in points], crs=grid.crs.to_wkt())
    write_layers({"isochrones": iso, "last_seen": seen}, folder / "travel.gpkg", overwrite=True)
    return iso


# --- the outputs as one set: written aside, put in place together, recorded last; a rerun keeps or redoes them -------

TOOL = "gistools travel"
STYLE = "travel_minutes.qml"
PRODUCTS = {"minutes": "travel_minutes.tif", "bands": "isochrone_bands.tif", "polygons": "travel.gpkg"}
# the files of one run, in the order they are put in place (the bands' category names in their GDAL sidecar)
SET = ("travel_minutes.tif", STYLE, "isochrone_bands.tif", "isochrone_bands.tif.aux.xml", "travel.gpkg")
INCOMPLETE = ("gistools travel stopped while it was putting new outputs in place: they may mix two runs; a rerun "
              "makes them again")


def _write_set(out: Path, minutes, grid, settings, points, xy, top: float):
    """Write the outputs in a scratch folder under ``out``, then put them in place together: report.json's list of
    how the outputs were made is dropped first (marked ``incomplete``) and written again last (by the caller), so a
    run stopped midway leaves a set a rerun knows to make again. Returns the isochrones' GeoDataFrame."""
    import shutil
    import tempfile

    from ..io.atomic import replace
    from ..io.outdir import SCRATCH_PREFIX
    from ..io.styles import style_is_ours

    staging = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}travel-", dir=out))
    try:  # a run killed in here leaves the scratch folder, which the next run's claim on the folder removes
        iso = _write_outputs(staging, minutes, grid, settings, points, xy, top, style=style_is_ours(out / STYLE))
        _mark_incomplete(out)
        for name in SET:
            if (staging / name).exists():
                replace(staging / name, out / name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return iso


def _mark_incomplete(out: Path) -> None:
    """report.json without its record of how the outputs were made, and saying so, before they are replaced."""
    from ..engine.record import read_folder_report
    from ..io.atomic import atomic_path

    previous = read_folder_report(out)
    if previous is None:
        return  # no record: outputs without one are made again by a rerun
    previous.update(made={}, incomplete=INCOMPLETE)
    with atomic_path(out / "report.json", overwrite=True) as tmp:
        tmp.write_text(json.dumps(previous, indent=2, default=str), encoding="utf-8")


def _fingerprint(settings: TravelSettings, points, dem_path, inputs: dict) -> dict:
    """The settings the outputs depend on, as JSON values (``max_memory`` changes the method, not the minutes)."""
    import dataclasses

    from ..io.vector import absolute_spec

    fields = {k: v for k, v in dataclasses.asdict(settings).items() if k != "max_memory"}
    fields.update(isochrones=sorted(float(v) for v in settings.isochrones), neighbours=int(settings.neighbours),
                  tobler=[float(v) for v in settings.tobler], shrub_factors=[float(v) for v in settings.shrub_factors])
    classes = inputs["classes"]
    raw = {"dem": str(Path(dem_path).resolve()), "last_seen": sorted([x, y] for x, y, _w in points), **fields,
           "shrub_classes": str(Path(classes).resolve()) if classes is not None else None,
           **{k: absolute_spec(inputs[k]) if inputs[k] else None for k in ("roads", "hydro", "waterbodies")}}
    return json.loads(json.dumps(raw, default=str))


def _input_stamps(dem_path, inputs: dict) -> dict:
    """What tells a rerun an input file changed since (gistools.engine.resume.input_stamp), per input."""
    from ..engine.resume import input_stamp
    from ..io.vector import split_layer_spec

    files = {"dem": dem_path, "shrub_classes": inputs["classes"],
             **{k: split_layer_spec(inputs[k])[0] if inputs[k] else None for k in ("roads", "hydro", "waterbodies")}}
    return json.loads(json.dumps({k: input_stamp(f) for k, f in files.items() if f is not None}))


def _ours(path: Path) -> bool:
    """Whether an output file was written by gistools travel: a raster with the gistools tag, the GeoPackage of
    its two layers."""
    from ..engine.resume import written_by_gistools

    if path.suffix.lower() != ".gpkg":
        return written_by_gistools(path)
    try:
        import pyogrio

        return {"isochrones", "last_seen"} <= {str(n) for n, _kind in pyogrio.list_layers(path)}
    except Exception:  # noqa: BLE001 - not a GeoPackage, unreadable: not known to be ours
        return False


def _shown(value) -> str:
    """A setting's value in a message: points as X,Y, numbers as they were given, None as none."""
    if value is None:
        return "none"
    if isinstance(value, list):
        nested = bool(value) and isinstance(value[0], list)
        return (" " if nested else ",").join(_shown(v) for v in value) if value else "none"
    if isinstance(value, float):
        return f"{value:.12g}"
    return str(value)


def _refuse_other_settings(existing: dict, made: dict, now: dict) -> None:
    """InputError naming both values when an output there was made with other settings or from another input."""
    from ..parameters import PARAMETERS, option

    for key, path in existing.items():
        before = made.get(key, {}).get("settings") if isinstance(made.get(key), dict) else None
        if not isinstance(before, dict):
            continue
        for name in [*now, *(k for k in before if k not in now)]:
            if before.get(name) != now.get(name):
                named = option(name) if name in PARAMETERS else name.replace("_", " ")
                raise InputError(f"{path} was made with {named} {_shown(before.get(name))}, this run asks "
                                 f"{_shown(now.get(name))}",
                                 hint=f"Pass {option('overwrite')} to make the outputs again with the new settings, "
                                      "or choose another output folder")


def _complete(out: Path, made: dict, previous: dict, stamps: dict) -> bool:
    """Whether every output is there as the record says it was written, from inputs unchanged since."""
    from ..io.raster import file_stamp

    for key, name in PRODUCTS.items():
        entry, path = made.get(key), out / name
        if not path.exists() or not isinstance(entry, dict) or entry.get("stamp") != file_stamp(path):
            log.info("%s: missing, or changed since it was written: making the outputs again", path)
            return False
    if previous.get("input_stamps") != stamps:
        log.warning("%s: an input changed since its outputs were made: making them again", out)
        return False
    return True


def _refuse_foreign(existing: dict, made: dict) -> None:
    """OutputExistsError for an output file neither recorded nor written by gistools travel (never replaced)."""
    from ..errors import OutputExistsError

    for key, path in existing.items():
        if key not in made and not _ours(path):
            raise OutputExistsError("a file gistools did not write is in the way", path=path,
                                    hint="Move or rename it, or choose another output folder")


def _earlier_run(out: Path, now: dict, stamps: dict, overwrite: bool) -> dict | None:
    """The record of an earlier run whose outputs in ``out`` are kept: complete, whole, made with the settings
    ``now`` from the same inputs (``stamps``). None: the outputs are (re)made. Refused before any work: an output
    of other settings (InputError naming both values, unless ``overwrite``), a file gistools did not write or a link
    (OutputExistsError, with or without ``overwrite``), the outputs of an earlier version that did not record how
    they were made (unless ``overwrite``)."""
    from ..engine.record import read_folder_report
    from ..engine.resume import check_targets
    from ..errors import OutputExistsError
    from ..io.outdir import check_record
    from ..parameters import option

    targets = {k: out / name for k, name in PRODUCTS.items()}
    check_targets(targets.values())
    existing = {k: p for k, p in targets.items() if p.exists()}
    if not existing:
        return None
    check_record(out, TOOL)
    previous = read_folder_report(out) or {}
    made = previous.get("made") if previous.get("tool") == TOOL else None
    _refuse_foreign(existing, made if isinstance(made, dict) else {})
    if overwrite:
        return None
    if not isinstance(made, dict) and previous.get("tool") == TOOL:
        first = next(iter(existing.values()))
        raise OutputExistsError(f"{first.name} is there from an earlier run that did not record its settings",
                                path=out, hint=f"Give another folder, or replace it: {option('overwrite')}")
    _refuse_other_settings(existing, made or {}, now)
    return previous if _complete(out, made or {}, previous, stamps) else None


def _kept(out: Path, earlier: dict, started: float) -> dict:
    """The record of a rerun that keeps the complete outputs of an earlier one (its line added to ``runs``)."""
    from ..engine.record import write_folder_report

    log.info("%s: the outputs of an earlier run with the same settings are complete: kept", out)
    rep = {k: v for k, v in earlier.items() if k not in ("schema", "version")}
    rep.update(kept=list(PRODUCTS), seconds=round(time.time() - started, 3))
    return write_folder_report(out, rep)


@dataclass(frozen=True)
class _Job:
    """A run of gistools travel once its inputs are checked."""

    dem: _Dem
    settings: TravelSettings
    points: list
    cells: list
    plan: dict
    inputs: dict
    now: dict
    stamps: dict
    started: float


def _speeds(job: _Job, heights) -> tuple[np.ndarray, np.ndarray, dict]:
    """(factor, fixed speed, {road_cells, water_cells}) of the DEM's cells: the shrub classes, the roads and water of
    the breaklines; a point last seen on a cell the walker cannot be on is refused."""
    from ..units import length_to_crs_units

    grid, settings, classes = job.dem.grid, job.settings, job.inputs["classes"]
    lengths = {name: length_to_crs_units(getattr(settings, name), job.dem.xy, name=name)
               for name in ("snap", "max_road_width", "max_hydro_width", "single_line_width")}
    class_codes = _classes_on(classes, grid) if classes is not None else None
    road, water = _roads_and_water(grid, job.inputs["roads"], job.inputs["hydro"], job.inputs["waterbodies"],
                                   settings, lengths)
    factor, fixed = speed_model(class_codes, road, water, settings)
    if class_codes is not None:
        road, water = road | (class_codes == CLASS_ROAD), water | (class_codes == CLASS_WATER)
    _check_starts(job.points, job.cells, (np.isfinite(heights) & (factor > 0)) | np.isfinite(fixed), water & ~road)
    return factor, fixed, {"road_cells": int(road.sum()), "water_cells": int((water & ~road).sum())}


def _solve_and_write(out: Path, job: _Job, heights, speeds, progress) -> dict:
    """The minutes, the outputs put in place as one set, and the record (report.json) written last."""
    from ..engine.record import read_folder_report, write_folder_report
    from ..engine.resume import made_record
    from ..progress import report, sub_progress

    factor, fixed, counts = speeds
    grid, settings, plan, neighbours = job.dem.grid, job.settings, job.plan, int(job.settings.neighbours)
    how = "the whole grid" if plan["method"] == "whole" else "blocks of {} x {} cells".format(*plan["block"])
    report(progress, 0.1, f"travel times over {grid.width:,} x {grid.height:,} cells ({neighbours} neighbours, {how})")
    solve, solver = time.time(), {}
    minutes = travel_minutes(heights, grid.cell_size, job.cells, factor=factor, fixed_speed=fixed,
                             xy_metres=job.dem.xy.metres, z_metres=job.dem.z.metres, neighbours=neighbours,
                             isotropic=settings.isotropic, tobler=tuple(settings.tobler),
                             max_memory=settings.max_memory * 1e9, block=plan["block"],
                             progress=sub_progress(progress, 0.1, 0.8), info=solver)
    solve = time.time() - solve
    report(progress, 0.8, "writing the rasters and isochrones")
    reached = np.isfinite(minutes)
    top = float(minutes[reached].max()) if reached.any() else 0.0
    iso = _write_set(out, minutes, grid, settings, job.points, job.dem.xy, top)
    rep = _record(job, iso, {**counts, "reached_share": float(reached.mean()), "max_minutes": top,
                             "solver": solver, "solve_seconds": round(solve, 3)})
    rep["made"] = made_record(read_folder_report(out), TOOL, str(job.dem.path), job.now,
                              {k: out / name for k, name in PRODUCTS.items()})
    return write_folder_report(out, rep)


def _record(job: _Job, iso, found: dict) -> dict:
    """report.json of a run (but ``made``)."""
    grid, settings, plan, xy, z = job.dem.grid, job.settings, job.plan, job.dem.xy, job.dem.z
    neighbours, solver = int(settings.neighbours), found["solver"]
    return {
        "tool": TOOL, "crs_wkt": grid.crs.to_wkt(), "dem": str(job.dem.path),
        "classes": str(job.inputs["classes"]) if job.inputs["classes"] else None, "unit": xy.short,
        "vertical_unit": z.short, "area_unit": f"{xy.name} squared", "cell_size": grid.cell_size,
        "cells": int(grid.width * grid.height), "graph_bytes_estimate": plan["graph_bytes"],
        "memory_estimate": plan["bytes"],
        "solver": {"method": plan["method"], "block": list(plan["block"]) if plan["block"] else None,
                   **{k: solver[k] for k in ("block_solves", "blocks", "blocks_reached") if k in solver}},
        "neighbours": neighbours, "straight_line_bound": NEIGHBOUR_BOUND[neighbours],
        "last_seen": [{"x": x, "y": y, "from": w} for x, y, w in job.points],
        "reached_share": found["reached_share"], "max_minutes": found["max_minutes"],
        "isochrones": [{k: row[k] for k in ("minutes", "area", "hectares", "acres")} for _, row in iso.iterrows()],
        "speed_model": {"tobler": list(settings.tobler), "shrub_factors": dict(zip(("light", "medium", "heavy"),
                        settings.shrub_factors)), "road_speed": settings.road_speed, "wade_speed": settings.wade_speed,
                        "isotropic": settings.isotropic, "road_cells": found["road_cells"],
                        "water_cells": found["water_cells"]},
        "outputs": dict(PRODUCTS), "kept": [], "input_stamps": job.stamps,
        "settings": {k: (list(v) if isinstance(v, tuple) else v) for k, v in settings.__dict__.items()},
        "solve_seconds": found["solve_seconds"], "seconds": round(time.time() - job.started, 3),
    }


def travel_from_dem(dem, out, last_seen, settings: TravelSettings | None = None, *, classes=None, roads=None,
                    hydro=None, waterbodies=None, overwrite: bool = False, progress=None) -> dict:
    """Minutes for a walker to reach every cell of a DEM from the nearest point last seen: ``gistools travel``.

    Tobler's hiking function on the slope of each step, slowed by the shrub classes, with roads and water from the
    classes raster and the breakline layers (``travel_minutes``). Writes under ``out``: ``travel_minutes.tif``
    (float32 minutes, nodata -9999 where no walk reaches, with the QGIS style ``travel_minutes.qml``),
    ``isochrone_bands.tif`` (uint8: 1 within the first isochrone, 2 within the second, ..., one more beyond the
    last, 255 not reached; with a colour table), ``travel.gpkg`` (layers ``isochrones`` and ``last_seen``) and
    ``report.json``.

    Parameters
    ----------
    dem : str or path
        A DEM raster or VRT (square cells, with a CRS), or an output folder of ``gistools rasters`` or ``gistools
        shrub`` (its ``dem.vrt``, and its ``classes.vrt`` when there).
    out : str or path
        Output folder, made when missing.
    last_seen : str, tuple or list
        The points last seen: ``"X,Y"`` in the DEM's CRS, an (x, y) pair, a point layer (a path or
        ``file.gpkg:LAYER``), or a list of them.
    settings : TravelSettings, optional
        The options (``tobler``, ``shrub_factors``, ``road_speed`` and ``wade_speed`` in km/h, ``isochrones`` in
        minutes, ``neighbours``, ``max_memory`` in GB, breakline widths, ...). None: the defaults.
    classes : str or path, optional
        A shrub classes raster (0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water), in the DEM's CRS. None: the
        folder's ``classes.vrt``, if any.
    roads : str, optional
        Edge-of-pavement lines (a path or ``file.gpkg:LAYER``), made into road polygons as the shrub chain makes
        them (added to the classes' roads).
    hydro : str, optional
        Water lines (streams, canals), likewise made into water polygons.
    waterbodies : str, optional
        Water polygons, likewise.
    overwrite : bool
        Make the outputs again whatever an earlier run left in ``out``. Without it, the complete outputs of an
        earlier run with the same settings from the same inputs are kept (``kept`` in the report); outputs an
        earlier run left incomplete, or of an input changed since, are made again; outputs of other settings are
        refused. The outputs are written aside and put in place together, report.json last (marked ``incomplete``
        in between), so a run stopped midway never leaves a set that looks complete.
    progress : callable, optional
        ``progress(fraction, message)``, called as the work goes; returning False cancels the run.

    Returns
    -------
    dict
        The report, also written to ``out/report.json``: ``isochrones`` (per isochrone ``minutes``, ``area`` in
        ``area_unit``, the CRS unit squared, ``hectares``, ``acres``), ``last_seen``, ``reached_share`` (the share
        of the DEM's cells a walk reaches), ``max_minutes``, ``unit`` and ``vertical_unit``, ``cell_size``,
        ``speed_model`` (with the ``road_cells`` and ``water_cells`` counted), ``solver`` (``method``: "whole"
        or "blocks", the ``block`` in cells, and block by block the ``block_solves``), ``memory_estimate`` and
        ``graph_bytes_estimate`` (the whole graph's) in bytes, ``outputs``, ``settings``, ``seconds``, ``kept``
        (the outputs of an earlier run kept), ``made`` and ``input_stamps`` (what a rerun compares).

    Raises
    ------
    InputError
        An option is not valid (an isochrone or a point last seen not finite, more isochrones than the bands raster
        has codes); the folder has no ``dem.vrt``; the DEM has no CRS, a geographic CRS, a rotated geotransform or
        cells that are not square; no point last seen is given, or one is outside the DEM or on a cell the walker
        cannot be on (water, no data); the classes raster is in another CRS; ``out`` holds outputs of other
        settings or inputs and ``overwrite`` is False.
    CRSMismatchError
        A layer is in another CRS than the DEM (``settings.reproject_vectors`` reprojects it).
    DataFileError
        The DEM is not found, or the classes raster cannot be read.
    OutOfMemoryError
        Even the cell arrays of the block-wise method (``CELL_BYTES`` a cell) pass ``settings.max_memory``: told
        from the DEM's width and height before any of its cells is read.
    OutputExistsError
        A file gistools did not write is at an output's name; or ``out`` holds the outputs of an earlier version
        that did not record its settings, and ``overwrite`` is False.
    Cancelled
        ``progress`` returned False.

    Examples
    --------
    >>> from gistools import TravelSettings, rasters_from_tiles, travel_from_dem
    >>> B = "sample_tiles/breaklines.gpkg"
    >>> report = rasters_from_tiles("sample_tiles", "rasters")  # doctest: +SKIP
    >>> report = travel_from_dem("rasters", "travel", "431000,1811000", TravelSettings(isochrones=(2, 4, 6)),
    ...                          roads=f"{B}:ROADBREAKLINE", waterbodies=f"{B}:WATERBODY")  # doctest: +SKIP
    >>> [(i["minutes"], round(i["hectares"], 1)) for i in report["isochrones"]]  # doctest: +SKIP
    [(2.0, 8.5), (4.0, 29.4), (6.0, 35.1)]
    """
    from ..io.outdir import claim_output, output_folder
    from ..parameters import in_data_units
    from ..progress import report

    started = time.time()
    settings = settings or TravelSettings()
    settings.validate()
    out = output_folder(out)
    dem_path, classes_path = _dem_inputs(dem, classes)
    report(progress, 0.0, "reading the DEM")
    meta = _dem_meta(dem_path)
    plan = plan_memory(meta.grid.shape, int(settings.neighbours), settings.max_memory * 1e9)  # before any cell is read
    settings = in_data_units(settings, meta.xy.is_foot)
    points = _last_seen_points(last_seen, meta.grid.crs, settings.reproject_vectors)
    inputs = {"classes": classes_path, "roads": roads, "hydro": hydro, "waterbodies": waterbodies}
    now, stamps = _fingerprint(settings, points, dem_path, inputs), _input_stamps(dem_path, inputs)
    job = _Job(meta, settings, points, _start_cells(points, meta.grid), plan, inputs, now, stamps, started)
    earlier = _earlier_run(out, now, stamps, overwrite)
    if earlier is not None:
        with claim_output(out, TOOL):
            rep = _kept(out, earlier, started)
    else:
        heights = _read_heights(meta)
        speeds = _speeds(job, heights)  # refusals (a point last seen in water) before the folder is made
        with claim_output(out, TOOL):
            rep = _solve_and_write(out, job, heights, speeds, progress)
    report(progress, 1.0, "done")
    return rep
