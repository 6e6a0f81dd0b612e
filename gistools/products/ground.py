"""Ground and noise classification of LAS/LAZ tiles (``gistools ground``, ``gistools:ground``).

Each tile is read whole, with its neighbours' points within a buffer (so a tiled run equals a run on the
merged tiles), classified by ``lidar.ground.classify_ground_and_noise`` (noise, then SMRF or CSF), and
written with only its classification changed: every point, the point order, every other dimension,
the extra bytes and the VLRs as they were. A ``.vpc`` (virtual point cloud) indexes the written tiles.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import shapely

from ..docstrings import shared_sections
from ..errors import InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..io.outdir import claim_output
from ..io.points import (TileInfo, common_crs, crs_label, parse_crs_text, read_all_points, read_tile_info,
                         write_all_points)
from ..io.vpc import write_vpc
from ..lidar.ground import (BELOW_THRESHOLDS, CANOPY_DENSITY_M2, CANOPY_M, CANOPY_MIN_CELL_M, DENSITY_CELL_M,
                            NOISE_BAND_M, NOISE_BINS, RECLASSIFIED, TIGHT_M, TIN_METHODS, CsfParams, NoiseBlocks,
                            NoiseParams, SmrfParams, classify_ground_and_noise, for_data, for_noise,
                            noise_from_histogram, noise_stride, smrftin_params, survey_density,
                            survey_noise_histogram, survey_returns, too_few_in_blocks)
from ..parameters import COMMANDS, PARAMETERS, check, check_all, choices, default_for, option
from ..parameters.lidar import check_method
from ..progress import ProgressCallback
from ..units import length_to_crs_units
from ..engine.buffered import (EVERYWHERE, STRIP_FIELDS, PointTileState, batch_inputs, buffered_passes, points_around,
                               read_headers, write_batch_report)

__all__ = ["GroundSettings", "ground_from_tiles", "FORMATS"]

FORMATS = choices("format")  # declared in gistools.parameters.lidar
WATER = 9


def check_point_format(fmt: str) -> None:
    """The format of the point-writing commands: laz, las, or copc (which needs copclib)."""
    check("format", fmt)
    if fmt == "copc":
        from ..io.copc import copc_available

        if not copc_available():
            raise InputError(f"{option('format', 'copc')} needs copclib, which is not installed",
                             hint=f"pip install 'gistools[copc]', or use {option('format', 'laz')}")


@dataclass(frozen=True)
class GroundSettings:
    """Parameters of ``gistools ground`` (declared in gistools.parameters.lidar: names, defaults, help). Lengths take
    a unit ("1m", "3ft") or are in the tiles' CRS units (heights: their vertical unit).

    SMRF (Pingel et al. 2013; PDAL's names): ``cell``, ``slope`` (rise over run), ``window`` (largest opening
    radius), ``threshold`` and ``scalar`` (a point within threshold + scalar x local slope of the surface is
    ground). The defaults were chosen on the real files of ../shared/data (docs/commands/ground.md): PDAL's own are
    cell 1 m, slope 0.15, window 18 m, threshold 0.5 m, scalar 1.25 m. CSF (lidR ``csf()`` defaults):
    ``csf_resolution``, ``csf_threshold``, ``csf_rigidness``, ``csf_time_step``, ``csf_iterations``,
    ``csf_slope_smooth``. Noise: ``noise`` ivf (lasR ``classify_with_ivf``: ``ivf_res`` 5 m, ``ivf_n`` 6),
    sor (``sor_k``, ``sor_multiplier``) or none; ``low_noise_depth``: points this far below the ground
    surface are low noise (7) even in clusters. ``buffer``: how far the neighbours' points are read (default
    2 x window + 10 cells). ``keep_classes``: points that were ground / noise and are not now keep their class
    (else 1). ``format``: laz, las or copc (needs copclib: ``pip install 'gistools[copc]'``; COPC holds point
    formats 6-8, so formats 0-5 are converted, and stores points in octree order).
    """

    method: str = default_for("ground_method")
    noise: str = default_for("noise")
    cell: str | float = default_for("cell")
    slope: float = default_for("slope")
    window: str | float = default_for("window")
    threshold: str | float = default_for("threshold")
    scalar: str | float = default_for("scalar")
    smrftin_cell: str | float = default_for("smrftin_cell")
    smrftin_slope: float = default_for("smrftin_slope")
    smrftin_window: str | float = default_for("smrftin_window")
    smrftin_threshold: str | float = default_for("smrftin_threshold")
    smrftin_scalar: str | float = default_for("smrftin_scalar")
    smrftin_step: str | float = default_for("smrftin_step")
    smrftin_patch: str | float = default_for("smrftin_patch")
    csf_resolution: str | float = default_for("csf_resolution")
    csf_threshold: str | float = default_for("csf_threshold")
    csf_rigidness: int = default_for("csf_rigidness")
    csf_time_step: float = default_for("csf_time_step")
    csf_iterations: int = default_for("csf_iterations")
    csf_slope_smooth: bool = default_for("csf_slope_smooth")
    ivf_res: str | float = default_for("ivf_res")
    ivf_n: int = default_for("ivf_n")
    sor_k: int = default_for("sor_k")
    sor_multiplier: float = default_for("sor_multiplier")
    low_noise_depth: str | float = default_for("low_noise_depth")
    buffer: str | float | None = None
    keep_classes: bool = default_for("keep_classes")
    format: str = default_for("format")
    crs: str | None = None

    def validate(self) -> None:
        """Every option checked against its declaration before anything is read or written."""
        check_method("ground_method", self.method)
        check_all(self)  # every field with a declaration of its name
        check_point_format(self.format)
        if float(self.csf_time_step) <= 0:
            raise InputError(f"{option('csf_time_step', self.csf_time_step)}: the cloth would not move; give a step "
                             "above 0", hint=f"e.g. {option('csf_time_step', default_for('csf_time_step'))} (CSF's own)")
        self._check_options_of_the_method()
        if self.method == "csf":
            import importlib.util

            if importlib.util.find_spec("CSF") is None:  # cloth-simulation-filter, the optional extra
                raise InputError(f"{option('method', 'csf')} needs cloth-simulation-filter, which is not installed",
                                 hint=f"pip install 'gistools[ground]', or use {option('method', 'smrf')}")


    def _check_options_of_the_method(self) -> None:
        """An option of another filter than the run's (changed from its default) is refused, naming the filter
        that reads it; adaptive reads smrftin's (under a canopy its own set takes their place)."""
        reads = "smrftin" if self.method == "adaptive" else self.method
        for name in COMMANDS["ground"]:
            method = PARAMETERS[name].read_by
            if method and method != reads:
                value = getattr(self, name)
                if value is not None and value != default_for(name):
                    raise InputError(f"{option(name, value)} is read by {option('method', method)}, and this run's "
                                     f"filter is {self.method}: it would change nothing",
                                     hint=f"Add {option('method', method)}, or leave {option(name)} out")


