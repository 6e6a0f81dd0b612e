"""The shrub chain (dissertation ch. 9, S4-S11): tiles and breaklines to a shrub density map.

Stages, each one function per tile run inline, on local processes or on Dask:

1. DSM, DEM, nDSM and the class of each cell's highest first return
   (:func:`gistools.products.rasters.rasters_from_tiles`).
2. *bands*: height bands of the nDSM; road and water polygons of the tile from the
   breaklines (split by the tile index, polygonised); vegetation = band minus road minus
   water (cell-centre-in-polygon, as Clip / Select By Location on Raster To Point output);
   vegetation inside wetlands.
3. *density*: point density and cover of vegetation cells over a circle, reading a halo
   from the neighbouring tiles through the VRT mosaic, so tile edges do not matter.
4. *classes*: none / light / medium / heavy (+ road, water) from cover; class polygons.

Then VRT mosaics, a GeoPackage of class polygons, a printable map and report.json.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyproj
import rasterio
import shapely
from shapely.geometry import box

from ..docstrings import shared_sections
from ..errors import DataFileError, GistoolsError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..io.points import parse_crs_text, read_tile_info
from ..io.tiles import find_tiles
from ..io.outdir import Rollback, claim_output
from ..io.raster import raster_is_readable, write_vrt
from ..io.vector import check_crs, check_field, read_layer, write_layer
from ..lidar.bands import BAND_NAMES, band_thresholds
from ..lidar.vegetation import VEG_ROAD, VEG_WATER
from ..io.styles import write_polygon_style
from ..lidar.shrub import CLASS_NAMES, CLASS_STYLE, DEFAULT_BREAKS
from ..progress import ProgressCallback, report, sub_progress
from ..parameters import in_data_units, option, render
from ..parameters.shrub import STAGE_SETTINGS, STEP_COMMANDS  # noqa: F401 - the step tables, declared there
from ..units import LinearUnit, horizontal_unit, length_to_crs_units
from ..vector.breaklines import road_polygons, water_polygons
from ..validation import check_jobs, check_scheduler
from ..engine.batch import make_pool
from ..engine.passes import Stage, TileState, run_stages
from .rasters import RasterSettings, rasters_from_tiles
from ..engine.record import add_run, write_folder_report
from .settings import ShrubSettings
from .steps import band_summary, bands_from_ndsm, class_breaks, class_summary, classes_from_cover, clip_bands, \
    density_from_vegetation, nodata_causes

__all__ = ["ShrubSettings", "shrub_from_tiles", "map_from_classes", "STAGES", "VEG_ROAD", "VEG_WATER"]

ACRE_M2 = 4046.8564224
HECTARE_M2 = 10000.0


@dataclass
class _TileState(TileState):
    outputs: dict = field(default_factory=dict)
    band_area: dict = field(default_factory=dict)
    class_area: dict = field(default_factory=dict)
    nodata_share: float = 0.0
    nodata_by_cause: dict = field(default_factory=dict)
    wetland_vegetation_area: float = 0.0


@dataclass(frozen=True)
class StepParams:
    """What the steps of a tile need, in the tiles' units (picklable: sent to the workers as it is)."""

    thresholds: tuple  # band limits T1, T2, T3 in the vertical unit
    noise_floor: float  # vertical unit
    z_unit: LinearUnit  # the vertical unit
    snap: float  # CRS units, as the lengths below
    max_road_width: float
    max_hydro_width: float
    single_line_width: float
    radius: float
    density_bands: tuple
    overwrite: dict  # stage -> redo it even when its outputs exist
    band_points: bool
    crs_wkt: str  # the horizontal CRS


def _frames(gbox, footprints) -> list:
    """The tile index polygons that cover this tile's box (the dissertation's split), or the box."""
    if footprints is None:
        return [gbox]
    hits = [f for f in footprints if f.intersects(gbox) and f.intersection(gbox).area > 0]
    return hits or [gbox]


def _existing(out, name, products, overwrite) -> dict | None:
    """Output paths of a stage when all exist and overwriting is off (a resumed run), else None."""
    paths = {p: Path(out) / p / f"{name}.tif" for p in products}
    if overwrite or not all(path.exists() and raster_is_readable(path) for path in paths.values()):
        return None
    return {k: str(v) for k, v in paths.items()}


# The tile tasks: each runs one step of gistools.products.steps (the steps' one implementation) on the tile's
# rasters, as a whole tile at once (block=0: a tile fits in memory, and its class polygons stay whole).

def _bands_tile(name, ndsm_path, top_path, p, out) -> dict:
    """Height bands of one tile (S4-S5)."""
    done = _existing(out, name, ("bands",), p.overwrite["bands"])
    if done:
        return {"outputs": done}
    points = Path(out) / "band_points" / f"{name}.gpkg" if p.band_points else None
    result = bands_from_ndsm(ndsm_path, Path(out) / "bands" / f"{name}.tif", top_class=top_path, thresholds=p.thresholds,
                             noise_floor=p.noise_floor, z_unit=p.z_unit, points_out=points, block=0)
    outputs = {"bands": str(result["bands"])}
    if points:
        outputs["band_points"] = str(points)
    return {"outputs": outputs}


