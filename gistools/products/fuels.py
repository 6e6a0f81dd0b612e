"""Canopy fuels and the FlamMap landscape of LAS/LAZ tiles (``gistools fuels``, ``gistools:fuels``).

Each tile is read with its neighbours' points (engine.buffered, as gistools metrics): heights above ground come from
the TIN of the ground points of the tile and its neighbours within the buffer, so a tiled run equals a run on the
merged tiles. Per cell of the snapped lattice (default LANDFIRE's 30 m; 100 ft on data in feet): ground elevation
(the TIN at the cell centre), canopy cover, canopy height, canopy base height, canopy bulk density and the surface
strata shares of the height bands (definitions: ``lidar.fuels``, ``lidar.metrics`` fuel_A_B). Then the landscape:
slope and aspect (Horn) of the elevation mosaic, the fuel model, all eight bands in LANDFIRE's order and encodings
(landscape.tif, int16) and the same as FlamMap's landscape file (landscape.lcp, GDAL's LCP driver).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..engine.buffered import (RASTER_FOUND, STRIP_FIELDS, RasterTileState, batch_inputs, buffered_passes, gridded_tile,
                               marked_todo, neighbour_table, read_headers, write_batch_report)
from ..errors import DataFileError, InputError, raise_if_every_tile_failed
from ..grid import cell_centres, cell_index, snapped_grid
from ..io.outdir import claim_output, output_folder
from ..io.points import common_crs, crs_label
from ..io.raster import crs_from_wkt, write_raster, write_vrt
from ..lidar.accumulate import NOISE_CLASSES
from ..lidar.bands import band_thresholds
from ..lidar.fuels import cbd_cbh, lad_profile, layer_counts, ratio_profile
from ..lidar.metrics import MetricSpec, cell_metrics
from ..lidar.normalize import ground_height_at, height_above_ground
from ..parameters import check_all, default_for, option
from ..parameters.core import COMMAND_DEFAULTS
from ..progress import ProgressCallback
from ..units import length_to_crs_units
from ..validation import grid_shape
from .landscape import INT16_RANGE, LANDSCAPE_BANDS, centre_latitude, write_landscape

__all__ = ["FuelsSettings", "fuels_from_tiles", "tile_fuels", "LAYERS", "LANDSCAPE_BANDS", "GROUND_CLASSES"]

GROUND_CLASSES = (2, 9)  # the TIN of heights above ground, as gistools metrics
_CHUNK = 20000  # profile columns computed at once (their layers x this many floats per array), at most
# The bounds of the work, checked against the tiles' headers before the first tile (_check_work). A profile has a
# layer per --layer of the heights (at most the z range of a tile and its neighbours): more than MAX_LAYERS is 1 mm
# layers over 100 m of canopy, finer than any lidar ranges (a few cm), so thinner layers only multiply the work.
MAX_LAYERS = 100_000
PROFILE_BYTES = 128  # what cell_fuels holds per cell (or chunk column) and layer: about 16 float64 arrays
CHUNK_BYTES = 512_000_000  # the chunk's arrays at most: fewer columns at once when the layers are many
# A cell's profile columns ((cell / --column)^2) may be at most this many times its pulses (its first returns, from
# the headers): more leave 99 in 100 columns without a pulse and the rest with one (the bias-corrected estimator
# needs five or more a column, Pimont et al. 2018); the columns' own arrays hold at most one entry per point.
COLUMNS_PER_PULSE = 100
# the per-cell rasters (float32, in the data's units; kg/m3 for cbd, percent for cover, 0-1 shares)
LAYERS = ("elevation", "cover", "height", "cbh", "cbd", "strata_b1", "strata_b2", "strata_b3", "shrub_share")


@dataclass(frozen=True)
class FuelsSettings:
    """Parameters of ``gistools fuels`` (declared in gistools.parameters.fuels: names, defaults, help). Lengths take a
    unit or are in the tiles' CRS units; ``cell_size`` None is 30 m (100 ft on data in feet); ``column`` None: the
    cell's profile columns get ``column_pulses`` first returns each (1 m at 20 pulses per m2). ``extinction`` k,
    ``leaf_mass_area`` kg/m2, ``cbh_threshold`` kg/m3; ``fuel_raster`` a raster of fuel-model codes or None
    (``fuel_codes`` follow the shrub class); ``latitude`` None: the tiles' centre."""

    cell_size: str | float | None = None
    canopy_floor: str | float = default_for("canopy_floor")
    height_percentile: float = default_for("height_percentile")
    layer: str | float = default_for("layer")
    extinction: float = default_for("extinction")
    leaf_mass_area: float = default_for("leaf_mass_area")
    running_mean: str | float = default_for("running_mean")
    cbh_threshold: float = default_for("cbh_threshold")
    bands: str = default_for("bands")
    noise_floor: str | float = default_for("noise_floor")
    class_breaks: tuple = default_for("class_breaks")
    fuel_raster: str | None = None
    fuel_codes: tuple = default_for("fuel_codes")
    latitude: float | None = None
    column: str | float | None = None
    column_pulses: int = default_for("column_pulses")
    profile: str = default_for("profile")
    buffer: str | float = COMMAND_DEFAULTS["fuels"]["buffer"]
    crs: str | None = None

    def validate(self) -> None:
        names = ["canopy_floor", "height_percentile", "layer", "extinction", "leaf_mass_area", "running_mean",
                 "cbh_threshold", "column_pulses", "profile", "bands", "noise_floor", "class_breaks", "buffer"]
        if self.cell_size is not None:
            names.append("cell_size")
        if self.column is not None:
            names.append("column")
        if self.latitude is not None:
            names.append("latitude")
        check_all(self, names)
        _check_positive(self)
        _check_fuel_codes(self.fuel_codes)
        if self.fuel_raster is not None and not Path(self.fuel_raster).is_file():
            raise InputError(f"the fuel-model raster {self.fuel_raster} does not exist",
                             hint="Give an existing raster of Scott and Burgan codes, or leave it out")