@dataclass(frozen=True)
class _Params:
    """The settings in one run's units (picklable, for the workers)."""

    method: str
    smrf: SmrfParams
    smrftin: SmrfParams
    csf: CsfParams
    noise: NoiseParams
    keep_classes: bool
    buffer: float
    z_metres: float = 1.0


def _params(s: GroundSettings, info: TileInfo) -> _Params:
    xy, z = info.unit, info.z_unit

    def h(v, n):  # horizontal lengths
        return length_to_crs_units(v, xy, name=n)

    def v(val, n):  # heights
        return length_to_crs_units(val, z, name=n)

    smrf = SmrfParams(cell=h(s.cell, "cell"), slope=float(s.slope), window=h(s.window, "window"),
                      threshold=v(s.threshold, "threshold"), scalar=v(s.scalar, "scalar"), z_per_xy=xy.metres / z.metres)
    smrftin = smrftin_params(cell=h(s.smrftin_cell, "smrftin cell"), slope=float(s.smrftin_slope),
                             window=h(s.smrftin_window, "smrftin window"),
                             threshold=v(s.smrftin_threshold, "smrftin threshold"),
                             scalar=v(s.smrftin_scalar, "smrftin scalar"), step=v(s.smrftin_step, "smrftin step"),
                             patch=h(s.smrftin_patch, "smrftin patch"), z_per_xy=xy.metres / z.metres,
                             noise_band=tuple(v(f"{m}m", "smrftin noise") for m in NOISE_BAND_M),
                             tight=(v(f"{TIGHT_M[0]}m", "smrftin threshold"), v(f"{TIGHT_M[1]}m", "smrftin scalar"), TIGHT_M[2]))
    csf = CsfParams(resolution=h(s.csf_resolution, "CSF resolution"), threshold=v(s.csf_threshold, "CSF threshold"),
                    rigidness=int(s.csf_rigidness), time_step=float(s.csf_time_step), iterations=int(s.csf_iterations),
                    slope_smooth=bool(s.csf_slope_smooth))
    noise = NoiseParams(method=s.noise, res=h(s.ivf_res, "IVF resolution"), n=int(s.ivf_n), k=int(s.sor_k),
                        multiplier=float(s.sor_multiplier), low_depth=v(s.low_noise_depth, "low noise depth"))
    if s.method == "adaptive":  # smrftin's set and the one it takes under a canopy (the data's units)
        c, m = CANOPY_M, xy.metres
        smrftin = replace(smrftin, canopy=(h(f"{c[0]}m", "canopy cell"), v(f"{c[1]}m", "canopy threshold"),
                                           v(f"{c[2]}m", "canopy scalar"), c[3], CANOPY_DENSITY_M2 * m * m,
                                           h(f"{CANOPY_MIN_CELL_M}m", "canopy smallest cell")),
                          below=BELOW_THRESHOLDS)
    used = smrftin if s.method in TIN_METHODS else smrf
    cell = max(used.cell, used.canopy[0]) if used.canopy else used.cell  # the coarser of its lattices
    buffer = 2 * used.window + 10 * cell
    if s.method in TIN_METHODS:  # raised patches are judged whole: up to a patch's width, and its neighbours'
        buffer += 2 * smrftin.patch + 3 * cell
    buffer = h(s.buffer, "buffer") if s.buffer is not None else buffer
    return _Params(s.method, smrf, smrftin, csf, noise, bool(s.keep_classes), buffer, z.metres)


