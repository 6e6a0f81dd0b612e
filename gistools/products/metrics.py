"""Cell metrics of LAS/LAZ tiles (``gistools metrics``, ``gistools:metrics``): one GeoTIFF per metric per tile on
the snapped lattice of ``gistools rasters``, a VRT per metric, report.json.

Each tile is read with its neighbours' points (engine.buffered): the cells on a shared edge get every point that
falls in them, and heights above ground come from the TIN of the ground points of the tile and its neighbours
within the buffer, so a tiled run equals a run on the merged tiles. Definitions: ``lidar.metrics``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..errors import DataFileError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..grid import cell_index, snapped_grid
from ..io.outdir import claim_output
from ..io.points import common_crs, crs_label
from ..io.raster import write_raster, write_vrt
from ..lidar.accumulate import NOISE_CLASSES
from ..lidar.metrics import LAYER_HEIGHT_M, MetricSpec, cell_metrics, needs_heights, parse_metric
from ..lidar.normalize import height_above_ground
from ..parameters import check_all, choices, default_for, option
from ..parameters.lidar import COMMAND_DEFAULTS, current_word
from ..progress import ProgressCallback
from ..units import length_to_crs_units
from ..validation import check_length
from ..engine.buffered import (RASTER_FOUND, STRIP_FIELDS, RasterTileState, batch_inputs, buffered_passes, gridded_tile,
                               marked_todo, read_headers, write_batch_report)

__all__ = ["MetricsSettings", "metrics_from_tiles", "RETURNS", "DEFAULT_METRICS", "GROUND_CLASSES"]

RETURNS = choices("returns")  # declared in gistools.parameters.lidar: the same words as gistools points
DEFAULT_METRICS = tuple(default_for("metrics"))
GROUND_CLASSES = (2, 9)  # the TIN of heights above ground: ground and water, as lidR's normalize_height


@dataclass(frozen=True)
class MetricsSettings:
    """Parameters of ``gistools metrics`` (declared in gistools.parameters.lidar: names, defaults, help).
    ``metrics``: names (lidar.metrics); ``normalized``: every z_* metric is computed on heights above ground instead
    and named hag_*. ``classes``: the ASPRS classes whose points count (None: all but noise 7, 18); ``returns``:
    first, last or all ("any", the old word of gistools points for all, is still taken). ``buffer``: how far the
    neighbours' ground points are read for heights above ground (default 30 m, lidR's chunk buffer). Lengths take a
    unit or are in the tiles' CRS units; a threshold in a metric's name ("hag_above2m", "cover_above6ft") likewise, a
    bare number being in the tiles' vertical unit."""

    cell_size: str | float = COMMAND_DEFAULTS["metrics"]["cell_size"]
    metrics: tuple[str, ...] = DEFAULT_METRICS
    normalized: bool = default_for("normalized")
    classes: tuple[int, ...] | None = None
    returns: str = default_for("returns")
    buffer: str | float = COMMAND_DEFAULTS["metrics"]["buffer"]
    crs: str | None = None

    def __post_init__(self):
        object.__setattr__(self, "returns", current_word("returns", self.returns))

    def specs(self) -> list[MetricSpec]:
        """The metrics asked for, hag_* in place of z_* when ``normalized`` (each name once)."""
        names = [f"hag_{m[2:]}" if self.normalized and m.startswith("z_") else m for m in self.metrics]
        return [parse_metric(m) for m in dict.fromkeys(names)]

    def validate(self) -> None:
        """Every field checked against its declaration, then each metric's name and thresholds."""
        if not self.metrics:
            raise InputError("no metric given", hint=f"e.g. {option('metrics', ('count', 'z_max', 'z_p95'))}")
        self.specs()
        check_all(self, ("cell_size", "buffer", "returns", "classes"))
        for spec in self.specs():
            for value, unit in spec.numbers:
                if unit:
                    check_length(f"{value}{unit}", f"metric {spec.name}", allow_equal=True, example="2m")


@dataclass(frozen=True)
class _Run:
    """One run's settings in the tiles' units (picklable)."""

    cell_size: float
    specs: tuple
    thresholds: dict
    layer: float
    classes: tuple | None
    returns: str
    buffer: float
    out: str
    crs_wkt: str
    z_unit: str
    cell_area_m2: float


