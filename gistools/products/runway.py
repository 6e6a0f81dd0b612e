"""Runway earthworks (dissertation ch. 7): survey + ICAO code to design model, sections, areas and mass haul.

``gistools runway`` and the QGIS algorithm call :func:`runway_earthworks`; :func:`compute_earthworks`
does the work in memory (no files) for scripts. Lengths in CRS units (metres: the ICAO template is
in metres, and a feet CRS is refused unless its lengths are converted first).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import shapely
from scipy.interpolate import LinearNDInterpolator

from ..engine.record import write_folder_report
from ..errors import InputError
from ..engine.resume import rerun_kept, run_record
from ..io.outdir import claim_output, output_folder
from ..grid import evaluate_on_grid, snapped_grid
from ..io.points import chosen_crs
from ..io.raster import atomic_path, write_raster
from ..io.vector import write_layers
from ..progress import ProgressCallback, report
from ..runway.earthworks import (balance_points, brueckner, compensate, dissertation_strip_areas, overhaul, section_areas,
                                 station_volumes)
from ..runway.icao import template as make_template
from ..io.survey import read_survey
from ..runway.survey import SurveyChecks, check_survey, estimate_spacing, fit_frame
from ..parameters import check_all, option
from ..units import METRE, LinearUnit, horizontal_unit, length_to_crs_units

__all__ = ["RunwaySettings", "compute_earthworks", "runway_earthworks", "runway_metres", "area_diagram",
           "brueckner_diagram"]


def runway_metres(value, name: str) -> float:
    """A length of parameter ``name`` ("10m", "30ft", "32.8ftUS", or a bare number in metres) in metres: the ICAO
    template and the survey's CRS are in metres."""
    return length_to_crs_units(value, LinearUnit("metre", METRE), name=option(name))


@dataclass(frozen=True)
class RunwaySettings:
    """code / runway_type / template: the cross section (gistools.runway.icao). spacing: stations and lateral grid
    (None: s = sqrt(A / N) of the survey). origin: chainage 0 at the "low", "high" or "first" light.
    profile_window: running mean of this many light heights for the design grade (1: the lights' own).
    f_cut / f_fill: swell of cut and compaction of fill (1.0: none). free_haul: metres (None: no overhaul).
    area_method: "exact" (signed, split where ground crosses design) or "dissertation" (unsigned hull + Heron)."""

    code: str = "4E"
    runway_type: str = "precision"
    template: str = "icao"
    spacing: float | None = None
    origin: str = "low"
    profile_window: int = 1
    f_cut: float = 1.0
    f_fill: float = 1.0
    free_haul: float | None = None
    area_method: str = "exact"
    checks: SurveyChecks = field(default_factory=SurveyChecks)

    def validate(self) -> None:
        """Every setting checked against its declaration (gistools.parameters.runway) before anything is read; the
        code by the ICAO template (which lists the valid ones)."""
        check_all(self, ("runway_type", "template", "origin", "profile_window", "f_cut", "f_fill", "area_method"))
        if int(self.profile_window) % 2 == 0:
            raise InputError(f"{option('profile_window')} {self.profile_window} must be an odd number >= 1",
                             hint=f"e.g. {option('profile_window', '5')}")


@dataclass
class Earthworks:
    points: pd.DataFrame
    removed: pd.DataFrame
    frame: object
    template: object
    spacing: float
    stations: np.ndarray
    offsets: np.ndarray
    ground: np.ndarray
    design: np.ndarray
    strip_cut: np.ndarray
    strip_fill: np.ndarray
    area_cut: np.ndarray
    area_fill: np.ndarray
    area_net: np.ndarray
    brueckner: np.ndarray
    balance: np.ndarray
    totals: dict


def _lateral_grid(s: float, tpl) -> np.ndarray:
    half = tpl.half_width
    ks = np.arange(0, half + 1e-9, s)
    ys = np.concatenate([ks, -ks, np.asarray(tpl.breakpoints), -np.asarray(tpl.breakpoints)])
    ys = ys[np.abs(ys) <= half + 1e-9]
    return np.unique(np.round(ys, 9))