def _clip_tile(name, bands_path, vec, p, out, causes=None) -> dict:
    """Road and water polygons of one tile from the breaklines (S6-S7), vegetation = band - road - water,
    vegetation inside wetlands (S8-S9). ``causes``: the tile's nodata causes from the rasters stage of this run (None:
    read from its rasters)."""
    done = _existing(out, name, ("veg", "wetveg"), p.overwrite["clip"])
    if causes is None:
        causes = nodata_causes(*(Path(out) / product / f"{name}.tif" for product in ("dsm", "dem", "topclass")), block=0)
    if done:
        return {"outputs": done, **band_summary(bands_path, done["wetveg"], block=0), "nodata_by_cause": causes}
    with rasterio.open(bands_path) as src:
        frames = _frames(box(*src.bounds), vec["footprints"])
    road = shapely.union_all([road_polygons(vec["roads"], f, snap=p.snap, max_width=p.max_road_width) for f in frames])
    water = shapely.union_all([water_polygons(vec["hydro"], vec["waterbodies"], f, snap=p.snap, max_width=p.max_hydro_width,
                                              single_line_width=p.single_line_width) for f in frames])
    wetlands = [shapely.union_all(vec["wetlands"])] if vec["wetlands"] else []
    paths = {product: Path(out) / product / f"{name}.tif" for product in ("veg", "wetveg")}
    result = clip_bands(bands_path, paths["veg"], wetland_out=paths["wetveg"], road_polygons=[road], water_polygons=[water],
                        wetlands=wetlands, block=0)
    return {"outputs": {k: str(v) for k, v in paths.items()}, "nodata_by_cause": causes,
            **{k: result[k] for k in ("band_area", "nodata_share", "wetland_vegetation_area")}}


def _density_tile(name, veg_tif, veg_vrt, p, out) -> dict:
    """Point density and cover of one tile's vegetation, its neighbours read through the mosaic (S10)."""
    done = _existing(out, name, ("density", "cover"), p.overwrite["density"])
    if done:
        return {"outputs": done}
    paths = {product: Path(out) / product / f"{name}.tif" for product in ("density", "cover")}
    density_from_vegetation(veg_vrt, paths["cover"], density_out=paths["density"], radius=p.radius,
                            density_bands=p.density_bands, like=veg_tif, block=0)
    return {"outputs": {k: str(v) for k, v in paths.items()}}


def _classes_tile(name, veg_tif, cover_tif, breaks, p, out) -> dict:
    """Shrub classes of one tile, their areas and polygons (S11)."""
    path = Path(out) / "classes" / f"{name}.tif"
    if _existing(out, name, ("classes",), p.overwrite["classes"]):
        result = class_summary(path, block=0)
    else:
        result = classes_from_cover(cover_tif, path, veg=veg_tif, breaks=breaks, keep_polygons=True, block=0)
    dissolved = [(c, shapely.to_wkb(g)) for c, g in result["polygons"]]
    return {"outputs": {"classes": str(path)}, "class_area": result["class_area"], "polygons": dissolved}


def _early_vectors(inputs, crs_text, layers, settings, reproject):
    """(tile CRS, _vectors(...)) for the first tile whose header reads, or None (the raster stage reports why)."""
    try:
        paths = find_tiles(inputs)
    except GistoolsError:
        return None
    override = parse_crs_text(crs_text) if crs_text else None
    for path in paths:
        try:
            crs = read_tile_info(path, override).crs
        except GistoolsError:
            continue
        return crs, _vectors(*layers, crs, settings, reproject)
    return None


def _water_for_ground(inputs, rs: RasterSettings, early, settings: ShrubSettings):
    """--classify-ground with breaklines: the water polygons of each tile frame (the clip step's), so that the
    returns on water are class 9 before the ground filter (they would otherwise be ground and pull the DEM
    down along the banks). None without hydro layers."""
    if early is None or not (early[1]["hydro"] or early[1]["waterbodies"]):
        return None
    crs, vec = early
    unit = horizontal_unit(crs)
    settings = in_data_units(settings, unit.is_foot)
    override = parse_crs_text(rs.crs) if rs.crs else None
    frames = vec["footprints"]
    if frames is None:
        boxes = []
        for path in find_tiles(inputs):
            try:
                boxes.append(box(*read_tile_info(path, override).bounds))
            except GistoolsError:
                continue
        frames = boxes
    length = lambda v, n: length_to_crs_units(v, unit, name=n)  # noqa: E731
    snap, max_w, single = (length(settings.snap, "snap"), length(settings.max_hydro_width, "max hydro width"),
                           length(settings.single_line_width, "single-line hydro width"))
    parts = [water_polygons(vec["hydro"], vec["waterbodies"], f, snap=snap, max_width=max_w, single_line_width=single)
             for f in frames]
    return [g for g in parts if g is not None and not g.is_empty]


def _vectors(roads, hydro, waterbodies, wetlands, tile_index, crs, settings, reproject):
    settings = in_data_units(settings, horizontal_unit(crs).is_foot)  # 0.2 ft snap on data in feet, 0.06 m in metres
    def load(spec, name, kinds):
        if spec is None:
            return None
        return check_crs(read_layer(spec, kinds, name), crs, str(spec), reproject=reproject)

    lines, polygons = ("line",), ("polygon",)  # as the QGIS algorithms declare them
    # each layer named as the reader names the parameter (--roads, roads, the dialog's label), in messages and the log
    roads_g, hydro_g = load(roads, render(option("roads")), lines), load(hydro, render(option("hydro")), lines)
    wb_g = load(waterbodies, render(option("waterbodies")), polygons)
    wet_g = load(wetlands, render(option("wetlands")), polygons)
    idx_g = load(tile_index, render(option("tile_index")), polygons)
    if idx_g is not None:
        check_field(idx_g, settings.tile_field, tile_index)
    return {
        "roads": list(roads_g.geometry) if roads_g is not None else [],
        "hydro": list(hydro_g.geometry) if hydro_g is not None else [],
        "waterbodies": list(wb_g.geometry) if wb_g is not None else [],
        "wetlands": list(wet_g.geometry) if wet_g is not None else [],
        "footprints": list(idx_g.geometry) if idx_g is not None else None,
    }