# the widest window the progressive filter takes, in cells of its grid: it opens the surface once per cell of
# radius, and an opening of radius r is r passes over the grid (r^2 / 2 passes in all). 200 cells (300 m on
# smrftin's 1.5 m cells, 200 m on SMRF's 1 m) is ten times the largest buildings' half-width the filters are
# used for (PDAL's default 18 m, lidR's pmf windows up to about 30 m) and about 20 s a 1 km tile.
MAX_WINDOW_CELLS = 200
CSF_PARTICLE_BYTES = 400  # cloth-simulation-filter's memory per cloth particle (its Particle and neighbour lists)


def check_ground_work(p: _Params, infos: dict, settings: GroundSettings) -> None:
    """Refuse, before the first tile, settings whose work or memory explodes on these tiles: a filter grid or a CSF
    cloth that the memory cannot hold, a window of more than MAX_WINDOW_CELLS cells (the arithmetic in the
    message)."""
    from ..validation import check_grid_size

    if not infos:
        return
    smrftin = p.method in TIN_METHODS
    used = p.smrftin if smrftin else p.smrf
    cell_name, window_name = ("smrftin_cell", "smrftin_window") if smrftin else ("cell", "window")
    unit = next(iter(infos.values())).unit.short
    survey = (min(i.bounds[0] for i in infos.values()), min(i.bounds[1] for i in infos.values()),
              max(i.bounds[2] for i in infos.values()), max(i.bounds[3] for i in infos.values()))
    for info in infos.values():
        w, s, e, n = info.bounds
        grown = (max(w - p.buffer, survey[0]), max(s - p.buffer, survey[1]), min(e + p.buffer, survey[2]),
                 min(n + p.buffer, survey[3]))  # the points a tile's filter grids: its own and its neighbours'
        if p.method == "csf":
            check_grid_size(grown, p.csf.resolution, f"{info.path} (CSF cloth)", unit=unit,
                            bytes_per_cell=CSF_PARTICLE_BYTES, cell_option="csf_resolution")
        else:
            check_grid_size(grown, used.cell, str(info.path), unit=unit, cell_option=cell_name)
    radius = math.ceil(used.window / used.cell)
    if p.method != "csf" and radius > MAX_WINDOW_CELLS:
        given = getattr(settings, window_name)
        raise InputError(
            f"{option(window_name, given)} ({used.window:g} {unit}) is a radius of {radius:,} cells of "
            f"{used.cell:g} {unit}: the filter opens the surface once per cell of radius, about "
            f"{radius * radius / 2:,.0f} passes over each tile's grid; at most {MAX_WINDOW_CELLS} cells "
            f"({MAX_WINDOW_CELLS * used.cell:g} {unit}) are taken",
            hint=f"Give about half the width of the largest building, e.g. "
                 f"{option(window_name, default_for(window_name))}")