def _run(settings: MetricsSettings, info, crs, out: Path) -> _Run:
    xy, z = info.unit, info.z_unit
    specs = settings.specs()
    thresholds = {}
    for spec in specs:
        if spec.attribute == "i" or spec.statistic == "percentile":
            thresholds[spec.name] = [v for v, _ in spec.numbers]
        else:
            thresholds[spec.name] = [length_to_crs_units(f"{v}{u}" if u else v, z, name=spec.name)
                                     for v, u in spec.numbers]
    cell = length_to_crs_units(settings.cell_size, xy, name="cell size")
    classes = None if settings.classes is None else tuple(int(c) for c in settings.classes)
    return _Run(cell, tuple(specs), thresholds, LAYER_HEIGHT_M / z.metres, classes, settings.returns,
                length_to_crs_units(settings.buffer, xy, name="buffer"), str(out), crs.to_wkt(), z.short,
                (cell * xy.metres) ** 2)


def _selected(pts: dict, run: _Run) -> np.ndarray:
    cls = pts["classification"]
    keep = ~np.isin(cls, NOISE_CLASSES) if run.classes is None else np.isin(cls, run.classes)
    if run.returns == "first":
        keep &= pts["return_number"] <= 1
    elif run.returns == "last":
        keep &= pts["return_number"] >= pts["number_of_returns"]
    return keep


def tile_metrics(own: dict, neighbours: list, grid, run: _Run) -> tuple[dict, dict]:
    """(metric name -> 2-D float array on ``grid``, counts) from a tile's points and its neighbours' (dicts of
    STRIP_FIELDS arrays, withheld points left out)."""
    allp = {k: np.concatenate([own[k], *(p[k] for p in neighbours)]) for k in STRIP_FIELDS}
    flat = cell_index(grid, allp["x"], allp["y"])
    use = (flat >= 0) & _selected(allp, run)
    hag, inside = None, None
    if needs_heights(run.specs):
        g = np.isin(allp["classification"], GROUND_CLASSES)
        if not g.any():
            raise DataFileError("no ground (class 2 or 9) points in the tile or its buffer, so no heights above "
                                f"ground for {', '.join(s.name for s in run.specs if s.on_heights)}",
                                hint="Classify ground first (gistools ground)")
        vertex = np.full(len(g), -1, np.int64)
        vertex[g] = np.arange(int(np.count_nonzero(g)))  # a ground point is a vertex of the TIN: no search for it
        hag, inside = height_above_ground(allp["x"][use], allp["y"][use], allp["z"][use], allp["x"][g], allp["y"][g],
                                          allp["z"][g], vertex=vertex[use])
    values = cell_metrics(flat[use], grid.width * grid.height, run.specs, z=allp["z"][use],
                          intensity=allp["intensity"][use], hag=hag, first=allp["return_number"][use] <= 1,
                          thresholds=run.thresholds, cell_area_m2=run.cell_area_m2, layer=run.layer)
    counts = {"points_used": int(np.count_nonzero(use)),
              "cells_with_points": int(np.count_nonzero(np.bincount(flat[use], minlength=grid.width * grid.height))),
              "heights_outside_tin": None if inside is None else int(np.count_nonzero(~inside))}
    return {k: v.reshape(grid.shape) for k, v in values.items()}, counts


def _metrics_tile(path: str, sources: list, crs_text, run: _Run) -> dict:
    """One tile's metric rasters."""
    info, grid, own, (arrays, counts) = gridded_tile(path, sources, crs_text, run.cell_size, run.crs_wkt,
                                                run.buffer if needs_heights(run.specs) else 0.0,
                                                lambda own, around, grid: tile_metrics(own, around, grid, run))
    outputs = {}
    for spec in run.specs:
        target = Path(run.out) / spec.name / f"{info.name}.tif"
        # no predictor: a cell's statistic is not a smooth surface, and without one the files are smaller (5-45 %
        # on the Levy block and the lidR surveys) and written 10-40 % faster than with the floating-point predictor
        write_raster(target, arrays[spec.name], grid, overwrite=True, tags={"GISTOOLS_PRODUCT": spec.name,
                     "GISTOOLS_Z_UNIT": run.z_unit}, description=_description(spec, run.z_unit), predictor=1)
        outputs[spec.name] = str(target)
    return {"outputs": outputs, "points": int(len(own["x"])), "neighbours": [nb for _k, nb, _s in sources], **counts}


def _description(spec: MetricSpec, z_unit: str) -> str:
    if spec.statistic == "density":
        return "points per square metre"
    if spec.statistic in ("count", "above", "cover", "fuel", "fhd", "vci", "cv") or spec.attribute == "i":
        return spec.name
    return f"{spec.name} ({z_unit})"