def _vector_trees(vec) -> dict:
    """An R-tree (shapely.STRtree) of each vector layer: a tile's geometries are found in O(log n), not by testing
    every geometry of the county for every tile."""
    return {k: shapely.STRtree(v) for k, v in vec.items() if v is not None}


def _subset(vec, bounds, margin, trees=None):
    """Vector geometries near a tile (what one worker needs), in their layer's order: those that intersect the
    tile's box grown by ``margin``. ``trees``: _vector_trees(vec), built once for all the tiles."""
    area = box(*bounds).buffer(margin)
    trees = trees if trees is not None else _vector_trees(vec)
    return {k: (None if v is None else [v[i] for i in np.sort(trees[k].query(area, predicate="intersects"))])
            for k, v in vec.items()}


STAGES = ("rasters", "bands", "clip", "density", "classes")


@shared_sections
def shrub_from_tiles(
    inputs,
    out,
    settings: ShrubSettings | None = None,
    *,
    roads=None,
    hydro=None,
    waterbodies=None,
    wetlands=None,
    tile_index=None,
    reproject_vectors: bool = False,
    jobs: int | str = "auto",
    scheduler: str | None = None,
    overwrite: bool = False,
    make_map: bool = True,
    band_points: bool = False,
    from_stage: str = "rasters",
    progress: ProgressCallback | None = None,
) -> dict:
    """The whole shrub chain on LAS / LAZ tiles: ``gistools shrub``.

    Writes under ``out``: ``dsm/ dem/ ndsm/ topclass/ bands/ veg/ wetveg/ density/ cover/ classes/`` (a GeoTIFF per
    tile) with their VRT mosaics, ``shrub_classes.gpkg``, ``shrub_map.png`` / ``.pdf`` and ``report.json``. Complete
    outputs of an earlier run are kept (a killed run resumes) unless ``overwrite``.

    Parameters
    ----------
    inputs : str, path or list
        LAS / LAZ files, folders (their tiles), glob patterns or a ``.vpc``; None with ``from_stage`` past
        ``"rasters"``.
    out : str or path
        Output folder, made when missing.
    settings : ShrubSettings, optional
        The options (``raster`` a RasterSettings, ``bands``, ``noise_floor``, ``radius``, ``class_breaks``, ...;
        lengths as text with their unit, e.g. ``"50ft"``, or a number in CRS units). None: the defaults.
    {breaklines_in}
    wetlands : str, optional
        Wetland polygons, likewise: vegetation inside them is also written to ``wetveg/``.
    tile_index : str, optional
        Tile footprints, likewise: the breaklines are split by tile.
    reproject_vectors : bool
        Reproject vector layers in another CRS than the tiles' (else they are refused).
    jobs : int or "auto"
        Tiles processed at once, each in a local process; "auto" (the default): in this process until the tiles'
        points repay starting workers (``gistools.engine.batch.auto_workers``).
    scheduler : str, optional
        A dask.distributed scheduler address, or ``"local"``, to run the tiles on instead.
    overwrite : bool
        Remake outputs that exist.
    make_map : bool
        Also draw the printable map (``shrub_map.png`` / ``.pdf``).
    band_points : bool
        Also write ``band_points/<tile>.gpkg``: a point per cell centre of bands B0-B3 with its band and height.
    from_stage : str
        ``"rasters"`` (the whole chain), or ``"bands"``, ``"clip"``, ``"density"``, ``"classes"``: rerun from that
        step on an existing ``out``, reusing what comes before it.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels the run.

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, skipped, failed), ``band_area`` and
        ``class_area`` (in ``area_unit``, the CRS unit squared), ``class_area_acres``, ``band_thresholds``,
        ``mosaics``, ``tiles``, ...

    Raises
    ------
    InputError
        An option is not valid, a vector layer is in another CRS, ``from_stage`` is unknown or has no earlier run.
    {tiles_raise_rest}

    Examples
    --------
    >>> from gistools import ShrubSettings, shrub_from_tiles
    >>> B = "sample_tiles/breaklines.gpkg"
    >>> report = shrub_from_tiles("sample_tiles", "shrub", ShrubSettings(radius="50ft"), roads=f"{B}:ROADBREAKLINE",
    ...                           waterbodies=f"{B}:WATERBODY", tile_index=f"{B}:FOOTPRINT")  # doctest: +SKIP
    >>> report["counts"]  # doctest: +SKIP
    {'ok': 4, 'skipped': 0, 'failed': 0}
    """
    settings = settings or ShrubSettings()
    settings.validate()
    check_scheduler(scheduler)
    jobs = check_jobs(jobs)
    if from_stage not in STAGES:
        raise InputError(f"stage {from_stage!r} is not one of {', '.join(STAGES)}")
    out = output_folder(out)
    if from_stage != "rasters" and not (out / "report.json").exists():
        _previous_run(out)  # refuses with the reason before the folder is touched
    run = dict(roads=roads, hydro=hydro, waterbodies=waterbodies, wetlands=wetlands, tile_index=tile_index,
               reproject_vectors=reproject_vectors, jobs=jobs, scheduler=scheduler, overwrite=overwrite,
               make_map=make_map, band_points=band_points, from_stage=from_stage, progress=progress)
    with claim_output(out, f"gistools {'shrub' if from_stage == 'rasters' else from_stage}"):
        if from_stage == "rasters":  # the chain: one bad tile never stops the batch, it is reported
            try:
                return raise_if_every_tile_failed(_shrub_in(inputs, out, settings, **run))
            except BaseException as err:
                _record_stop(out, err)
                raise
        # a step rerun that fails (a tile, an error, Ctrl-C) leaves the folder as it was
        folders = [f for stage in STAGES[STAGES.index(from_stage):] for f in STAGE_FOLDERS[stage]]
        with Rollback(out, folders, STEP_FILES) as saved:
            report = _shrub_in(inputs, out, settings, **run)
            if report["counts"].get("failed"):
                saved.restore()
                report["rolled_back"] = True
            else:
                saved.drop()
        return report