def _output_name(path: Path, fmt: str) -> str:
    stem = path.name[: -len(".copc.laz")] if path.name.lower().endswith(".copc.laz") else path.stem
    return f"{stem}.copc.laz" if fmt == "copc" else f"{stem}.{fmt}"


def _tile_points(path: str, neighbours: list, crs_text, p: _Params, water_wkb=()):
    """(las, info, own non-withheld count, withheld mask, the tile's and its neighbours' points within the buffer)."""
    override = parse_crs_text(crs_text) if crs_text else None
    info = read_tile_info(path, override)
    las = read_all_points(path)
    own = {"x": np.asarray(las.x, np.float64), "y": np.asarray(las.y, np.float64), "z": np.asarray(las.z, np.float64),
           "return_number": np.asarray(las.return_number, np.uint8),
           "number_of_returns": np.asarray(las.number_of_returns, np.uint8),
           "classification": np.asarray(las.classification, np.uint8)}
    withheld = np.asarray(las.withheld, bool) if "withheld" in las.point_format.dimension_names else np.zeros(len(own["x"]), bool)
    w, s, e, n = info.bounds
    box = (w - p.buffer, s - p.buffer, e + p.buffer, n + p.buffer)
    parts = [{k: a[~withheld] for k, a in own.items()}, *points_around(neighbours, box, crs_text)]
    allp = {k: np.concatenate([q[k] for q in parts]) for k in own}
    _in_water(allp, water_wkb)
    return las, info, int(np.count_nonzero(~withheld)), withheld, allp


def _in_water(allp: dict, water_wkb) -> None:
    """Returns on the water polygons are water (class 9, in ``allp``), out of the ground filter."""
    if water_wkb:
        inside = shapely.contains_xy(shapely.union_all([shapely.from_wkb(g) for g in water_wkb]), allp["x"], allp["y"])
        allp["classification"] = np.where(inside & np.isin(allp["classification"], RECLASSIFIED), WATER,
                                          allp["classification"]).astype(np.uint8)


def _noise_tile(path: str, sources: list, crs_text, p: _Params, stride: int, water_wkb=()) -> dict:
    """smrftin's first pass on one tile (lidar.ground.survey_noise_histogram): the histogram of its own ground
    points' residuals, which the run adds up into the survey's noise. A large survey (``stride`` > 1) is measured
    in its NoiseBlocks: the tile's own points there come from its own strip (``sources[0]``), not the tile."""
    if stride <= 1:
        _las, _info, n_own, _withheld, allp = _tile_points(path, sources, crs_text, p, water_wkb)
    else:
        info = read_tile_info(path, parse_crs_text(crs_text) if crs_text else None)
        w, s, e, n = info.bounds
        b = NoiseBlocks.of(p.smrftin, p.z_metres, stride).reach
        mine = points_around(sources[:1], EVERYWHERE, crs_text)
        if len(mine[0]["x"]):  # own points beyond the header's bounds have their blocks too
            w, s = min(w, float(mine[0]["x"].min())), min(s, float(mine[0]["y"].min()))
            e, n = max(e, float(mine[0]["x"].max())), max(n, float(mine[0]["y"].max()))
        b *= 1 + 1e-9  # and a block's edge within rounding of the box's
        parts = mine + points_around(sources[1:], (w - b, s - b, e + b, n + b), crs_text)
        allp = {k: np.concatenate([q[k] for q in parts]) for k in STRIP_FIELDS}
        n_own = len(mine[0]["x"])
        _in_water(allp, water_wkb)
        sources = sources[1:]
    own = np.zeros(len(allp["x"]), bool)
    own[:n_own] = True
    counts = survey_noise_histogram(allp["x"], allp["y"], allp["z"], allp["return_number"], allp["number_of_returns"],
                                    allp["classification"], own, p.smrftin, p.noise, p.z_metres, stride)
    returns = survey_returns(allp["x"][:n_own], allp["y"][:n_own], allp["return_number"][:n_own],
                             allp["number_of_returns"][:n_own], _density_cell(p))  # adaptive's measures
    return {"histogram": counts.tolist(), "returns": returns, "neighbours": [nb for _kind, nb, _source in sources]}