@shared_sections
def metrics_from_tiles(inputs, out, settings: MetricsSettings | None = None, *, jobs: int | str = "auto",
                       scheduler: str | None = None, overwrite: bool = False,
                       progress: ProgressCallback | None = None) -> dict:
    """Cell metrics (point count, density, height statistics, cover, ...) of the tiles of ``inputs``:
    ``gistools metrics``.

    Writes ``out/<metric>/<tile>.tif``, the mosaics ``out/<metric>.vrt`` and ``out/report.json``; cells without points
    are nodata. A tile whose every metric exists is kept unless ``overwrite``; a tile that fails is reported and the
    others go on.

    Parameters
    ----------
    {tiles_in}
    settings : MetricsSettings, optional
        The options (``cell_size`` as text with its unit or a number in CRS units, ``metrics``, ``normalized``,
        ``classes``, ``returns``, ...). None: the defaults.
    {tiles_run}

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, skipped, failed), ``metrics``,
        ``tiles``.

    Raises
    ------
    InputError
        An option is not valid (an unknown metric, ...), or ``inputs`` holds no tile.
    {tiles_raise_rest}

    Examples
    --------
    >>> from gistools import MetricsSettings, metrics_from_tiles
    >>> report = metrics_from_tiles("sample_tiles", "metrics", MetricsSettings(cell_size="10ft"))  # doctest: +SKIP
    >>> report["metrics"]  # doctest: +SKIP
    ['count', 'density', 'z_min', 'z_max', 'z_mean', 'z_sd', 'z_p95']
    """
    settings = settings or MetricsSettings()
    paths, override = batch_inputs(inputs, settings, jobs, scheduler)
    out = output_folder(out)
    with claim_output(out, "gistools metrics"):
        return raise_if_every_tile_failed(_metrics_in(paths, out, settings, override, jobs, scheduler, overwrite,
                                                      progress))


def _metrics_in(paths, out: Path, settings: MetricsSettings, override, jobs, scheduler, overwrite, progress) -> dict:
    started = time.time()
    states, infos = read_headers(paths, override, RasterTileState)
    run = None
    if infos:
        run = _run(settings, next(iter(infos.values())), common_crs(list(infos.values())), out)
        todo, on_done = marked_todo(infos, states, run, out, "gistools metrics",
                                    lambda name: {s.name: out / s.name / f"{name}.tif" for s in run.specs}, RASTER_FOUND,
                                    overwrite)

        # without heights above ground a tile needs only the neighbours' points in its own cells (its grid snapped
        # out to the lattice): where tile edges lie on the lattice, no neighbour's (nor pass 1's reads)
        reach = None if needs_heights(run.specs) else {n: snapped_grid(i.bounds, run.cell_size).bounds
                                                       for n, i in infos.items()}
        buffered_passes(todo, infos, states, buffer=max(run.buffer, run.cell_size) if reach is None else run.cell_size,
                        crs_text=settings.crs, out=out, jobs=jobs, scheduler=scheduler, progress=progress,
                        tile_fn=_metrics_tile,
                        tile_args=lambda n, sources: (str(infos[n].path), sources, settings.crs, run), on_done=on_done,
                        verb="done", tag="metrics", reach=reach)
    return _report(out, settings, run, infos, states, _mosaics(out, run, states), started)


def _mosaics(out: Path, run: _Run | None, states: dict) -> dict:
    """A VRT per metric over the tiles that are ok or kept."""
    mosaics = {}
    for spec in run.specs if run is not None else ():
        tifs = [Path(st.outputs[spec.name]) for st in states.values()
                if st.status in ("ok", "skipped") and spec.name in st.outputs]
        if tifs:
            mosaics[spec.name] = str(write_vrt(out / f"{spec.name}.vrt", sorted(tifs)))
    return mosaics


def _report(out, settings: MetricsSettings, run: _Run | None, infos: dict, states: dict, mosaics: dict,
            started) -> dict:
    first = next(iter(infos.values()), None)
    units = None if run is None else {"cell_size": run.cell_size, "buffer": run.buffer, "thresholds": run.thresholds,
                                      "horizontal_unit": first.unit.name, "vertical_unit": first.z_unit.name,
                                      "layer_height": run.layer}
    return write_batch_report(out, "gistools metrics", crs_label(first.crs) if first else None, settings, states,
                              started, metrics=[s.name for s in run.specs] if run else [], units=units, mosaics=mosaics)