def _check_ground_spans_strip(chain: np.ndarray, offset: np.ndarray, length: float, strip_width: float) -> None:
    """Refuse ground points (type 2) that cannot make a ground model of the strip: fewer than 3, or all along one
    line (their offsets from the centre line span less than a tenth of the strip's width)."""
    if len(chain) < 3:
        raise InputError(f"{len(chain)} ground point(s) (type 2); the ground model needs at least 3 across the strip",
                         hint="Give the survey's ground points with type 2")
    pts = np.column_stack([chain, offset])
    sv = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    across = float(offset.max() - offset.min())
    if sv[1] <= 1e-6 * max(sv[0], length, 1.0) or across < 0.1 * strip_width:
        raise InputError(f"the ground points (type 2) lie on one line: their offsets from the centre line span "
                         f"{across:.2f} m of the {strip_width:.0f} m strip, so they give no ground surface across it",
                         hint="Give ground points across the runway strip, not only along one line")


def compute_earthworks(points: pd.DataFrame, settings: RunwaySettings | None = None,
                       progress: ProgressCallback | None = None) -> Earthworks:
    """All the steps in memory on survey points (id, type, x, y, z)."""
    st = settings or RunwaySettings()
    st.validate()
    tpl = make_template(st.code, st.runway_type, st.template)
    report(progress, 0.05, "checks")
    kept, removed = check_survey(points, st.checks)
    lights = kept.loc[kept["type"] == 1, ["x", "y"]].to_numpy(np.float64)
    if len(np.unique(lights, axis=0)) < 2:
        raise InputError(f"the centre-line lights (type 1) lie at {len(np.unique(lights, axis=0))} distinct position(s); "
                         "the centre line needs at least 2", hint="Check the survey's x, y of the type 1 points")
    frame = fit_frame(kept, origin=st.origin, profile_window=st.profile_window)
    ch, off = frame.local(kept["x"].to_numpy(), kept["y"].to_numpy())
    kept = kept.assign(chainage=ch, offset=off)
    ground_pts = kept[kept["type"] == 2]
    _check_ground_spans_strip(ground_pts["chainage"].to_numpy(), ground_pts["offset"].to_numpy(), frame.line.length,
                              2 * tpl.half_width)
    s = float(st.spacing) if st.spacing else estimate_spacing(ground_pts["chainage"].to_numpy(), ground_pts["offset"].to_numpy())
    if not s > 0:
        raise InputError(f"{option('spacing')} {s} must be positive", hint=f"e.g. {option('spacing', '10m')}")
    length = frame.line.length
    n = int(np.floor(length / s + 1e-9))
    if n > 1_000_000:
        raise InputError(f"spacing {s:g} m over {length:,.1f} m gives {n + 1:,} stations",
                         hint=f"Give a larger {option('spacing')}")
    stations = np.arange(n + 1) * s
    if length - stations[-1] > 1e-6 * s:
        stations = np.append(stations, length)
    offsets = _lateral_grid(s, tpl)
    report(progress, 0.3, "ground model")
    # local coordinates snapped to 1 micrometre: a rotation leaves points of one survey line 1e-9 m apart,
    # and the TIN would otherwise close such a jagged edge with slivers that skip the middle point
    gx, gy = np.round(ground_pts["chainage"].to_numpy(), 6), np.round(ground_pts["offset"].to_numpy(), 6)
    tin = LinearNDInterpolator(np.column_stack([gx, gy]), ground_pts["z"].to_numpy())
    X, Y = np.meshgrid(stations, offsets, indexing="ij")
    ground = tin(X, Y)
    gap = np.isnan(ground)
    if gap.any():  # just outside the survey's hull (an edge of the strip): the nearest point within s / 2
        from scipy.spatial import cKDTree

        dist, idx = cKDTree(np.column_stack([gx, gy])).query(np.column_stack([X[gap], Y[gap]]))
        near = dist <= s / 2
        filled = np.full(dist.shape, np.nan)
        filled[near] = ground_pts["z"].to_numpy()[idx[near]]
        ground[gap] = filled
    design = frame.z_centre(X) - tpl.drop(Y)
    kept = kept.assign(design=frame.z_centre(ch) - tpl.drop(off))
    kept["ground_minus_design"] = kept["z"] - kept["design"]
    report(progress, 0.6, "sections")
    d = ground - design
    cut, fill, a_cut, a_fill = section_areas(offsets, d)
    if st.area_method == "dissertation":
        y0 = np.broadcast_to(offsets[:-1], cut.shape)
        y1 = np.broadcast_to(offsets[1:], cut.shape)
        unsigned = dissertation_strip_areas(y0, y1, np.nan_to_num(ground[:, :-1]), np.nan_to_num(ground[:, 1:]),
                                            design[:, :-1], design[:, 1:])
        unsigned[np.isnan(ground[:, :-1]) | np.isnan(ground[:, 1:])] = 0
        cut, fill = unsigned, np.zeros_like(unsigned)  # the dissertation calls every area cut
        a_cut, a_fill = cut.sum(axis=1), fill.sum(axis=1)
    net = compensate(a_cut, a_fill, st.f_cut, st.f_fill)
    b = brueckner(stations, net)
    v_cut, v_fill = station_volumes(stations, net)
    dx = np.diff(stations)
    transverse = np.minimum(st.f_cut * a_cut, st.f_fill * a_fill)
    totals = {
        "cut": float(v_cut.sum()), "fill": float(v_fill.sum()), "net": float(v_cut.sum() - v_fill.sum()),
        "gross_cut": float(np.sum(dx * (a_cut[:-1] + a_cut[1:]) / 2)),
        "gross_fill": float(np.sum(dx * (a_fill[:-1] + a_fill[1:]) / 2)),
        "transverse": float(np.sum(dx * (transverse[:-1] + transverse[1:]) / 2)),
        "uncovered_cells": int(np.isnan(ground).sum()),
    }
    if st.free_haul is not None:
        totals.update(overhaul(stations, b, st.free_haul))
    report(progress, 0.7, "done computing")
    return Earthworks(kept, removed, frame, tpl, s, stations, offsets, ground, design, cut, fill, a_cut, a_fill, net, b,
                      balance_points(stations, b), totals)