def _ground_tile(path: str, neighbours: list, crs_text, p: _Params, target: str, water_wkb=()) -> dict:
    """Classify one tile with its neighbours' buffer strips and write it; the class counts before and after."""
    las, info, n_own, withheld, allp = _tile_points(path, neighbours, crs_text, p, water_wkb)
    used = [name for _kind, name, _source in neighbours]
    with _quiet_stdout(p.method == "csf"):  # the CSF library prints its progress to the C stdout
        new = classify_ground_and_noise(allp["x"], allp["y"], allp["z"], allp["return_number"],
                                        allp["number_of_returns"], allp["classification"], method=p.method, smrf=p.smrf,
                                        smrftin=p.smrftin, adaptive=p.smrftin, csf=p.csf, noise=p.noise,
                                        keep_classes=p.keep_classes, z_metres=p.z_metres)
    before = np.asarray(las.classification, np.uint8).copy()
    after = before.copy()
    after[~withheld] = new[:n_own]
    las.classification = after
    write_all_points(las, target, overwrite=True, copc_wkt=_wkt1(info.crs) if target.endswith(".copc.laz") else None)
    counts = {int(c): int(k) for c, k in enumerate(np.bincount(after, minlength=256)) if k}
    return {"output": target, "points": int(len(after)), "changed": int(np.count_nonzero(after != before)),
            "points_by_class": counts, "neighbours": used, "bounds": list(info.bounds), "z_range": list(info.z_range)}


_QUIET = {"lock": threading.Lock(), "depth": 0, "saved": None}  # tiles on threads (engine.ThreadPool) share fd 1


@contextlib.contextmanager
def _quiet_stdout(active: bool):
    """The process's file descriptor 1 sent to /dev/null for the block (C libraries that print), when ``active``;
    tiles on several threads: from the first one in to the last one out."""
    if not active:
        yield
        return
    with _QUIET["lock"]:
        if _QUIET["depth"] == 0:
            sys.stdout.flush()
            _QUIET["saved"] = os.dup(1)
            with open(os.devnull, "wb") as null:
                os.dup2(null.fileno(), 1)
        _QUIET["depth"] += 1
    try:
        yield
    finally:
        with _QUIET["lock"]:
            _QUIET["depth"] -= 1
            if _QUIET["depth"] == 0:
                os.dup2(_QUIET["saved"], 1)
                os.close(_QUIET["saved"])


def _wkt1(crs) -> str:
    try:
        return crs.to_wkt("WKT1_GDAL")
    except Exception:  # a CRS WKT1 cannot express
        return crs.to_wkt()


@dataclass
class _TileState(PointTileState):
    changed: int = 0
    points_by_class: dict | None = None


@shared_sections
def ground_from_tiles(inputs, out, settings: GroundSettings | None = None, *, jobs: int | str = "auto", scheduler: str | None = None,
                      overwrite: bool = False, progress: ProgressCallback | None = None, water=None) -> dict:
    """Ground (class 2) and noise (7, 18) of every tile of ``inputs``, classified: ``gistools ground``.

    Writes ``out/<tile>.laz`` (or ``.las``, ``.copc.laz``), ``out/ground.vpc`` and ``out/report.json``. Inputs are
    never written. Tiles whose output exists are kept (a rerun resumes) unless ``overwrite``; a tile that fails is
    reported and the others go on.

    Parameters
    ----------
    {tiles_in}
    settings : GroundSettings, optional
        The options (``method`` smrf or csf, the filter's parameters, ``noise``, ``format``, ...; lengths as text
        with their unit, e.g. ``"1m"``, or a number in CRS units; heights in the vertical unit). None: the defaults.
    {tiles_run}
    water : list of shapely geometries, optional
        Water polygons (shapely geometries, in CRS units) whose points of classes 0, 1, 2, 7, 18 become water (9)
        before the filters.

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, skipped, failed), ``tiles``, ``vpc``.

    {tiles_raise}

    Examples
    --------
    >>> from gistools import GroundSettings, ground_from_tiles
    >>> report = ground_from_tiles("sample_tiles", "ground", GroundSettings(method="smrf"))  # doctest: +SKIP
    >>> report["counts"]  # doctest: +SKIP
    {'ok': 4, 'skipped': 0, 'failed': 0}
    """
    settings = settings or GroundSettings()
    paths, override = batch_inputs(inputs, settings, jobs, scheduler)
    out = output_folder(out)
    with claim_output(out, "gistools ground"):
        try:
            return raise_if_every_tile_failed(_ground_in(paths, out, settings, override, jobs, scheduler, overwrite,
                                                         progress, water))
        finally:
            if settings.method == "csf":  # the cloth's helper processes end with the run (gistools.lidar.cloth)
                from ..lidar.cloth import close_helper

                close_helper()