# the settings that scale the profile: 0 is no profile (CBD and CBH 0 under any canopy); why each must be positive
# (the layer thickness is a length without a minimum: positive, by its declaration)
_POSITIVE = {"extinction": "the Beer-Lambert extinction coefficient k divides the leaf area density "
                           "(LAD = ln(N_in / N_out) / (k dz))",
             "leaf_mass_area": "the bulk density is the leaf area density times the leaf mass per area"}


def _check_positive(settings: FuelsSettings) -> None:
    for name, why in _POSITIVE.items():
        if not float(getattr(settings, name)) > 0:
            raise InputError(f"{option(name, getattr(settings, name))} must be positive: {why}",
                             hint=f"Give e.g. {option(name, default_for(name))}")


def _check_fuel_codes(codes) -> None:
    """Three whole numbers 0-32767 (the LCP's int16 fuel-model band), light, medium and heavy shrub's in any order;
    the same code three times is a constant fuel model."""
    example = f"Give e.g. {option('fuel_codes', '121,142,145')} (Scott and Burgan codes)"
    try:
        values = [float(c) for c in codes]
    except (TypeError, ValueError):
        raise InputError(f"{option('fuel_codes')} {codes!r} is not a list of numbers", hint=example) from None
    shown = ",".join(f"{v:g}" for v in values)
    if len(values) != 3:
        raise InputError(f"{option('fuel_codes')} {shown}: needs 3 codes (light, medium, heavy shrub), got "
                         f"{len(values)}", hint=example)
    bad = [v for v in values if not (math.isfinite(v) and v.is_integer() and 0 <= v <= INT16_RANGE[1])]
    if bad:
        raise InputError(f"{option('fuel_codes')} {shown}: {bad[0]:g} is not a fuel-model code (codes are whole "
                         f"numbers 0-{INT16_RANGE[1]}, the LCP's int16)", hint=example)


@dataclass(frozen=True)
class _Run:
    """One run's settings in the tiles' units (picklable)."""

    cell_size: float
    floor: float  # canopy floor, z unit
    percentile: float
    dz: float  # layer, z unit
    k: float
    lma: float  # kg/m2
    window: int  # layers of the running mean
    threshold: float  # kg/m3
    bands: tuple  # noise floor, T1, T2, T3 (z unit)
    buffer: float
    out: str
    crs_wkt: str
    z_metres: float  # metres per z unit
    z_unit: str
    xy_metres: float  # metres per xy unit
    column: float | None = None  # xy unit; None: from column_pulses
    profile: str = "ratio"
    xy_unit: str = ""
    column_pulses: int = 20