def area_diagram(ew: Earthworks, title: str = ""):
    """The area diagram (matplotlib Figure): cut areas up, fill areas down, the net area after transverse
    compensation as a line, against chainage."""
    from ..plot import new_figure

    fig = new_figure((11, 4.5))
    ax = fig.subplots()
    ax.plot(ew.stations, ew.area_net, color="k", lw=1, label="net (after transverse compensation)")
    ax.fill_between(ew.stations, ew.area_cut, 0, color="#c0504d", alpha=0.5, label="cut")
    ax.fill_between(ew.stations, -ew.area_fill, 0, color="#4f81bd", alpha=0.5, label="fill")
    ax.axhline(0, color="0.4", lw=0.6)
    ax.set_xlabel("chainage (m)")
    ax.set_ylabel("section area (m²): cut +, fill −")
    ax.set_title(f"Area diagram - {title}")
    ax.legend(loc="upper right")
    return fig


def brueckner_diagram(ew: Earthworks, title: str = ""):
    """The Brueckner (mass-haul) diagram (matplotlib Figure), balance points marked."""
    from ..plot import new_figure

    fig = new_figure((11, 4.5))
    ax = fig.subplots()
    ax.plot(ew.stations, ew.brueckner, color="k", lw=1.2, label="Brückner (cumulative volume)")
    ax.plot(ew.balance, np.interp(ew.balance, ew.stations, ew.brueckner), "o", color="#c0504d", label="balance points")
    ax.axhline(0, color="0.4", lw=0.6, label="balance line")
    ax.set_xlabel("chainage (m)")
    ax.set_ylabel("cumulative volume (m³): rising = cut")
    ax.set_title(f"Brückner diagram - {title}")
    ax.legend(loc="best")
    return fig


def _diagrams(ew: Earthworks, out: Path, title: str) -> dict:
    """Write the area and Brueckner diagrams as PNG and PDF."""
    paths = {}
    for name, make in (("area_diagram", area_diagram), ("brueckner", brueckner_diagram)):
        fig = make(ew, title)
        for ext in ("png", "pdf"):
            target = out / f"{name}.{ext}"
            with atomic_path(target, overwrite=True) as tmp:
                fig.savefig(tmp, format=ext, dpi=120)
            paths[f"{name}_{ext}"] = str(target)
    return paths