def _ground_in(paths, out: Path, settings: GroundSettings, override, jobs, scheduler, overwrite, progress,
               water=None) -> dict:
    started = time.time()
    states, infos = read_headers(paths, override, _TileState, lambda q: _output_name(q, settings.format), out)
    crs = common_crs(list(infos.values())) if infos else None
    p = _params(settings, next(iter(infos.values()))) if infos else None
    check_ground_work(p, infos, settings)
    targets = {name: out / _output_name(info.path, settings.format) for name, info in infos.items()}
    todo = []
    for name, target in targets.items():
        if target.exists() and not overwrite:
            states[name].status, states[name].output = "skipped", str(target)
        else:
            todo.append(name)
    if todo and p.method in TIN_METHODS and p.smrftin.noise_band and p.smrftin.noise is None:
        p = _measured_noise(infos, states, p, settings.crs, out, jobs, scheduler, progress, water)
        todo = [n for n in todo if states[n].status != "failed"]
    _classify_tiles(todo, infos, targets, states, p, settings.crs, out, jobs, scheduler, progress, water)
    written = [n for n in infos if states[n].status in ("ok", "skipped") and states[n].output]
    vpc = write_vpc(out / "ground.vpc", [(states[n].output, infos[n].bounds, infos[n].z_range, infos[n].point_count, crs)
                                         for n in written]) if written else None
    return _ground_report(out, settings, p, infos, states, crs, vpc, started)


def _near(water, bounds, margin: float) -> list:
    """The water polygons that reach a tile's box grown by ``margin``, as WKB (small to send to a worker)."""
    if not water:
        return []
    w, s, e, n = bounds
    area = shapely.box(w - margin, s - margin, e + margin, n + margin)
    return [shapely.to_wkb(g) for g in water if g.intersects(area)]


def _measured_noise(infos, states, p: _Params, crs_text, out, jobs, scheduler, progress, water=None) -> _Params:
    """smrftin's first pass over every tile (kept ones too, so that a rerun measures what a whole run measures):
    the survey's ground noise from the tiles' histograms added up, in ``p.smrftin.noise``, and its share of points of
    multi-return pulses (the tiles' own points; in the blocks of a large survey), in ``p.smrftin.multi``."""
    names = [n for n in infos if states[n].status != "failed"]
    stride = noise_stride(sum(infos[n].point_count for n in names))  # a large survey: measured in blocks
    total, returns = _noise_pass(names, infos, states, p, stride, crs_text, out, jobs, scheduler, progress, water)
    if too_few_in_blocks(stride, total):  # the blocks missed the survey's ground: every point
        total, returns = _noise_pass(names, infos, states, p, 1, crs_text, out, jobs, scheduler, progress, water)
    noise = noise_from_histogram(total, p.z_metres) if total.size else None
    (points, multi, last), cells = returns
    share = multi / points if points else None
    density = survey_density(int(last), len(cells), _density_cell(p))
    # an unknown noise (too few ground points) is the run's answer too: the tiles do not measure it again
    return replace(p, smrftin=replace(p.smrftin, noise=noise, multi=share, density=density) if noise is not None
                   else for_data(p.smrftin, None, share, density))


def _density_cell(p: _Params) -> float:
    """DENSITY_CELL_M in the run's CRS units."""
    return DENSITY_CELL_M / (p.smrftin.z_per_xy * p.z_metres)