def _run(settings: FuelsSettings, info, crs, out: Path) -> _Run:
    xy, z = info.unit, info.z_unit
    cell = settings.cell_size
    if cell is None:
        default = COMMAND_DEFAULTS["fuels"]["cell_size"]
        cell = default.ft if xy.metres < 0.5 else default.m
    dz = length_to_crs_units(settings.layer, z, name="layer")
    depth = length_to_crs_units(settings.running_mean, z, name="running mean")
    t1, t2, t3 = band_thresholds(z, settings.bands)
    floor = length_to_crs_units(settings.noise_floor, z, name="noise floor")
    return _Run(length_to_crs_units(cell, xy, name="cell size"), length_to_crs_units(settings.canopy_floor, z,
                name="canopy floor"), float(settings.height_percentile), dz, float(settings.extinction),
                float(settings.leaf_mass_area), max(1, int(round(depth / dz))), float(settings.cbh_threshold),
                (floor, t1, t2, t3), length_to_crs_units(settings.buffer, xy, name="buffer"), str(out), crs.to_wkt(),
                z.metres, z.short, xy.metres,
                None if settings.column is None else length_to_crs_units(settings.column, xy, name="column"),
                settings.profile, xy.short, int(settings.column_pulses))


def _percentile(cell, v, n, p) -> np.ndarray:
    """Per cell, percentile ``p`` of ``v`` (linear interpolation, numpy's default); NaN where a cell has none."""
    spec = MetricSpec("p", "hag", "percentile", ((p, ""),))
    return cell_metrics(cell, n, [spec], hag=v, thresholds={"p": [p]})["p"]


def cell_fuels(cell, n: int, hag, first, ground, run: _Run, column=None, last=None) -> dict:
    """{layer name: float64 array of ``n`` cells} from the points in cells ``cell`` (flat 0..n-1) with heights above
    ground ``hag`` (z unit), ``first`` (first returns), ``ground`` (ground / water class) and ``last`` (each pulse's
    last return; the ratio profile needs it); ``column``: per point, an integer key of its profile column (None:
    one profile per cell). NaN where a cell has no point; cells without canopy have height, CBH and CBD 0. Heights
    out in the z unit, CBD in kg/m3."""
    count = np.bincount(cell, minlength=n)
    has = count > 0
    canopy = (hag > run.floor) & ~ground
    floor_, t1, t2, t3 = run.bands
    specs = [MetricSpec("cover", None, "cover", ((run.floor, ""),)), MetricSpec("b1", None, "fuel", ()),
             MetricSpec("b2", None, "fuel", ()), MetricSpec("b3", None, "fuel", ()),
             MetricSpec("shrub", None, "fuel", ())]
    h_strata = np.where(ground, 0.0, hag)  # a ground return is at the ground, whatever the TIN says
    shares = cell_metrics(cell, n, specs, hag=h_strata, first=first, thresholds={
        "cover": [run.floor], "b1": [floor_, t1], "b2": [t1, t2], "b3": [t2, t3], "shrub": [floor_, t2]})
    cover = 100.0 * shares["cover"]
    height = np.where(has, 0.0, np.nan)
    if canopy.any():
        top = _percentile(cell[canopy], hag[canopy], n, run.percentile)
        height = np.where(np.isfinite(top), top, height)
    # the leaf area density profile (m2/m3), per column then the columns' mean in each cell (over the columns
    # a pulse reaches in that layer: a voxel no pulse reaches has no estimate)
    f = np.asarray(first, bool)
    if column is None:
        colcell, col_of = np.arange(n), np.asarray(cell, np.int64)
    else:
        span = int(column.max(initial=0)) + 1
        keys, col_of = np.unique(np.asarray(cell, np.int64) * span + column, return_inverse=True)
        colcell, col_of = keys // span, col_of.ravel()
    m = len(colcell)
    veg_h = np.where(ground, -np.inf, np.maximum(hag, 0.0))
    layers = _layer_count(veg_h[np.isfinite(veg_h)].max(initial=0.0), run)
    total = np.zeros((n, layers))
    sampled = np.zeros((n, layers))
    seen = np.zeros(m, bool)  # columns with a point (the ratio profile) or a first return (MacArthur-Horn)
    order = np.argsort(col_of, kind="stable")
    chunk = _chunk(layers)
    bounds = np.searchsorted(col_of[order], np.arange(0, m + chunk, chunk))
    for c0, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        if a == b:
            continue
        idx = order[a:b]
        lo, hi = c0 * chunk, min(m, (c0 + 1) * chunk)
        local = col_of[idx] - lo
        if run.profile == "ratio":
            clad = ratio_profile(local, hi - lo, hag[idx], ground[idx], last[idx], dz=run.dz, k=run.k,
                                 layers=layers) / run.z_metres
            seen[lo:hi] = np.bincount(local, minlength=hi - lo) > 0
        else:
            fi = f[idx]
            counts = layer_counts(local[fi], hi - lo, hag[idx][fi], ground[idx][fi], dz=run.dz, layers=layers)
            seen[lo:hi] = counts.sum(axis=1) > 0
            clad = np.where(seen[lo:hi, None], lad_profile(counts, dz=run.dz * run.z_metres, k=run.k), np.nan)
        _add_columns(total, sampled, colcell[lo:hi], clad)
    per = np.bincount(colcell, weights=seen.astype(float), minlength=n)
    lad = np.where(sampled > 0, total / np.maximum(sampled, 1.0), 0.0)
    no_first = per == 0
    cbd, cbh = cbd_cbh(lad * run.lma, dz=run.dz, floor=run.floor, window=run.window, threshold=run.threshold)
    cbd = np.where(has, np.where(no_first, np.nan, cbd), np.nan)
    cbh = np.where(has, np.where(no_first, np.nan, cbh), np.nan)
    return {"cover": cover, "height": height, "cbh": cbh, "cbd": cbd, "strata_b1": shares["b1"],
            "strata_b2": shares["b2"], "strata_b3": shares["b3"], "shrub_share": shares["shrub"]}