def _record_stop(out: Path, err: BaseException) -> None:
    """The chain stopped after its rasters (an error, Ctrl-C): the record the rasters wrote names the chain, says it
    is incomplete and why, so the folder never looks like a finished run (a rerun resumes it)."""
    from ..engine.record import read_folder_report

    record = read_folder_report(out)
    if not record or record.get("tool") != "gistools rasters" or record.get("incomplete"):
        return
    why = "interrupted" if isinstance(err, KeyboardInterrupt) else f"{type(err).__name__}: {err}"
    record.update(tool="gistools shrub", incomplete=f"the chain stopped after its rasters ({why}); rerun gistools "
                                                    "shrub to complete it")
    record.setdefault("warnings", []).append(record["incomplete"])
    try:
        write_folder_report(out, record)
    except Exception:  # noqa: BLE001 - the error being raised matters more than this note
        pass


# what each stage writes under --out (the step reruns put them back when they fail)
STAGE_FOLDERS = {"rasters": (), "bands": ("bands", "band_points"), "clip": ("veg", "wetveg"),
                 "density": ("density", "cover"), "classes": ("classes",)}
STEP_FILES = ("report.json", "shrub_classes.gpkg", "shrub_classes.qml", "shrub_map.png", "shrub_map.pdf", "bands.vrt", "veg.vrt",
              "wetveg.vrt", "density.vrt", "cover.vrt", "classes.vrt")


def _chain_pool(jobs, scheduler, inputs, summary):
    """The chain's one worker pool (or None: inline): from the tiles' points for the whole chain (``summary`` None),
    from the earlier run's tiles for a step rerun."""
    if summary is None:
        return make_pool(jobs, scheduler, *_tiles_and_points(inputs, count_points=jobs == "auto"))
    return make_pool(jobs, scheduler, sum(t["status"] in ("ok", "skipped") for t in summary["tiles"]))


def _tiles_and_points(inputs, count_points: bool) -> tuple[int, None, int | None]:
    """(the tiles of ``inputs``, None, their points from the headers: for jobs="auto"; None where not counted or a
    header does not read, which the run reports)."""
    import laspy

    from ..io.tiles import find_tiles

    paths = find_tiles(inputs)
    total = 0 if count_points else None
    for path in paths if count_points else ():
        try:
            with laspy.open(path) as reader:
                total += int(reader.header.point_count)
        except Exception:  # noqa: BLE001 - a bad tile is the run's to report, not the estimate's
            return len(paths), None, None
    return len(paths), None, total


def _shrub_in(inputs, out: Path, settings: ShrubSettings, *, roads, hydro, waterbodies, wetlands, tile_index,
              reproject_vectors, jobs, scheduler, overwrite, make_map, band_points, from_stage, progress) -> dict:
    started = time.time()
    layers = (roads, hydro, waterbodies, wetlands, tile_index)
    early, summary = None, None
    if from_stage == "rasters":
        rs = RasterSettings(**{**settings.raster.__dict__, "products": ("dsm", "dem", "ndsm", "topclass"),
                               "return_band_breaks": (settings.noise_floor, *_band_break_lengths(settings))})
        # the vector layers are read and checked against the first readable tile's CRS before the long raster
        # stage, so a CRS mismatch or a missing field is reported in seconds, not after the county's rasters
        early = _early_vectors(inputs, rs.crs, layers, settings, reproject_vectors)
    else:
        summary = _previous_run(out)
    pool = _chain_pool(jobs, scheduler, inputs, summary)  # one pool for the rasters and the steps: workers start once
    try:
        if summary is None:
            water = _water_for_ground(inputs, rs, early, settings) if rs.classify_ground else None
            summary = rasters_from_tiles(inputs, out, rs, jobs=jobs, overwrite=overwrite, scheduler=scheduler,
                                         progress=sub_progress(progress, 0, 0.6), pool=pool, water=water)
        if summary["crs_wkt"] is None:
            return summary
        crs = pyproj.CRS.from_wkt(summary["crs_wkt"])
        settings = in_data_units(settings, horizontal_unit(crs).is_foot)  # 25 ft radius on data in feet, 7.5 m in metres
        params = _step_params(summary, settings, overwrite, from_stage, band_points)
        vec = early[1] if early is not None and early[0] == crs else _vectors(*layers, crs, settings, reproject_vectors)
        base = {t["name"]: t for t in summary["tiles"]}
        states = {t["name"]: _TileState(t["name"], t["path"], t["status"], t.get("error")) for t in summary["tiles"]}
        names = [n for n, t in base.items() if t["status"] in ("ok", "skipped")]
        for n in names:
            states[n].status, states[n].error = "ok", None
        ticker = _StepTicker(progress, 0.6 if from_stage == "rasters" else 0.0, 4 * len(names), states, len(names))
        step_seconds: dict = {}
        mosaic, polygons, breaks = _steps_as_stages(out, names, states, params, vec, settings, pool, ticker.tick,
                                                    step_seconds, _fresh_causes(base, from_stage))
    finally:
        if pool is not None:
            pool.close()
    good = [n for n in names if states[n].status == "ok"]
    title = f"Shrub density - {_input_label(inputs)}" if inputs else summary.get("map_title") or f"Shrub density - {out.name}"
    t0 = time.perf_counter()
    _write_chain_outputs(out, good, mosaic, polygons, crs, summary, settings, title if make_map else None)
    step_seconds["polygons_and_map"] = time.perf_counter() - t0  # once a run, not per tile
    report(progress, 1.0, "done")
    shrub_report = _shrub_report(summary, base, states, good, params, breaks, mosaic, started, settings.classify)
    shrub_report["stage_seconds"] = _stage_seconds(summary, from_stage, step_seconds)
    record = settings_record(settings, dict(zip(LAYERS, layers)), reproject_vectors)
    return write_folder_report(out, _as_run_of(shrub_report, summary, from_stage, title, record))


