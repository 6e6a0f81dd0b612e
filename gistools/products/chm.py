"""Canopy height models of LAS/LAZ tiles (``gistools chm``, ``gistools:chm``): ``OUT/chm/<tile>.tif``, ``OUT/chm.vrt``,
report.json with the pits left in each tile.

Each tile is read with its neighbours' points (engine.buffered): first returns get their height above the TIN of the
ground of the tile and its neighbours (lidar.normalize), and the CHM's TINs see the points across the tile edges.
Methods: ``lidar.chm``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..errors import DataFileError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..io.outdir import claim_output
from ..io.points import common_crs, crs_label
from ..io.raster import write_raster, write_vrt
from ..lidar.accumulate import NOISE_CLASSES
from ..lidar.chm import CHM_METHODS, auto_edge, chm_p2r, chm_pitfree, chm_tin, nominal_spacing, pits
from ..lidar.normalize import height_above_ground
from ..parameters import check_all, default_for, option
from ..parameters.lidar import COMMAND_DEFAULTS, check_method
from ..progress import ProgressCallback
from ..units import length_to_crs_units
from ..validation import check_length
from ..engine.buffered import (STRIP_FIELDS, TileState, batch_inputs, buffered_passes, gridded_tile, marked_todo, read_headers,
                               write_batch_report)

__all__ = ["ChmSettings", "chm_from_tiles", "CHM_METHODS", "PIT_DEPTH", "survey_spacing"]

GROUND_CLASSES = (2, 9)
PIT_DEPTH = "1m"  # a pit: a cell more than this below all 8 neighbours (counted in report.json)
AUTO = "auto"  # a max_edge from the first returns' spacing (lidar.chm.auto_edge)


def _lengths(name: str) -> tuple:
    return tuple(default_for(name).split(","))


@dataclass(frozen=True)
class ChmSettings:
    """Parameters of ``gistools chm`` (declared in gistools.parameters.lidar: names, defaults, help). ``method``:
    p2r, pitfree or tin. ``thresholds``, ``threshold_step`` and ``max_edge``: pitfree's height thresholds (those
    given, then one every step up to the highest return; step "0": only those given) and its triangle edge limits
    (the first layer's, then the upper layers'; "0" = no limit; "auto": 4 nominal spacings of the tiles' first
    returns, from their headers, ``survey_spacing``). The defaults (0, 2, 4, ... m; 0, auto) leave no pit on the
    synthetic conifer stand of tests/test_chm.py, where lidR's (0, 2, 5, 10, 15 m; 0, 1 m:
    ``--thresholds 0m,2m,5m,10m,15m --threshold-step 0 --max-edge 0,1m``) leave some; docs/commands/chm.md gives
    the figures on real stands. ``tin_max_edge``: the tin method's limit. ``buffer``: how far the neighbours' points
    are read. Lengths take a unit or are in the tiles' CRS units."""

    cell_size: str | float = COMMAND_DEFAULTS["chm"]["cell_size"]
    method: str = default_for("chm_method")
    thresholds: tuple = _lengths("thresholds")
    threshold_step: str | float = default_for("threshold_step")
    max_edge: tuple = _lengths("max_edge")
    tin_max_edge: str | float = default_for("tin_max_edge")
    buffer: str | float = COMMAND_DEFAULTS["chm"]["buffer"]
    crs: str | None = None

    def validate(self) -> None:
        """Every field checked against its declaration, then pitfree's lists."""
        check_method("chm_method", self.method)
        check_all(self)  # every field with a declaration of its name
        if not self.thresholds:
            raise InputError(f"{option('thresholds')}: give at least one height",
                             hint=f"e.g. {option('thresholds', ('0m', '2m', '5m', '10m', '15m'))}")
        for t in self.thresholds:
            check_length(t, "thresholds", allow_equal=True, example="0m,2m,5m,10m,15m")
        if len(self.max_edge) != 2:
            raise InputError(f"{option('max_edge', tuple(self.max_edge))}: give two lengths (the first layer's, "
                             "the upper layers')", hint=f"e.g. {option('max_edge', ('0', '1m'))}")
        for e in self.max_edge:
            if str(e).strip().lower() != AUTO:
                check_length(e, "max_edge", allow_equal=True, example="0,1m")


