"""Heights above ground of LAS/LAZ tiles (``gistools normalize``, ``gistools:normalize``).

Every point gets z minus the TIN of the ground points (classes 2 and 9, as lidR's ``normalize_height``) of its
tile and of its neighbours within the buffer (engine.buffered), so a tiled run equals one TIN of all the tiles'
ground. The height goes into a ``HeightAboveGround`` extra dimension (float32; its description names the unit)
or, with ``replace_z``, into z. With ``classify_vegetation`` unclassified points become low / medium / high
vegetation (3 / 4 / 5) by the height bands, and, given breaklines, surface points in roads road surface (11) and
in water water (9). Every other dimension, the point order, the VLRs are kept; a ``.vpc`` indexes the outputs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import laspy
import numpy as np
import shapely

from ..docstrings import shared_sections
from ..errors import DataFileError, GistoolsError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..io import decoded
from ..io.outdir import claim_output
from ..io.points import common_crs, crs_label, parse_crs_text, read_all_points, read_tile_info, write_all_points
from ..io.vpc import write_vpc
from ..lidar.bands import band_thresholds
from ..lidar.normalize import height_above_ground, vegetation_classes
from ..parameters import check_all, default_for, option, render
from ..parameters.lidar import COMMAND_DEFAULTS
from ..progress import ProgressCallback
from ..units import horizontal_unit, length_to_crs_units
from ..validation import check_length
from ..vector.breaklines import road_polygons, water_polygons
from ..engine.buffered import (PointTileState, batch_inputs, buffered_passes, points_around, read_headers,
                               write_batch_report)
from .ground import _output_name, _wkt1, check_point_format

__all__ = ["NormalizeSettings", "normalize_from_tiles", "HAG_DIMENSION", "GROUND_CLASSES"]

HAG_DIMENSION = "HeightAboveGround"  # PDAL's name (filters.hag_delaunay)
GROUND_CLASSES = (2, 9)


@dataclass(frozen=True)
class NormalizeSettings:
    """Parameters of ``gistools normalize`` (declared in gistools.parameters.lidar: names, defaults, help).
    ``buffer``: how far the neighbours' ground points are read (30 m, lidR's chunk buffer). ``replace_z``: heights
    above ground replace z (no extra dimension). ``classify_vegetation``: classes 3 / 4 / 5 for unclassified points
    by the height bands (``bands``: exact 1 / 2 / 6 m or text_literal; low up to T1, medium up to T3, high above),
    points within ``noise_floor`` of the ground untouched; road surface (11) and water (9) for points of classes 0-2
    within ``noise_floor`` of the ground inside the road and water polygons made from the breaklines (the shrub
    chain's rules: ``snap``, ``max_road_width``, ...). ``format``: laz, las or copc."""

    buffer: str | float = COMMAND_DEFAULTS["normalize"]["buffer"]
    replace_z: bool = default_for("replace_z")
    classify_vegetation: bool = default_for("classify_vegetation")
    bands: str = default_for("bands")
    noise_floor: str | float = default_for("noise_floor")
    snap: str | float = "0.2ft"
    max_road_width: str | float = "60ft"
    max_hydro_width: str | float = "500ft"
    single_line_width: str | float = "8ft"
    format: str = default_for("format")
    crs: str | None = None

    def validate(self) -> None:
        """Every field checked against its declaration, then the rules between them."""
        check_all(self, ("buffer", "noise_floor", "bands"))
        check_length(self.snap, "snap", allow_equal=True, example="0.2ft")
        for value, name in ((self.max_road_width, "max_road_width"), (self.max_hydro_width, "max_hydro_width"),
                            (self.single_line_width, "single_line_width")):
            check_length(value, name, example="60ft")
        if self.format == "copc" and not self.replace_z:
            raise InputError(f"{option('format', 'copc')}: gistools' COPC writer holds no extra dimension, so the "
                             "HeightAboveGround dimension cannot go there",
                             hint=f"Add {option('replace_z')} (the heights as z), or use {option('format', 'laz')}")
        check_point_format(self.format)


@dataclass(frozen=True)
class _Params:
    buffer: float
    replace_z: bool
    classify: bool
    thresholds: tuple
    floor: float
    z_unit: str


def _hag_dimension(las, unit: str) -> None:
    """The HeightAboveGround extra dimension (float32), added unless the file has it already."""
    if HAG_DIMENSION not in las.point_format.dimension_names:
        las.add_extra_dim(laspy.ExtraBytesParams(name=HAG_DIMENSION, type=np.float32,
                                                 description=f"height above ground ({unit})"[:31]))


def _normalize_tile(path: str, sources: list, crs_text, p: _Params, target: str, road_wkb=None, water_wkb=None) -> dict:
    """One tile: heights above ground from the TIN of its and its neighbours' ground, written with the points."""
    info = read_tile_info(path, parse_crs_text(crs_text) if crs_text else None)
    las = decoded.take(path) or read_all_points(path)  # kept by pass 1 in this process, or decoded now
    x, y, z = (np.asarray(getattr(las, k), np.float64) for k in "xyz")
    cls = np.asarray(las.classification, np.uint8)
    withheld = np.asarray(las.withheld, bool) if "withheld" in las.point_format.dimension_names else np.zeros(len(x), bool)
    w, s, e, n = info.bounds
    b = p.buffer
    nb = points_around(sources, (w - b, s - b, e + b, n + b), crs_text)
    g = ~withheld & np.isin(cls, GROUND_CLASSES)
    ground = [np.concatenate([a[g], *(q[k][np.isin(q["classification"], GROUND_CLASSES)] for q in nb)])
              for a, k in ((x, "x"), (y, "y"), (z, "z"))]
    if len(ground[0]) == 0:
        raise DataFileError("no ground (class 2 or 9) points in the tile or within the buffer of its neighbours",
                            path=path, hint=f"Classify ground first (gistools ground), or give a larger {option('buffer')}")
    vertex = np.full(len(x), -1, np.int64)
    vertex[g] = np.arange(int(np.count_nonzero(g)))  # the tile's own ground points come first in the TIN's points
    hag, inside = height_above_ground(x, y, z, *ground, vertex=vertex)
    before = cls.copy()
    if p.classify:
        road = shapely.contains_xy(shapely.from_wkb(road_wkb), x, y) if road_wkb else None
        water = shapely.contains_xy(shapely.from_wkb(water_wkb), x, y) if water_wkb else None
        after = vegetation_classes(cls, hag, p.thresholds, floor=p.floor, road=road, water=water)
        after[withheld] = cls[withheld]
        las.classification = after
    else:
        after = cls
    if p.replace_z:
        las.z = hag
    else:
        _hag_dimension(las, p.z_unit)
        las[HAG_DIMENSION] = hag.astype(np.float32)
    write_all_points(las, target, overwrite=True, copc_wkt=_wkt1(info.crs) if target.endswith(".copc.laz") else None)
    changed = after != before
    by = {int(c): int(k) for c, k in enumerate(np.bincount(after[changed], minlength=256)) if k}
    return {"output": target, "points": int(len(x)), "outside_tin": int(np.count_nonzero(~inside)),
            "hag_range": [float(np.min(hag)), float(np.max(hag))] if len(hag) else None,
            "reclassified": by, "neighbours": [nb_ for _k, nb_, _s in sources],
            "z_range": [float(hag.min()), float(hag.max())] if p.replace_z and len(hag) else list(info.z_range)}


@dataclass
class _TileState(PointTileState):
    outside_tin: int = 0
    hag_range: list | None = None
    reclassified: dict | None = None
    z_range: list | None = None


@shared_sections
def normalize_from_tiles(inputs, out, settings: NormalizeSettings | None = None, *, roads=None, hydro=None,
                         waterbodies=None, reproject_vectors: bool = False, jobs: int | str = "auto", scheduler: str | None = None,
                         overwrite: bool = False, progress: ProgressCallback | None = None) -> dict:
    """Heights above ground of every point of the tiles of ``inputs``: ``gistools normalize``.

    Writes ``out/<tile>.laz`` (or ``.las``, ``.copc.laz``) with the height above ground (an extra dimension, or
    replacing z), ``out/normalized.vpc`` and ``out/report.json``. Tiles whose output exists are kept unless
    ``overwrite``; a tile that fails is reported and the others go on.

    Parameters
    ----------
    inputs : str, path or list
        LAS / LAZ files, folders (their tiles), glob patterns or a ``.vpc``; ground points classified (class 2).
    out : str or path
        Output folder, made when missing.
    settings : NormalizeSettings, optional
        The options (``buffer``, ``replace_z``, ``classify_vegetation``, ``format``, ...; lengths as text with their
        unit or a number in CRS units). None: the defaults.
    roads : str, optional
        Edge-of-pavement lines, a path or ``file.gpkg:LAYER`` (only with ``settings.classify_vegetation``).
    hydro : str, optional
        Water lines, likewise.
    waterbodies : str, optional
        Water polygons, likewise.
    reproject_vectors : bool
        Reproject breaklines in another CRS than the tiles' (else they are refused).
    {tiles_run}

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, skipped, failed), ``tiles``.

    Raises
    ------
    InputError
        An option is not valid (breaklines without ``classify_vegetation``), or ``inputs`` holds no tile.
    {tiles_raise_rest}

    Examples
    --------
    >>> from gistools import normalize_from_tiles
    >>> normalize_from_tiles("sample_tiles", "normalized")["counts"]  # doctest: +SKIP
    {'ok': 4, 'skipped': 0, 'failed': 0}
    """
    settings = settings or NormalizeSettings()
    paths, override = batch_inputs(inputs, settings, jobs, scheduler)
    out = output_folder(out)
    if (roads or hydro or waterbodies) and not settings.classify_vegetation:
        raise InputError(f"{option('roads')} / {option('hydro')} / {option('waterbodies')} are used only with "
                         f"{option('classify_vegetation')}",
                         hint=f"Add {option('classify_vegetation')}, or leave the breaklines out")
    with claim_output(out, "gistools normalize"):
        return raise_if_every_tile_failed(_normalize_in(paths, out, settings, override, jobs, scheduler, overwrite,
                                                        progress, (roads, hydro, waterbodies), reproject_vectors))


def _layers(specs, crs, reproject) -> dict:
    from ..io.vector import check_crs, read_layer

    kinds = {"roads": ("line",), "hydro": ("line",), "waterbodies": ("polygon",)}
    loaded = {}
    for (name, spec) in zip(kinds, specs):
        if spec:
            gdf = check_crs(read_layer(spec, kinds[name], render(option(name))), crs, str(spec), reproject=reproject)
            loaded[name] = [g for g in gdf.geometry if g is not None and not g.is_empty]
    return loaded


def _tile_polygons(layers: dict, bounds, s: NormalizeSettings, crs) -> tuple[bytes | None, bytes | None]:
    """(road, water) polygons of a tile's footprint from the breaklines, as WKB (None when there are none)."""
    if not layers:
        return None, None
    unit = horizontal_unit(crs)
    length = lambda v, n: length_to_crs_units(v, unit, name=n)  # noqa: E731
    frame = shapely.box(*bounds)
    near = {k: [g for g in v if g.intersects(frame)] for k, v in layers.items()}
    snap = length(s.snap, "snap")
    road = road_polygons(near.get("roads", []), frame, snap=snap, max_width=length(s.max_road_width, "max road width")) \
        if near.get("roads") else None
    water = water_polygons(near.get("hydro", []), near.get("waterbodies", []), frame, snap=snap,
                           max_width=length(s.max_hydro_width, "max hydro width"),
                           single_line_width=length(s.single_line_width, "single-line width")) \
        if near.get("hydro") or near.get("waterbodies") else None
    return tuple(None if g is None or g.is_empty else shapely.to_wkb(g) for g in (road, water))


def _normalize_in(paths, out: Path, settings: NormalizeSettings, override, jobs, scheduler, overwrite, progress,
                  layer_specs, reproject) -> dict:
    started = time.time()
    states, infos = read_headers(paths, override, _TileState, lambda q: _output_name(q, settings.format), out)
    crs = common_crs(list(infos.values())) if infos else None
    vpc, p = None, None
    if infos:
        p = _params(settings, next(iter(infos.values())))
        layers = _layers(layer_specs, crs, reproject) if settings.classify_vegetation else {}
        targets = {n: out / _output_name(i.path, settings.format) for n, i in infos.items()}
        todo = []
        for n, t in targets.items():
            if t.exists() and not overwrite:
                states[n].status, states[n].output, states[n].z_range = "skipped", str(t), _z_range(t, override)
            else:
                todo.append(n)

        def args(n, sources):
            return (str(infos[n].path), sources, settings.crs, p, str(targets[n]),
                    *_tile_polygons(layers, infos[n].bounds, settings, crs))

        def on_done(name, value, seconds):
            st = states[name]
            for k in ("output", "points", "outside_tin", "hag_range", "reclassified", "z_range", "neighbours"):
                setattr(st, k, value[k])
            st.seconds = round(seconds, 3)

        buffered_passes(todo, infos, states, buffer=p.buffer, crs_text=settings.crs, out=out, jobs=jobs,
                        scheduler=scheduler, progress=progress, tile_fn=_normalize_tile, tile_args=args, on_done=on_done,
                        verb="normalized", tag="normalize")
        vpc = _vpc(out, infos, states, crs)
    units = None if p is None else {"buffer": p.buffer, "band_thresholds": list(p.thresholds), "noise_floor": p.floor,
                                    "vertical_unit": p.z_unit}
    return write_batch_report(out, "gistools normalize", crs_label(crs) if crs is not None else None, settings, states,
                              started, units=units, dimension=None if settings.replace_z else HAG_DIMENSION,
                              vpc=str(vpc) if vpc else None)


def _params(settings: NormalizeSettings, first) -> _Params:
    xy, zu = first.unit, first.z_unit
    return _Params(length_to_crs_units(settings.buffer, xy, name="buffer"), settings.replace_z,
                   settings.classify_vegetation, band_thresholds(zu, settings.bands),
                   length_to_crs_units(settings.noise_floor, zu, name="noise floor"), zu.short)


def _vpc(out: Path, infos: dict, states: dict, crs):
    """normalized.vpc over the tiles written or kept (their z range: the heights' when z was replaced)."""
    written = [n for n in infos if states[n].status in ("ok", "skipped") and states[n].output]
    if not written:
        return None
    return write_vpc(out / "normalized.vpc", [(states[n].output, infos[n].bounds, states[n].z_range or infos[n].z_range,
                                               infos[n].point_count, crs) for n in written])


def _z_range(path: Path, override) -> list | None:
    """The z range in a kept output's header (its heights, when z was replaced)."""
    try:
        return list(read_tile_info(path, override).z_range)
    except GistoolsError:
        return None