def _fresh_causes(base: dict, from_stage: str) -> dict:
    """Tile -> its nodata causes where this run's rasters stage made its rasters (status ok: pass 2 ran); the clip
    step reads the others' from their rasters."""
    if from_stage != "rasters":
        return {}
    return {n: t["nodata_by_cause"] for n, t in base.items() if t["status"] == "ok" and t.get("nodata_by_cause")}


def _stage_seconds(summary: dict, from_stage: str, step_seconds: dict) -> dict:
    """The run's seconds by stage: the rasters' (when it made them) and the steps', each summed over the tiles."""
    rasters = summary.get("stage_seconds") or {} if from_stage == "rasters" else {}
    return {**rasters, **{k: round(v, 3) for k, v in step_seconds.items()}}


def _as_run_of(shrub_report: dict, previous: dict, from_stage: str, title: str, record: dict) -> dict:
    """The chain's report as the record of the command that ran (the chain or a step rerun from ``from_stage``):
    the stages it did not redo keep what the earlier run recorded."""
    shrub_report.update(tool="gistools shrub" if from_stage == "rasters" else f"gistools {STEP_COMMANDS[from_stage]}",
                        map_title=title, settings=record)
    shrub_report.update(_kept_parameters(previous, from_stage))
    _keep_earlier_settings(shrub_report["settings"], previous.get("settings"), from_stage)
    if from_stage in ("rasters", "bands"):
        shrub_report.pop("steps_predate_rasters", None)  # every step remade from the rasters
    return shrub_report


def _write_chain_outputs(out: Path, good: list, mosaic: dict, polygons: list, crs, summary: dict,
                         settings: ShrubSettings, map_title: str | None) -> None:
    """The mosaics of the last steps, the class polygons and (with a title) the map."""
    for product in ("density", "cover", "classes"):
        mosaic[product] = write_vrt(out / f"{product}.vrt", [out / product / f"{n}.tif" for n in good],
                                    categories=CLASS_STYLE if product == "classes" else None)
    unit = LinearUnit(summary["horizontal_unit"], summary["horizontal_unit_m"])
    # by tile (each tile's in the order its task made them): the same rows whatever order the workers finished in
    polygons = sorted(polygons, key=lambda item: item[0])
    _write_polygons(out / "shrub_classes.gpkg", polygons, crs, settings.tile_field, unit.metres ** 2)
    if map_title and mosaic.get("classes"):
        _draw_map(out, map_title, unit)  # the chain's own run line says it made the map


def _step_params(summary: dict, settings: ShrubSettings, overwrite: bool, from_stage: str, band_points: bool) -> StepParams:
    """The settings in the tiles' units (from the rasters' report), and which stages to redo."""
    crs = pyproj.CRS.from_wkt(summary["crs_wkt"])
    unit = LinearUnit(summary["horizontal_unit"], summary["horizontal_unit_m"])
    z_unit = LinearUnit(summary["vertical_unit"], summary["vertical_unit_m"])

    def length(v, n):
        return length_to_crs_units(v, unit, name=n)

    return StepParams(
        thresholds=band_thresholds(z_unit, settings.bands, settings.band_breaks_m),
        noise_floor=length_to_crs_units(settings.noise_floor, z_unit, name="noise floor"), z_unit=z_unit,
        snap=length(settings.snap, "snap"), max_road_width=length(settings.max_road_width, "max road width"),
        max_hydro_width=length(settings.max_hydro_width, "max hydro width"),
        single_line_width=length(settings.single_line_width, "single-line hydro width"),
        radius=length(settings.radius, "density radius"), density_bands=tuple(settings.density_bands),
        overwrite={stage: overwrite or STAGES.index(stage) >= STAGES.index(from_stage) for stage in STAGES},
        band_points=band_points, crs_wkt=(crs.sub_crs_list[0] if crs.is_compound else crs).to_wkt())