def _design_raster(ew: Earthworks, crs, cell: float):
    line = ew.frame.line
    half = ew.template.half_width
    region = line.buffer(half, cap_style="flat")
    grid = snapped_grid(region.bounds, cell, crs)
    shapely.prepare(region)

    def design(X, Y):
        block = np.full(X.shape, np.nan)
        inside = shapely.contains_xy(region, X, Y)
        if inside.any():
            ch, off = ew.frame.local(X[inside], Y[inside])
            block[inside] = ew.frame.z_centre(ch) - ew.template.drop(off)
        return block

    return evaluate_on_grid(grid, design), grid


def runway_earthworks(source, out, settings: RunwaySettings | None = None, *, crs=None, overwrite: bool = False,
                      progress: ProgressCallback | None = None, fields: dict | None = None) -> dict:
    """Cut and fill of a runway from a survey of its ground: ``gistools runway``.

    Fits the runway's frame to the survey, lays the ICAO template of its reference code on it and computes the volumes
    station by station, the mass haul (Brueckner) diagram and the overhaul. Writes under ``out``: ``runway.gpkg``,
    ``design_surface.tif``, ``sections.csv``, the diagrams and ``report.json`` (volumes in m3, lengths in m).

    Parameters
    ----------
    source : str or path
        The survey: a CSV or point layer with id, type, x, y, z (metres).
    out : str or path
        Output folder, made when missing.
    settings : RunwaySettings, optional
        The options (``code`` e.g. ``"4E"``, ``runway_type``, ``template``, ``spacing``, ``swell``, ``free_haul``,
        ...; lengths as text with their unit or a number in metres). None: the defaults.
    crs : str, optional
        The survey's CRS (e.g. ``"EPSG:3003"``) when the file carries none; it must be in metres.
    overwrite : bool
        Replace a run already in ``out``.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.
    fields : dict, optional
        ``{field: column}`` where the table names the fields otherwise (id, type, x, y, z).

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``cut``, ``fill``, ``net`` (m3), ``length`` (m),
        ``stations``, ``balance_points``, ``units``, ``outputs``.

    Raises
    ------
    InputError
        An option or the survey is not valid, it has no CRS, or its CRS is not in metres.
    OutputExistsError
        ``out`` holds another command's outputs, or a run whose record does not say its settings (and
        ``overwrite`` is False); a run of other settings is refused naming the first that differs (InputError).

    Examples
    --------
    >>> from gistools import RunwaySettings, runway_earthworks
    >>> report = runway_earthworks("survey.csv", "orio", RunwaySettings(code="4E"), crs="EPSG:3003")  # doctest: +SKIP
    >>> report["units"]["cut"], report["cut"] > 0  # doctest: +SKIP
    ('m3', True)
    """
    started = time.time()
    st = settings or RunwaySettings()
    st.validate()
    out = output_folder(out)
    make_template(st.code, st.runway_type, st.template)  # refuse an unknown code before reading anything
    now = {**{k: v for k, v in vars(st).items() if k != "checks"}, **vars(st.checks), "crs": crs, "fields": fields}
    kept = rerun_kept(out, "gistools runway", now, source, overwrite, started)
    if kept is not None:
        return kept
    points, file_crs = read_survey(source, fields)
    crs_obj = chosen_crs(crs, file_crs, "the survey", source, "Orio al Serio: EPSG:3003")
    unit = horizontal_unit(crs_obj)
    if abs(unit.metres - 1.0) > 1e-12:
        raise InputError(f"the CRS is in {unit.name}; the ICAO template is in metres", path=source,
                         hint="Reproject the survey to a metre CRS first")
    try:
        ew = compute_earthworks(points, st, progress=progress)
    except InputError as err:
        if err.path is not None:
            raise
        raise InputError(str(err), path=source) from None  # the survey's degenerate content: name the file
    report(progress, 0.75, "writing")
    with claim_output(out, "gistools runway"):
        rep = _write_runway(ew, points, crs_obj, out, st, started, (now, source))
    report(progress, 1.0, "done")
    return rep