def _chunk(layers: int) -> int:
    """The profile columns computed at once: at most _CHUNK, and fewer when the layers are many (CHUNK_BYTES)."""
    return int(max(1, min(_CHUNK, CHUNK_BYTES // (PROFILE_BYTES * max(int(layers), 1)))))


def _layer_count(top: float, run: _Run) -> int:
    """The profile's layers up to height ``top``; DataFileError past MAX_LAYERS (the headers' z range, checked
    before the first tile, said fewer)."""
    layers = math.floor(top / run.dz) + 1
    if layers > MAX_LAYERS:
        raise DataFileError(f"heights above ground reach {top:.6g} {run.z_unit}: {layers:,} layers of {run.dz:.3g} "
                            f"{run.z_unit}, more than the {MAX_LAYERS:,} a profile may have (the header's z range "
                            "is smaller than its points')", hint=f"Give a thicker {option('layer')}, or fix the "
                            "header (lasinfo -repair)")
    return int(layers)


def _add_columns(total, sampled, cells, clad) -> None:
    """Add the columns' profiles ``clad`` (columns x layers, NaN where no pulse reaches) to their cells' rows of
    ``total`` and count them in ``sampled``; ``cells`` (the columns' cells) ascending: only the rows of the cells
    from the first to the last are touched."""
    layers = total.shape[1]
    base = int(cells[0])
    span = int(cells[-1]) - base + 1
    flat_ = ((cells - base)[:, None] * layers + np.arange(layers)).ravel()
    ok = np.isfinite(clad)
    total[base:base + span] += np.bincount(flat_, weights=np.where(ok, clad, 0.0).ravel(),
                                           minlength=span * layers).reshape(span, layers)
    sampled[base:base + span] += np.bincount(flat_, weights=ok.ravel().astype(float),
                                             minlength=span * layers).reshape(span, layers)


def profile_columns(grid, x, y, flat, first, run: _Run) -> np.ndarray:
    """Per point, the key of its profile column within its cell (``flat``: the points' cells): each cell split into
    q x q equal squares, q = round(cell / ``run.column``), or, ``run.column`` None, the q that gives each square
    ``run.column_pulses`` first returns on average (q = round(sqrt(first returns in the cell / column_pulses)))."""
    n = grid.width * grid.height
    if run.column is None:
        pulses = np.bincount(flat[np.asarray(first, bool)], minlength=n)
        q = np.maximum(1, np.rint(np.sqrt(pulses / run.column_pulses))).astype(np.int64)
    else:
        q = np.full(n, max(1, int(round(grid.cell_size / run.column))), np.int64)
    qp = q[flat]
    fx, fy = np.divide(x, grid.cell_size, dtype=np.float64), np.divide(y, grid.cell_size, dtype=np.float64)
    fx, fy = fx - np.floor(fx), fy - np.floor(fy)  # the position inside the cell (cell_index's floor), 0-1
    sx = np.minimum((fx * qp).astype(np.int64), qp - 1)
    sy = np.minimum((fy * qp).astype(np.int64), qp - 1)
    return sx * int(q.max(initial=1)) + sy


def _check_points(ground, use, first) -> None:
    """DataFileError when the tile and its buffer have no ground point (no heights above ground) or the tile's
    cells no first return (no canopy cover, and the landscape would be nodata everywhere)."""
    if not ground.any():
        raise DataFileError("no ground (class 2 or 9) points in the tile or its buffer, so no heights above ground",
                            hint="Classify ground first (gistools ground)")
    if not first.any():
        count = int(np.count_nonzero(use))
        raise DataFileError(f"none of the {count:,} points in the tile's cells (noise left out) is a first return "
                            "(return number 1), so no canopy cover and a landscape of nodata" if count else
                            "no points (noise left out) in the tile's cells", hint="Check its return numbers and "
                            "classes (gistools info lists them)")


def tile_fuels(own: dict, neighbours: list, grid, run: _Run) -> tuple[dict, dict]:
    """(layer name -> 2-D float array on ``grid``, counts) from a tile's points and its neighbours' (dicts of
    STRIP_FIELDS arrays)."""
    allp = {k: np.concatenate([own[k], *(p[k] for p in neighbours)]) for k in STRIP_FIELDS}
    flat = cell_index(grid, allp["x"], allp["y"])
    cls = allp["classification"]
    use = (flat >= 0) & ~np.isin(cls, NOISE_CLASSES)
    g = np.isin(cls, GROUND_CLASSES)
    _check_points(g, use, allp["return_number"][use] <= 1)
    vertex = np.full(len(g), -1, np.int64)
    vertex[g] = np.arange(int(np.count_nonzero(g)))
    hag, inside = height_above_ground(allp["x"][use], allp["y"][use], allp["z"][use], allp["x"][g], allp["y"][g],
                                      allp["z"][g], vertex=vertex[use])
    # a return of the pulse whose ground return is a TIN vertex has a height that is a difference of two
    # quantised z: on a layer's boundary up to the last bits of the TIN's arithmetic, which a TIN of other
    # neighbours may round the other way; rounded to 1e-9 of the unit, it falls on one side in every run
    hag = np.round(hag, 9)
    n = grid.width * grid.height
    first = allp["return_number"][use] <= 1
    column = None
    if (run.column is None or run.column > 0) and use.any():
        column = profile_columns(grid, allp["x"][use], allp["y"][use], flat[use], first, run)
    last = allp["return_number"][use] >= allp["number_of_returns"][use]
    out = cell_fuels(flat[use], n, hag, first, g[use], run, column, last)
    cx, cy = np.meshgrid(*cell_centres(grid))
    elev, _ = ground_height_at(allp["x"][g], allp["y"][g], allp["z"][g], cx.ravel(), cy.ravel())
    out["elevation"] = np.asarray(elev, np.float64)
    counts = {"points_used": int(np.count_nonzero(use)), "heights_outside_tin": int(np.count_nonzero(~inside)),
              "cells_with_points": int(np.count_nonzero(np.bincount(flat[use], minlength=n)))}
    return {k: np.asarray(v, np.float64).reshape(grid.shape) for k, v in out.items()}, counts


_DESCRIPTIONS = {"elevation": "ground elevation ({z})", "cover": "canopy cover (percent)",
                 "height": "canopy height ({z})",
                 "cbh": "canopy base height ({z})", "cbd": "canopy bulk density (kg/m3)",
                 "strata_b1": "share of returns in band B1", "strata_b2": "share of returns in band B2",
                 "strata_b3": "share of returns in band B3",
                 "shrub_share": "share of returns up to 2 m above the floor"}


def _fuels_tile(path: str, sources: list, crs_text, run: _Run) -> dict:
    info, grid, own, (arrays, counts) = gridded_tile(path, sources, crs_text, run.cell_size, run.crs_wkt, run.buffer,
                                                lambda own, around, grid: tile_fuels(own, around, grid, run))
    outputs = {}
    for name in LAYERS:
        target = Path(run.out) / name / f"{info.name}.tif"
        write_raster(target, arrays[name], grid, overwrite=True, tags={"GISTOOLS_PRODUCT": f"fuels_{name}",
                     "GISTOOLS_Z_UNIT": run.z_unit}, description=_DESCRIPTIONS[name].format(z=run.z_unit))
        outputs[name] = str(target)
    return {"outputs": outputs, "points": int(len(own["x"])), "neighbours": [nb for _k, nb, _s in sources], **counts}



@shared_sections
def fuels_from_tiles(inputs, out, settings: FuelsSettings | None = None, *, jobs: int | str = "auto",
                     scheduler: str | None = None, overwrite: bool = False,
                     progress: ProgressCallback | None = None) -> dict:
    """Canopy fuels and the FlamMap landscape of the tiles of ``inputs`` (files, folders, globs, a .vpc).

    Writes ``out/<layer>/<tile>.tif`` and ``out/<layer>.vrt`` for each of :data:`LAYERS` (float32 in the data's
    units: elevation, canopy height and base height in the tiles' vertical unit, canopy bulk density in kg/m3,
    cover in percent, strata shares 0-1), ``out/landscape.tif`` (eight int16 bands in LANDFIRE's order and
    encodings: :data:`LANDSCAPE_BANDS`, metric whatever the data's unit), ``out/landscape.lcp`` (the same, FlamMap's
    landscape file) and ``out/report.json``; returns the report. One bad tile is reported and the others go on.

    Parameters
    ----------
    inputs : str, path or list
        LAS / LAZ files, folders (their tiles), glob patterns or a ``.vpc``; ground classified (class 2).
    out : str or path
        Output folder, made when missing.
    settings : FuelsSettings, optional
        The options (``cell_size``, the profile's constants, the fuel model mapping; lengths as text with their
        unit). None: the defaults (30 m cells on metre data, 100 ft on data in feet).
    {tiles_run}

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts``, each tile's entry in ``tiles``, the
        settings, units and the ``landscape`` files.

    Raises
    ------
    InputError
        An option is not valid, or ``inputs`` holds no tile; the tiles' headers show that an option's work cannot
        be done (too many profile layers or columns, more memory than there is, a landscape off the Earth or beyond
        the LCP's int16: refused before the first tile, with the numbers); or the landscape's values do not fit
        the LCP's int16 (raised once report.json and the fuel layers are written).
    {tiles_raise_rest}

    Examples
    --------
    >>> from gistools.products.fuels import FuelsSettings, fuels_from_tiles
    >>> report = fuels_from_tiles("sample_tiles", "out/fuels", FuelsSettings(cell_size="100ft"))  # doctest: +SKIP
    >>> report["landscape"]["lcp"]  # doctest: +SKIP
    'out/fuels/landscape.lcp'
    """
    settings = settings or FuelsSettings()
    started = time.time()
    paths, override = batch_inputs(inputs, settings, jobs, scheduler)
    out = output_folder(out)
    states, infos = read_headers(paths, override, RasterTileState)
    run = _run(settings, next(iter(infos.values())), common_crs(list(infos.values())), out) if infos else None
    if run is not None:
        _check_work(infos, run, settings)  # before anything is written
    with claim_output(out, "gistools fuels"):
        return raise_if_every_tile_failed(_fuels_in(out, settings, states, infos, run, started, jobs=jobs,
                                                    scheduler=scheduler, overwrite=overwrite, progress=progress))


def _fuels_in(out: Path, settings: FuelsSettings, states: dict, infos: dict, run: _Run | None, started: float, *,
              jobs, scheduler, overwrite, progress) -> dict:
    """The tiles, the mosaics and the landscape; report.json. A landscape that cannot be written (values the LCP
    cannot hold, no cell of data) is raised after the report is written (the tiles' layers are kept)."""
    if run is not None:
        todo, on_done = marked_todo(infos, states, run, out, "gistools fuels",
                                    lambda name: {k: out / k / f"{name}.tif" for k in LAYERS}, RASTER_FOUND, overwrite)
        buffered_passes(todo, infos, states, buffer=max(run.buffer, run.cell_size), crs_text=settings.crs, out=out,
                        jobs=jobs, scheduler=scheduler, progress=progress, tile_fn=_fuels_tile,
                        tile_args=lambda n, sources: (str(infos[n].path), sources, settings.crs, run),
                        on_done=on_done, verb="done", tag="fuels")
    mosaics = _mosaics(out, states) if run is not None else {}
    landscape, refused = None, None
    if run is not None and "elevation" in mosaics:
        try:
            landscape = _landscape(out, mosaics, run, settings, infos)
        except InputError as err:
            refused = err
    first = next(iter(infos.values()), None)
    report = write_batch_report(out, "gistools fuels", crs_label(first.crs) if first else None, settings, states,
                                started, layers=list(LAYERS), units=_units(run, first), mosaics=mosaics,
                                landscape=landscape, warnings=[str(refused)] if refused else [])
    if refused is not None:
        raise refused
    return report


def _mosaics(out: Path, states: dict) -> dict:
    """A VRT per layer over the tiles that are ok or kept."""
    mosaics = {}
    for name in LAYERS:
        tifs = [Path(st.outputs[name]) for st in states.values()
                if st.status in ("ok", "skipped") and name in st.outputs]
        if tifs:
            mosaics[name] = str(write_vrt(out / f"{name}.vrt", sorted(tifs)))
    return mosaics


def _landscape(out: Path, mosaics: dict, run: _Run, settings: FuelsSettings, infos: dict) -> dict:
    """landscape.tif, landscape.lcp and the web map of the canopy base classes."""
    from ..deliver.fuelsmap import fuels_web_map

    landscape = write_landscape(out, mosaics, run, settings)
    landscape["web_map"] = fuels_web_map(out, mosaics["cbh"], z_metres=run.z_metres, xy_metres=run.xy_metres,
                                         parameters={"CRS": crs_label(common_crs(list(infos.values()))),
                                                     "cell size": f"{run.cell_size:g} {run.xy_unit}",
                                                     "profile": run.profile,
                                                     "CBH threshold": f"{run.threshold:g} kg/m3"})["html"]
    return landscape


def _units(run: _Run | None, first) -> dict | None:
    if run is None:
        return None
    return {"cell_size": run.cell_size, "horizontal_unit": first.unit.name, "vertical_unit": first.z_unit.name,
            "canopy_floor": run.floor, "layer": run.dz, "running_mean_layers": run.window, "extinction": run.k,
            "profile_column": run.column, "column_pulses": run.column_pulses if run.column is None else None,
            "leaf_mass_area_kg_m2": run.lma, "cbh_threshold_kg_m3": run.threshold,
            "height_percentile": run.percentile, "band_limits": list(run.bands)}


# ------------------------------------------------------------------ the bounds of the work, from the headers

def _check_work(infos: dict, run: _Run, settings: FuelsSettings) -> None:
    """Refuse, before the first tile and with the arithmetic, what the tiles' headers show cannot be done: a profile
    of more than MAX_LAYERS layers or one whose arrays exceed the available memory (the worst tile: the z range of
    it and its neighbours over --layer, by its cells), more than COLUMNS_PER_PULSE columns a pulse (--column), a
    landscape whose centre is off the Earth (--cell-size) or whose elevations the LCP's int16 cannot hold."""
    from ..validation import check_grid_size

    for info in infos.values():  # the cell size's grid first (as each tile's, but before the first tile)
        check_grid_size(info.bounds, run.cell_size, str(info.path), unit=info.unit.short)
    _check_elevations(infos, run)
    _check_latitude(infos, run, settings)
    table = neighbour_table(infos, max(run.buffer, run.cell_size))
    tiles = [_tile_work(name, info, [infos[Path(p).stem] for p in table[name]], run) for name, info in infos.items()]
    _check_layers(max(tiles, key=lambda t: (t["layers"], t["bytes"])), run, settings)
    _check_memory(max(tiles, key=lambda t: t["bytes"]), run, settings)
    _check_columns(infos, run, settings)


def _tile_work(name: str, info, neighbours: list, run: _Run) -> dict:
    """A tile's profile from its header and its neighbours': the heights it may span, its layers, cells and
    bytes."""
    lows = [info.z_range[0], *(i.z_range[0] for i in neighbours)]
    highs = [info.z_range[1], *(i.z_range[1] for i in neighbours)]
    span = max(max(highs) - min(lows), 0.0)
    layers = math.floor(span / run.dz) + 1  # a Python int: exact however thin the layer
    cols, rows = grid_shape(info.bounds, run.cell_size)
    return {"name": name, "low": min(lows), "high": max(highs), "span": span, "layers": layers,
            "cells": cols * rows, "bytes": PROFILE_BYTES * layers * (cols * rows + _chunk(layers))}


def _check_layers(t: dict, run: _Run, settings: FuelsSettings) -> None:
    if t["layers"] > MAX_LAYERS:
        z = run.z_unit
        raise InputError(f"{option('layer', settings.layer)}: tile {t['name']}'s heights may reach {t['span']:.6g} {z} "
                         f"(z {t['low']:.6g} to {t['high']:.6g} {z} in its and its neighbours' headers), "
                         f"{t['span']:.6g} / {run.dz:.3g} {z} = {t['layers']:.3g} layers, more than the "
                         f"{MAX_LAYERS:,} a profile may have (1 mm layers over 100 m; lidar ranges to a few cm)",
                         hint=f"Give a thicker {option('layer')}, e.g. {option('layer', '1m')} (FVS uses 1 ft)")


def _check_memory(t: dict, run: _Run, settings: FuelsSettings) -> None:
    from ..machine import available_memory

    memory = available_memory()
    if memory is not None and t["bytes"] > 0.8 * memory:
        z, xy = run.z_unit, run.xy_unit
        raise InputError(f"tile {t['name']}'s profiles need about {t['bytes'] / 1e9:,.1f} GB: {t['cells']:,} cells of "
                         f"{run.cell_size:.6g} {xy} x {t['layers']:,} layers of {run.dz:.3g} {z} (its {t['span']:.6g} "
                         f"{z} of z over {option('layer', settings.layer)}) x {PROFILE_BYTES} bytes, more than 80 % "
                         f"of this process's {memory / 1e9:.1f} GB of available memory",
                         hint=f"Give a larger {option('cell_size')} or a thicker {option('layer')}, or run on a "
                         "machine with more memory")


def _check_columns(infos: dict, run: _Run, settings: FuelsSettings) -> None:
    if not run.column:  # None: from --column-pulses (at least one pulse a column); 0: one profile per cell
        return
    pulses = sum((i.points_by_return[0] if i.points_by_return else i.point_count) for i in infos.values())
    area = sum(max(i.bounds[2] - i.bounds[0], 0.0) * max(i.bounds[3] - i.bounds[1], 0.0) for i in infos.values())
    per_cell = pulses / area * run.cell_size ** 2 if area > 0 else math.inf
    q = max(1, round(run.cell_size / run.column))
    if q * q > COLUMNS_PER_PULSE * max(per_cell, 1.0):
        xy = run.xy_unit
        raise InputError(f"{option('column', settings.column)}: ({run.cell_size:g} {xy} cell / {run.column:.3g} {xy} "
                         f"column)^2 = {float(q * q):.3g} columns a cell, but the cells get about {per_cell:,.0f} "
                         f"pulses ({pulses:,} first returns over {area:,.0f} {xy}2 in the headers): more than "
                         f"{COLUMNS_PER_PULSE} columns a pulse, nearly all without one (the profile's estimator needs "
                         "five or more pulses a column)", hint=f"Give a wider {option('column')}, e.g. "
                         f"{option('column', '1m')}, or leave it out (columns of {option('column_pulses')} pulses)")


def _check_elevations(infos: dict, run: _Run) -> None:
    """The landscape's elevation band is int16 metres (LCP): tiles whose every z lies beyond it are refused."""
    low = min(i.z_range[0] for i in infos.values()) * run.z_metres
    high = max(i.z_range[1] for i in infos.values()) * run.z_metres
    lo, hi = INT16_RANGE
    if low > hi or high < lo:
        raise InputError(f"the tiles' z is {low / run.z_metres:,.6g} to {high / run.z_metres:,.6g} {run.z_unit} in "
                         f"their headers ({low:,.0f} to {high:,.0f} m): beyond the {lo:,} to {hi:,} m that the "
                         "landscape's elevation holds (the LCP format stores int16 metres)",
                         hint="Check the tiles' z values and vertical unit (gistools info)")


def _check_latitude(infos: dict, run: _Run, settings: FuelsSettings) -> None:
    """The landscape's centre must be on the Earth (its latitude goes in the .lcp header)."""
    w = min(i.bounds[0] for i in infos.values())
    s = min(i.bounds[1] for i in infos.values())
    e = max(i.bounds[2] for i in infos.values())
    n = max(i.bounds[3] for i in infos.values())
    grid = snapped_grid((w, s, e, n), run.cell_size)
    if not math.isfinite(centre_latitude(grid.transform, (grid.height, grid.width), run.crs_wkt)):
        xy = run.xy_unit
        gw, gs, ge, gn = grid.bounds
        raise InputError(f"{option('cell_size', settings.cell_size)}: the landscape's {grid.width} x {grid.height} "
                         f"cells of {run.cell_size:.6g} {xy} span x {gw:.6g} to {ge:.6g}, y {gs:.6g} to {gn:.6g} "
                         f"{xy}, whose centre is off the Earth in {crs_label(crs_from_wkt(run.crs_wkt))} (no latitude "
                         "for the .lcp header)", hint=f"Give a smaller {option('cell_size')}, e.g. "
                         f"{option('cell_size', '30m')} (LANDFIRE's)")