def _noise_pass(names, infos, states, p: _Params, stride: int, crs_text, out, jobs, scheduler, progress,
                water=None) -> tuple[np.ndarray, tuple]:
    """(the tiles' noise histograms added up, ([their points, those of multi-return pulses, last returns], the
    keys of the density cells that hold one)) (``_noise_tile`` over ``names``; in NoiseBlocks when ``stride`` >
    1)."""
    total = np.zeros(NOISE_BINS + 1, np.int64)
    counts = np.zeros(3, np.int64)  # points, points of multi-return pulses, last returns
    cells = []
    blocks = NoiseBlocks.of(p.smrftin, p.z_metres, stride) if stride > 1 else None
    buffer = blocks.reach if blocks else p.buffer

    def args(n, sources):
        return (str(infos[n].path), sources, crs_text, p, stride, _near(water, infos[n].bounds, buffer))

    def on_done(name, value, seconds):
        total[:] += np.asarray(value["histogram"], np.int64)
        counts[:] += np.asarray(value["returns"][:3], np.int64)
        cells.append(np.asarray(value["returns"][3], np.int64))

    kept = {n: states[n].status for n in names}
    buffered_passes(names, infos, states, buffer=buffer, crs_text=crs_text, out=out, jobs=jobs, scheduler=scheduler,
                    progress=progress, tile_fn=_noise_tile, tile_args=args, on_done=on_done, verb="measured",
                    tag="ground-noise", strip_rule=blocks)
    for n, status in kept.items():  # a kept tile stays "skipped"; a failure of the first pass stays a failure
        if states[n].status != "failed":
            states[n].status = status
    return total, (counts, np.unique(np.concatenate(cells)) if cells else np.zeros(0, np.int64))


def _classify_tiles(todo, infos, targets, states, p: _Params, crs_text, out, jobs, scheduler, progress, water=None) -> None:
    """Each tile with its neighbours' edge strips (engine.buffered), inline, on local processes or on Dask."""
    if not todo:  # every tile kept, or none whose header reads (their errors are in ``states``)
        return

    def args(n, sources):
        return (str(infos[n].path), sources, crs_text, p, str(targets[n]), _near(water, infos[n].bounds, p.buffer))

    def on_done(name, value, seconds):
        st = states[name]
        for k in ("output", "points", "changed", "points_by_class", "neighbours"):
            setattr(st, k, value[k])
        st.seconds = round(seconds, 3)

    buffered_passes(todo, infos, states, buffer=p.buffer, crs_text=crs_text, out=out, jobs=jobs, scheduler=scheduler,
                    progress=progress, tile_fn=_ground_tile, tile_args=args, on_done=on_done, verb="classified",
                    tag="ground")


def _kept_units(out, units: dict) -> dict:
    """The units of the folder's report (the run that made its tiles), where every tile was kept and nothing was
    measured; else these, the set's figures unknown (None)."""
    from ..engine.record import read_folder_report

    before = (read_folder_report(out) or {}).get("units")
    if isinstance(before, dict) and set(units) <= set(before):
        return {k: before[k] for k in units}
    return {**units, **{k: None for k in ("cell", "threshold", "scalar", "slope", "ground_noise",
                                           "multi_return_share", "last_returns_per_square_metre")}}


def _ground_report(out, settings: GroundSettings, p: _Params | None, infos: dict, states: dict, crs, vpc,
                   started) -> dict:
    first = next(iter(infos.values()), None)
    tin = p is not None and p.method in TIN_METHODS
    used = None if p is None else (for_data(p.smrftin, p.smrftin.noise, p.smrftin.multi, p.smrftin.density) if tin
                                   else p.smrf)
    units = None if p is None else {"cell": used.cell, "window": used.window, "threshold": used.threshold,
                                    "scalar": used.scalar, "slope": used.slope, "buffer": p.buffer,
                                    "horizontal_unit": first.unit.name, "vertical_unit": first.z_unit.name}
    if tin:
        units["ground_noise"] = used.noise  # measured by smrftin's first pass (vertical unit); None: too few points
        units["multi_return_share"] = used.multi  # points of multi-return pulses (adaptive's measure of a canopy)
        metres = first.unit.metres
        units["last_returns_per_square_metre"] = None if used.density is None else used.density / (metres * metres)
        if p.smrftin.noise_band and p.smrftin.noise is None and p.smrftin.multi is None:  # every tile kept: nothing
            units = _kept_units(out, units)  # measured; the run that made them said what it took
    return write_batch_report(out, "gistools ground", crs_label(crs) if crs is not None else None, settings, states,
                              started, units=units, vpc=str(vpc) if vpc else None)