@dataclass(frozen=True)
class _Run:
    method: str
    cell_size: float
    thresholds: tuple
    step: float | None
    max_edges: tuple
    tin_max_edge: float | None
    buffer: float
    pit_depth: float
    out: str
    crs_wkt: str
    z_unit: str


def survey_spacing(infos) -> float:
    """The nominal spacing of the tiles' first returns, in their CRS units, from their headers: the area of their
    boxes over their first returns (all their points where a header does not count them by return)."""
    area = sum(max(i.bounds[2] - i.bounds[0], 0.0) * max(i.bounds[3] - i.bounds[1], 0.0) for i in infos)
    first = sum(int(i.points_by_return[0]) if i.points_by_return and i.points_by_return[0] else int(i.point_count)
                for i in infos)
    return nominal_spacing(first, area)


def _run(s: ChmSettings, info, crs, out: Path, spacing: float) -> _Run:
    xy, z = info.unit, info.z_unit

    def edge(v, name):
        if str(v).strip().lower() == AUTO:
            return auto_edge(spacing) if math.isfinite(spacing) else None
        e = length_to_crs_units(v, xy, name=name)
        return None if e == 0 else e

    return _Run(s.method, length_to_crs_units(s.cell_size, xy, name="cell size"),
                tuple(length_to_crs_units(t, z, name="threshold") for t in s.thresholds),
                length_to_crs_units(s.threshold_step, z, name="threshold step") or None,
                tuple(edge(e, "max edge") for e in s.max_edge), edge(s.tin_max_edge, "tin max edge"),
                length_to_crs_units(s.buffer, xy, name="buffer"), length_to_crs_units(PIT_DEPTH, z, name="pit depth"),
                str(out), crs.to_wkt(), z.short)


def tile_chm(own: dict, neighbours: list, grid, run: _Run) -> np.ndarray:
    """The CHM of a tile's grid from its points and its neighbours' (dicts of STRIP_FIELDS arrays)."""
    allp = {k: np.concatenate([own[k], *(p[k] for p in neighbours)]) for k in STRIP_FIELDS}
    first = (allp["return_number"] <= 1) & ~np.isin(allp["classification"], NOISE_CLASSES)
    g = np.isin(allp["classification"], GROUND_CLASSES)
    if not g.any():
        raise DataFileError("no ground (class 2 or 9) points in the tile or its buffer, so no heights above ground",
                            hint="Classify ground first (gistools ground)")
    x, y = allp["x"][first], allp["y"][first]
    vertex = np.full(len(g), -1, np.int64)
    vertex[g] = np.arange(int(np.count_nonzero(g)))  # a ground point is a vertex of the TIN: no search for it
    h, _inside = height_above_ground(x, y, allp["z"][first], allp["x"][g], allp["y"][g], allp["z"][g],
                                     vertex=vertex[first])
    if run.method == "p2r":
        return chm_p2r(x, y, h, grid)
    if run.method == "tin":
        return chm_tin(x, y, h, grid, max_edge=run.tin_max_edge)
    return chm_pitfree(x, y, h, grid, thresholds=run.thresholds, max_edges=run.max_edges, step=run.step)


def _chm_tile(path: str, sources: list, crs_text, run: _Run) -> dict:
    info, grid, _own, chm = gridded_tile(path, sources, crs_text, run.cell_size, run.crs_wkt, run.buffer,
                                   lambda own, around, grid: tile_chm(own, around, grid, run))
    target = Path(run.out) / "chm" / f"{info.name}.tif"
    write_raster(target, chm, grid, overwrite=True, units=run.z_unit, tags={"GISTOOLS_PRODUCT": "chm",
                 "GISTOOLS_CHM_METHOD": run.method}, description=f"canopy height ({run.z_unit})")
    return {"output": str(target), "pits": int(pits(chm, run.pit_depth).sum()), "cells": int(np.isfinite(chm).sum()),
            "neighbours": [nb for _k, nb, _s in sources]}


@dataclass
class _TileState(TileState):
    output: str | None = None
    pits: int = 0
    cells: int = 0