class _StepTicker:
    """Progress over the steps' tile tasks, from ``start`` to 0.95 of the run."""

    def __init__(self, progress, start: float, total: int, states: dict, tiles: int):
        self.progress, self.start, self.total, self.states, self.tiles, self.done = progress, start, max(total, 1), states, tiles, 0

    def tick(self, message: str) -> None:
        self.done += 1
        failed = sum(st.status == "failed" for st in self.states.values())
        report(self.progress, self.start + (0.95 - self.start) * self.done / self.total,
               f"{message} | {self.tiles} tiles, {failed} failed")


def _ndsm_bounds(out: Path, name: str):
    path = out / "ndsm" / f"{name}.tif"
    try:
        with rasterio.open(path) as src:
            return src.bounds
    except rasterio.errors.RasterioError as err:
        raise DataFileError(f"cannot read the raster ({err})", path=path,
                            hint="Rerun gistools shrub on the tiles (the rasters stage rewrites it)") from None


def _steps_as_stages(out: Path, names: list, states: dict, p: StepParams, vec: dict, settings: ShrubSettings, pool,
                     tick, seconds_by_step: dict, causes: dict):
    """bands, clip, density and classes of every tile that is still ok, as the engine's stages (run_stages; the
    mosaics and the block's class breaks between them); (mosaics, class polygons, class breaks).
    ``seconds_by_step`` gets each step's seconds, summed over the tiles; ``causes``: tile -> its nodata causes where
    this run's rasters stage made them."""
    mosaic, polygons = {}, []

    def timed_as(stage, done):  # the step's seconds summed over its tiles (in the workers: with --jobs N they overlap)
        def on_done(name, value, seconds):
            seconds_by_step[stage] = seconds_by_step.get(stage, 0.0) + seconds
            done(name, value, seconds)
        return on_done

    def keep_outputs(name, value, seconds):
        states[name].outputs.update(value["outputs"])

    def clip_done(name, value, seconds):
        st = states[name]
        st.outputs.update(value["outputs"])
        st.band_area, st.nodata_share = value["band_area"], value["nodata_share"]
        st.nodata_by_cause = value["nodata_by_cause"]
        st.wetland_vegetation_area = value["wetland_vegetation_area"]

    def classes_done(name, value, seconds):
        states[name].outputs.update(value["outputs"])
        states[name].class_area = value["class_area"]
        polygons.extend((name, c, g) for c, g in value["polygons"])

    margin = p.max_road_width + p.max_hydro_width
    trees = _vector_trees(vec)
    breaks = [DEFAULT_BREAKS]

    def mosaics(good):  # the next stage reads the vegetation across tile edges
        for product in ("bands", "veg", "wetveg"):
            mosaic[product] = write_vrt(out / f"{product}.vrt", [out / product / f"{n}.tif" for n in good])

    def block_breaks(good):  # the class breaks of the whole block's cover
        cover = write_vrt(out / "cover.vrt", [out / "cover" / f"{n}.tif" for n in good])
        breaks[0] = class_breaks(cover, settings.classify, settings.class_breaks) if cover else DEFAULT_BREAKS

    run_stages([
        Stage("bands", _bands_tile, lambda n: (n, out / "ndsm" / f"{n}.tif", out / "topclass" / f"{n}.tif", p, out),
              timed_as("bands", keep_outputs), tiles=names),
        Stage("clip", _clip_tile, lambda n: (n, out / "bands" / f"{n}.tif",
                                             _subset(vec, _ndsm_bounds(out, n), margin, trees), p, out, causes.get(n)),
              timed_as("clip", clip_done), then=mosaics),
        Stage("density", _density_tile, lambda n: (n, out / "veg" / f"{n}.tif", mosaic["veg"], p, out),
              timed_as("density", keep_outputs), then=block_breaks),
        Stage("classes", _classes_tile, lambda n: (n, out / "veg" / f"{n}.tif", out / "cover" / f"{n}.tif", breaks[0],
                                                   p, out),
              timed_as("classes", classes_done)),
    ], states, pool, tick, out)
    return mosaic, polygons, breaks[0]


def _shrub_report(summary: dict, base: dict, states: dict, good: list, p: StepParams, breaks, mosaic: dict,
                  started: float, classify: str = "breaks") -> dict:
    """report.json of the chain: the rasters' report, the steps' parameters, areas by band and class, per tile."""
    unit = LinearUnit(summary["horizontal_unit"], summary["horizontal_unit_m"])
    area_m2 = unit.metres ** 2
    totals_band = {b: sum(states[n].band_area.get(b, 0.0) for n in good) for b in BAND_NAMES}
    totals_class = {c: sum(states[n].class_area.get(c, 0.0) for n in good) for c in CLASS_NAMES.values()}
    return {
        **{k: v for k, v in summary.items() if k not in ("tiles", "counts", "mosaics", "seconds")},
        "tool": "gistools shrub",
        "area_unit": f"{unit.name} squared",
        "band_thresholds": list(p.thresholds),
        "band_unit": summary["vertical_unit"],
        "density_radius": p.radius,
        "density_bands": list(p.density_bands),
        "class_breaks": list(breaks),
        "class_method": classify,
        "band_area": totals_band,
        "band_area_from_returns": _returns_band_area([base[n] for n in good]),
        "class_area": totals_class,
        "class_area_acres": {k: v * area_m2 / ACRE_M2 for k, v in totals_class.items()},
        "nodata_share": float(np.mean([states[n].nodata_share for n in good])) if good else None,
        "nodata_by_cause": _mean_causes([states[n].nodata_by_cause for n in good]),
        "tiles": [{**{k: v for k, v in base[n].items() if k not in states[n].__dict__}, **states[n].__dict__,
                   "outputs": {**base[n].get("outputs", {}), **states[n].outputs}} for n in states],
        "counts": {s: sum(st.status == s for st in states.values()) for s in ("ok", "skipped", "failed")},
        "mosaics": {k: str(v) for k, v in {**summary.get("mosaics", {}), **mosaic}.items() if v},
        "seconds": round(time.time() - started, 3),
    }