def _write_runway(ew, points, crs_obj, out: Path, st, started, made: tuple) -> dict:
    import geopandas as gpd

    P = ew.points
    removed = ew.removed.merge(points[["id", "x", "y", "z", "line"]].drop_duplicates("id"), on="id", how="left")
    sx0, sy0 = ew.frame.world(ew.stations, np.full(len(ew.stations), -ew.template.half_width))
    sx1, sy1 = ew.frame.world(ew.stations, np.full(len(ew.stations), ew.template.half_width))
    layers = {
        "points": gpd.GeoDataFrame(P, geometry=shapely.points(P["x"], P["y"], P["z"]), crs=crs_obj),
        "removed": gpd.GeoDataFrame(removed, geometry=shapely.points(removed["x"], removed["y"], removed["z"]), crs=crs_obj),
        "centre_line": gpd.GeoDataFrame({"length": [ew.frame.line.length], "bearing": [ew.frame.bearing]},
                                        geometry=[ew.frame.line], crs=crs_obj),
        "stations": gpd.GeoDataFrame({"chainage": ew.stations, "area_cut": ew.area_cut, "area_fill": ew.area_fill,
                                      "area_net": ew.area_net, "brueckner": ew.brueckner},
                                     geometry=shapely.linestrings(np.stack([np.column_stack([sx0, sy0]),
                                                                            np.column_stack([sx1, sy1])], axis=1)), crs=crs_obj),
    }
    write_layers(layers, out / "runway.gpkg", overwrite=True)
    cell = max(ew.spacing, 0.5)
    design_grid, grid = _design_raster(ew, crs_obj, cell)
    write_raster(out / "design_surface.tif", design_grid, grid, overwrite=True, units="m",
                 tags={"GISTOOLS_PRODUCT": "runway design surface", "GISTOOLS_CODE": ew.template.code},
                 description="design surface")
    i, j = np.meshgrid(np.arange(len(ew.stations)), np.arange(len(ew.offsets) - 1), indexing="ij")
    table = pd.DataFrame({
        "station": ew.stations[i.ravel()], "y0": ew.offsets[j.ravel()], "y1": ew.offsets[j.ravel() + 1],
        "ground0": ew.ground[i, j].ravel(), "ground1": ew.ground[i, j + 1].ravel(),
        "design0": ew.design[i, j].ravel(), "design1": ew.design[i, j + 1].ravel(),
        "cut": ew.strip_cut.ravel(), "fill": ew.strip_fill.ravel()})
    with atomic_path(out / "sections.csv", overwrite=True) as tmp:
        table.to_csv(tmp, index=False, float_format="%.4f")
    files = {"gpkg": str(out / "runway.gpkg"), "design_surface": str(out / "design_surface.tif"),
             "sections": str(out / "sections.csv")}
    files.update(_diagrams(ew, out, f"{ew.template.code} {ew.template.runway_type}, {ew.template.kind} template"))
    counts = ew.removed["reason"].value_counts().to_dict()
    rep = {
        "tool": "gistools runway",
        "code": ew.template.code,
        "runway_type": ew.template.runway_type,
        "template": ew.template.kind,
        "zones": [{"name": z.name, "outer_offset": z.outer, "slope": z.slope} for z in ew.template.zones],
        "crs": crs_obj.to_string(),
        "cut": ew.totals["cut"], "fill": ew.totals["fill"], "net": ew.totals["net"],
        "totals": ew.totals,
        "units": {"cut": "m3", "fill": "m3", "net": "m3", "length": "m", "spacing": "m", "haul_moment": "m3 x m",
                  "mean_haul_distance": "m", "overhaul": "m3 x m", "free_haul": "m", "bearing": "degrees from north"},
        "free_haul": st.free_haul,
        "balance_points": [float(v) for v in ew.balance],
        "stations": int(len(ew.stations)),
        "spacing": ew.spacing,
        "length": float(ew.frame.line.length),
        "bearing": ew.frame.bearing,
        "factors": {"cut": st.f_cut, "fill": st.f_fill},
        "area_method": st.area_method,
        "removed": {"duplicates": int(counts.get("duplicate", 0)), "renumbered": int(counts.get("renumbered", 0)),
                    "outliers": int(sum(v for k, v in counts.items() if k not in ("duplicate", "renumbered"))),
                    "by_reason": {k: int(v) for k, v in counts.items()}},
        "points": {"lights": int((ew.points["type"] == 1).sum()), "other": int((ew.points["type"] == 2).sum())},
        "outputs": files,
        "settings": dict(vars(st)),
        "made": run_record(*made, files),
    }
    rep["seconds"] = round(time.time() - started, 3)
    rep = write_folder_report(out, rep)
    return rep