@shared_sections
def chm_from_tiles(inputs, out, settings: ChmSettings | None = None, *, jobs: int | str = "auto", scheduler: str | None = None,
                   overwrite: bool = False, progress: ProgressCallback | None = None) -> dict:
    """A canopy height model GeoTIFF per tile of ``inputs``: ``gistools chm``.

    Writes ``out/chm/<tile>.tif``, the mosaic ``out/chm.vrt`` and ``out/report.json`` (cells and pits per tile); heights
    above ground in the vertical unit. Tiles whose output exists are kept unless ``overwrite``; a tile that fails is
    reported and the others go on.

    Parameters
    ----------
    {tiles_in}
    settings : ChmSettings, optional
        The options (``cell_size``, ``method`` p2r, pitfree or tin, ``thresholds``, ``max_edge``, ...; lengths as text
        with their unit or a number in CRS units). None: the defaults.
    {tiles_run}

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, skipped, failed), ``tiles``.

    {tiles_raise}

    Examples
    --------
    >>> from gistools import ChmSettings, chm_from_tiles
    >>> chm_from_tiles("sample_tiles", "chm", ChmSettings(method="pitfree"))["counts"]  # doctest: +SKIP
    {'ok': 4, 'skipped': 0, 'failed': 0}
    """
    settings = settings or ChmSettings()
    paths, override = batch_inputs(inputs, settings, jobs, scheduler)
    out = output_folder(out)
    with claim_output(out, "gistools chm"):
        return raise_if_every_tile_failed(_chm_in(paths, out, settings, override, jobs, scheduler, overwrite, progress))


# the most pit-free layers a tile may take (a TIN of the points above each threshold): 500 layers of 0.2 m reach
# 100 m, past the tallest trees; the default (a layer every 2 m) makes about 50
MAX_LAYERS = 500


def check_layers(run: _Run, infos: dict, settings: ChmSettings) -> None:
    """Refuse, before the first tile, a threshold step that makes more than MAX_LAYERS pit-free layers on these
    tiles (their headers' height range bounds the heights above ground)."""
    if run.method != "pitfree" or not run.step or not infos:
        return
    span = max(i.z_range[1] - i.z_range[0] for i in infos.values())
    layers = len(run.thresholds) + max(0, math.ceil((span - max(run.thresholds)) / run.step))
    if layers > MAX_LAYERS:
        raise InputError(
            f"{option('threshold_step', settings.threshold_step)} ({run.step:g} {run.z_unit}) makes up to {layers:,} "
            f"pit-free layers over the tiles' {span:,.6g} {run.z_unit} of height range, a TIN each; at most "
            f"{MAX_LAYERS} are taken", hint=f"Give a larger step, e.g. {option('threshold_step', '2m')}")


def _chm_in(paths, out: Path, settings: ChmSettings, override, jobs, scheduler, overwrite, progress) -> dict:
    started = time.time()
    states, infos = read_headers(paths, override, _TileState)
    run, spacing = None, math.nan
    if infos:  # the spacing is the report's; the run (what a resumed tile must match) holds the edges it gives
        spacing = survey_spacing(infos.values())
        run = _run(settings, next(iter(infos.values())), common_crs(list(infos.values())), out, spacing)
        check_layers(run, infos, settings)
        todo, on_done = marked_todo(infos, states, run, out, "gistools chm",
                                    lambda name: {"chm": out / "chm" / f"{name}.tif"}, ("pits", "cells", "neighbours"),
                                    overwrite, single="chm")
        buffered_passes(todo, infos, states, buffer=run.buffer, crs_text=settings.crs, out=out, jobs=jobs,
                        scheduler=scheduler, progress=progress, tile_fn=_chm_tile,
                        tile_args=lambda n, sources: (str(infos[n].path), sources, settings.crs, run), on_done=on_done,
                        verb="done", tag="chm")
    tifs = sorted(Path(st.output) for st in states.values() if st.status in ("ok", "skipped") and st.output)
    first = next(iter(infos.values()), None)
    units = None if run is None else {"cell_size": run.cell_size, "thresholds": list(run.thresholds),
                                      "threshold_step": run.step, "max_edges": list(run.max_edges),
                                      "first_return_spacing": spacing if math.isfinite(spacing) else None,
                                      "pit_depth": run.pit_depth, "vertical_unit": run.z_unit}
    return write_batch_report(out, "gistools chm", crs_label(first.crs) if first else None, settings, states, started,
                              units=units, mosaic=str(write_vrt(out / "chm.vrt", tifs)) if tifs else None,
                              pits=sum(st.pits for st in states.values() if st.status in ("ok", "skipped")))