# the report's parameters of each stage: a step rerun from a later stage keeps the earlier stages' as they were made
_STAGE_PARAMETERS = {"bands": ("band_thresholds", "band_unit"), "density": ("density_radius", "density_bands")}
# the settings (as given: lengths with their units) and the layers of each stage, recorded in report.json["settings"]
LAYERS = ("roads", "hydro", "waterbodies", "wetlands", "tile_index")


def settings_record(settings: ShrubSettings, layers: dict, reproject_vectors: bool) -> dict:
    """The step settings and vector layers a run used, as given (lengths with units; layer files made absolute, so
    that a step rerun from another folder finds them)."""
    from ..io.vector import absolute_spec

    record = {k: getattr(settings, k) for stage in STAGE_SETTINGS.values() for k in stage if hasattr(settings, k)}
    record.update({k: absolute_spec(v) if v is not None else None for k, v in layers.items()})
    record["reproject_vectors"] = bool(reproject_vectors)
    return {k: list(v) if isinstance(v, tuple) else v for k, v in record.items()}


def _recorded_settings(out: Path) -> dict:
    """The settings report.json records, each checked against its declaration: a damaged or edited value is the
    record's fault, named as such (not an option the user never gave)."""
    from ..parameters import PARAMETERS, check

    recorded = _previous_run(out).get("settings") or {}
    if not isinstance(recorded, dict):
        raise DataFileError("report.json records no settings (damaged or edited)", path=out / "report.json",
                            hint="Rerun gistools shrub on the tiles")
    for key, value in recorded.items():
        if key in PARAMETERS and key in ShrubSettings.__dataclass_fields__ and value is not None:
            try:
                check(key, tuple(value) if isinstance(value, list) else value)
            except (GistoolsError, TypeError, ValueError):
                shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
                raise DataFileError(f"report.json records {key} = {shown}, which is not a valid value (damaged or "
                                    "edited)", path=out / "report.json", hint="Rerun gistools shrub on the tiles") from None
    return dict(recorded)


def step_settings(out, stage: str, **changes) -> tuple[ShrubSettings, dict]:
    """(settings, layers) for rerunning ``stage`` on ``out``: what report.json records the earlier run used, with
    ``changes`` (names of ShrubSettings fields, of the layers or ``reproject_vectors``) to the settings of ``stage``
    only; the stages after it are redone with what they were made with. The one-step commands use this."""
    if stage not in STEP_COMMANDS:
        raise InputError(f"stage {stage!r} is not one of {', '.join(STEP_COMMANDS)}")
    wrong = sorted(set(changes) - set(STAGE_SETTINGS[stage]))
    if wrong:
        raise InputError(f"{', '.join(wrong)}: not a setting of the {stage} step",
                         hint=f"The {stage} step takes {', '.join(STAGE_SETTINGS[stage])}")
    recorded = _recorded_settings(Path(out))
    recorded.update(changes)
    fields = {k: tuple(v) if isinstance(v, list) else v for k, v in recorded.items() if k in ShrubSettings.__dataclass_fields__}
    layers = {k: recorded.get(k) for k in LAYERS}
    layers["reproject_vectors"] = bool(recorded.get("reproject_vectors", False))
    return ShrubSettings(**fields), layers


def _kept_parameters(previous: dict, from_stage: str) -> dict:
    """The recorded parameters of the stages a rerun from ``from_stage`` did not redo (``gistools classify`` after
    ``gistools density --radius 50ft`` keeps 50 ft, not the default it was not asked for)."""
    if from_stage == "rasters":
        return {}
    start = STAGES.index(from_stage)
    return {k: previous[k] for stage, keys in _STAGE_PARAMETERS.items() if STAGES.index(stage) < start
            for k in keys if k in previous}


def _keep_earlier_settings(record: dict, previous: dict | None, from_stage: str) -> None:
    """The settings of the stages a rerun from ``from_stage`` did not redo, as the earlier run recorded them."""
    if from_stage == "rasters" or not previous:
        return
    for stage in STAGES[1:STAGES.index(from_stage)]:
        record.update({k: previous[k] for k in STAGE_SETTINGS[stage] if k in previous})


def _mean_causes(per_tile: list) -> dict | None:
    """The tiles' mean share of cells without a band, per cause (as nodata_share is their mean)."""
    if not per_tile:
        return None
    return {k: float(np.mean([c.get(k, 0.0) for c in per_tile])) for k in ("no_first_return", "water", "no_ground_near")}


def _band_break_lengths(settings: ShrubSettings) -> tuple[str, str, str]:
    """The band limits as lengths with units, for counting first returns before the vertical unit is known."""
    from ..lidar.bands import PRESETS

    if settings.band_breaks_m is not None:
        return tuple(f"{b}m" for b in settings.band_breaks_m)  # type: ignore[return-value]
    values, unit = PRESETS[settings.bands]
    return tuple(f"{v * unit.metres!r}m" for v in values)  # type: ignore[return-value]


def _returns_band_area(tiles) -> dict | None:
    """Band areas from first returns: share of the returns in each band x the area with a DEM (None if a tile lacks counts)."""
    total = np.zeros(5)
    for t in tiles:
        frb = t.get("first_return_bands")
        if not frb or not sum(frb["counts"]):
            return None
        counts = np.asarray(frb["counts"], float)
        total += counts / counts.sum() * frb["dem_cells"] * frb["cell_area"]
    return {name: float(total[i]) for i, name in enumerate(BAND_NAMES)} | {"above": float(total[4])}


def _check_run_keys(summary: dict) -> None:
    """The keys a step rerun needs, of the types it needs (KeyError, TypeError, ValueError or CRSError else)."""
    pyproj.CRS.from_wkt(summary["crs_wkt"])
    tiles_ok = [isinstance(t, dict) and isinstance(t.get("name"), str) and isinstance(t.get("status"), str)
                for t in summary["tiles"]]
    numbers_ok = [type(summary[k]) in (int, float) and summary[k] > 0
                  for k in ("horizontal_unit_m", "vertical_unit_m", "cell_size")]
    texts_ok = [isinstance(summary[k], str) for k in ("horizontal_unit", "vertical_unit")]
    if not all(tiles_ok + numbers_ok + texts_ok):
        raise ValueError("a key of the wrong type")


def _previous_run(out: Path) -> dict:
    path = out / "report.json"
    if not path.exists():
        raise InputError(f"{out}: no report.json of an earlier run", hint="Run gistools shrub (or gistools rasters) on the tiles first")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
        _check_run_keys(summary)
    except (ValueError, KeyError, TypeError, RecursionError, pyproj.exceptions.CRSError):
        raise DataFileError("report.json is not the report of a gistools run (damaged or edited)", path=path,
                            hint="Rerun gistools shrub on the tiles") from None
    if "topclass" not in summary.get("mosaics", {}) and not (out / "topclass").is_dir():
        raise InputError(f"{out}: the earlier run has no topclass/ rasters", hint="Run gistools shrub on the tiles first")
    return summary


def map_from_classes(out, *, title: str | None = None, unit: LinearUnit | None = None) -> dict:
    """The printable map (PNG and PDF) of a shrub chain's ``out/classes.vrt``: ``gistools map``.

    Writes ``out/shrub_map.png`` and ``out/shrub_map.pdf`` and adds the run to ``out/report.json``.

    Parameters
    ----------
    out : str or path
        The folder of a shrub chain run.
    title : str, optional
        The map's title; None: the chain's.
    unit : LinearUnit, optional
        The unit of the scale bar (``gistools.units.LinearUnit``); None: the data's horizontal unit.

    Returns
    -------
    dict
        ``paths``: the PNG and the PDF.

    Raises
    ------
    InputError
        ``out`` holds no ``classes.vrt``.

    Examples
    --------
    >>> from gistools import map_from_classes, shrub_from_tiles
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> [p.name for p in map_from_classes("shrub", title="Sample block")["paths"]]  # doctest: +SKIP
    ['shrub_map.png', 'shrub_map.pdf']
    """
    out = output_folder(out)
    if not (out / "classes.vrt").exists():
        raise InputError(f"{out}: no classes.vrt", hint="Run gistools shrub (or gistools classify) first")
    summary = _previous_run(out) if unit is None or title is None else {}
    if unit is None:
        unit = LinearUnit(summary["horizontal_unit"], summary["horizontal_unit_m"])
    title = title or summary.get("map_title") or f"Shrub density - {out.name}"  # the chain's title, kept across reruns
    started = time.time()
    with claim_output(out, "gistools map"):
        result = _draw_map(out, title, unit)
        add_run(out, {"tool": "gistools map", "seconds": round(time.time() - started, 3), "settings": {"title": title}})
        return result


def _draw_map(out: Path, title: str, unit: LinearUnit) -> dict:
    from ..plot import map_parameters, shrub_map

    return shrub_map(out / "classes.vrt", out / "shrub_map", title=title, unit=unit,
                     parameters=map_parameters(out / "classes.vrt", out / "cover.vrt", unit))


def _write_polygons(path, polygons, crs, tile_field, area_m2):
    import geopandas as gpd

    rows = [{"tile": n, "class_code": c, "class": CLASS_NAMES[c], "geometry": shapely.from_wkb(g)} for n, c, g in polygons]
    gdf = gpd.GeoDataFrame(rows, geometry="geometry", crs=crs.sub_crs_list[0] if crs.is_compound else crs) if rows else \
        gpd.GeoDataFrame({"tile": [], "class_code": [], "class": []}, geometry=[], crs=crs)
    gdf["area"] = gdf.geometry.area
    gdf["area_acres"] = gdf["area"] * area_m2 / ACRE_M2
    gdf["area_ha"] = gdf["area"] * area_m2 / HECTARE_M2
    write_layer(gdf, path, "shrub_classes")
    write_polygon_style(path, "class_code", {c: v for c, v in CLASS_STYLE.items() if c})  # QGIS draws it by class


def _input_label(inputs) -> str:
    if hasattr(inputs, "local_tiles"):  # an area (gistools.Area)
        return str(inputs)
    items = [inputs] if isinstance(inputs, (str, Path)) else list(inputs)
    return ", ".join(Path(i).name for i in items[:3]) + (" ..." if len(items) > 3 else "")
