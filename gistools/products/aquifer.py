"""The aquifer model (dissertation ch. 8): layer contacts to cleaned TIN surfaces, walls, closed units,
thickness and volume. ``gistools aquifer model`` / ``query`` and the QGIS algorithms call these.

Everything is computed before anything is written, so bad input leaves no output; every file is
written atomically. Lengths take a unit ("0.5m") or are CRS units; volumes are cubic CRS units.
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyproj
import shapely

from ..engine.record import write_folder_report
from ..io.contacts import read_contacts
from ..aquifer.outliers import OutlierSettings, find_outliers, order_violations
from ..aquifer.surface import HEIGHT_METHODS, Surface, build_surface, densify, height_at, mask_outside, unique_edges
from ..aquifer.isopach import isopach
from ..aquifer.volume import common_footprint, overlay_volume, tin_integral
from ..aquifer.walls import unit_mesh
from ..io.meshes import write_obj, write_ply
from ..mesh import is_closed, match_rings
from ..errors import InputError
from ..engine.resume import rerun_kept, run_record
from ..io.outdir import claim_output, output_folder
from ..grid import cell_centres, evaluate_on_grid, snapped_grid
from ..io.raster import atomic_path, write_raster
from ..parameters import check_all, choices, option
from ..validation import check_count, check_length, check_number
from ..io.vector import check_crs, read_layer, write_layers
from ..progress import ProgressCallback, report
from ..units import horizontal_unit, length_to_crs_units

log = logging.getLogger(__name__)

__all__ = ["AquiferSettings", "aquifer_model", "aquifer_query", "load_model", "query_model", "unit_name"]


ORDERS = choices("order")  # declared in gistools.parameters.aquifer


@dataclass(frozen=True)
class AquiferSettings:
    """Parameters of the aquifer model. Lengths: "0.5m" or CRS units.

    Outlier rules (see gistools.aquifer.outliers): xy_tol, k, abs_thr, c, f_nn, order_tol.
    concave_ratio: clip each surface to shapely's concave hull of its points (0-1; None = convex,
    the dissertation's). n_per_edge: densified points per TIN edge (2 reproduces the dissertation's
    counts). cell_size: thickness rasters (None: about 500 cells across). matching: "3d" or "2d".
    mesh_format: "ply" or "obj". figures: draw the PNG figures (needs matplotlib). densify: also write
    the densified points (``densified_<layer>.csv``, the dissertation's NewPoints files); their count
    is always in the report. order: "stratigraphic" (a lower surface is never above the one above it: where the
    two TINs cross, as where a unit pinches out and its base has fewer boreholes than its top, the unit's
    thickness is 0, not negative; volumes, thickness rasters and queries follow) or "raw" (the TINs as they are).
    The crossing's area and volume are reported either way, as a quality figure.
    """

    xy_tol: str | float = "0.5m"
    k: int = 12
    abs_thr: str | float = "8m"
    c: float = 5.0
    f_nn: float = 5.0
    order_tol: str | float = "1m"
    concave_ratio: float | None = None
    n_per_edge: int = 2
    cell_size: str | float | None = None
    matching: str = "3d"
    mesh_format: str = "ply"
    figures: bool = True
    densify: bool = False
    order: str = "stratigraphic"

    def validate(self) -> None:
        """Every option checked against its declaration (gistools.parameters.aquifer) before anything is read or
        written."""
        check_all(self, ("xy_tol", "abs_thr", "order_tol", "concave_ratio", "n_per_edge", "matching", "mesh_format",
                         "order"))
        check_count(self.k, "k", minimum=3, example="12")
        check_number(self.c, "c", low=0, low_open=True, example="5")
        check_number(self.f_nn, "f_nn", low=0, low_open=True, example="5")
        if self.cell_size is not None:  # the parameter thickness_cell_size (cell_size is the rasters')
            check_length(self.cell_size, "cell_size", example="10m")


def unit_name(upper: str, lower: str) -> str:
    return f"{upper}/{lower}"


@dataclass
class Model:
    """What aquifer_model computes: cleaned points, flags, surfaces and per-unit results."""

    layers: list
    crs: pyproj.CRS
    points: pd.DataFrame
    flags: pd.DataFrame
    surfaces: dict
    units: dict = field(default_factory=dict)
    links: pd.DataFrame | None = None
    order: str = "stratigraphic"


def _nice(step: float) -> float:
    e = 10 ** np.floor(np.log10(step))
    for m in (1, 2, 5, 10):
        if step <= m * e:
            return float(m * e)
    return float(10 * e)


def _surfaces(points, layers, clip_polygon, concave_ratio) -> dict:
    """One TIN per layer; built on threads (Qhull releases the GIL), the result is the same as one by one."""
    from concurrent.futures import ThreadPoolExecutor

    def one(layer):
        g = points[points["layer"] == layer]
        s = build_surface(layer, g["id"].to_numpy(), g["x"].to_numpy(), g["y"].to_numpy(), g["z"].to_numpy())
        if concave_ratio is not None:
            s = mask_outside(s, shapely.concave_hull(shapely.multipoints(np.column_stack([s.x, s.y])), ratio=concave_ratio))
        if clip_polygon is not None:
            s = mask_outside(s, clip_polygon)
        return s

    if clip_polygon is not None:
        shapely.prepare(clip_polygon)  # once, before the threads share it
    with ThreadPoolExecutor(max_workers=min(len(layers), os.cpu_count() or 1)) as pool:
        return dict(zip(layers, pool.map(one, layers)))


def build_model(source, layers, *, crs=None, swap_xy=False, settings: AquiferSettings | None = None, clip=None,
                progress: ProgressCallback | None = None, fields: dict | None = None) -> Model:
    """Read, clean and triangulate (S0-S5); the in-memory model the outputs and queries use."""
    s = settings or AquiferSettings()
    s.validate()
    points, crs_obj = read_contacts(source, layers, crs=crs, swap_xy=swap_xy, fields=fields)
    unit = horizontal_unit(crs_obj)
    length = lambda name: length_to_crs_units(getattr(s, name), unit, name=option(name))  # noqa: E731
    osets = OutlierSettings(xy_tol=length("xy_tol"), k=int(s.k), abs_thr=length("abs_thr"), c=float(s.c),
                            f_nn=float(s.f_nn), order_tol=length("order_tol"))
    report(progress, 0.05, "outliers")
    kept, flags = find_outliers(points, layers, osets)
    report(progress, 0.2, "surfaces")
    clip_polygon = None
    if clip is not None:
        gdf = check_crs(read_layer(clip), crs_obj, str(clip), against="the contacts'", reproject=None)
        clip_polygon = shapely.union_all(gdf.geometry.to_numpy())
    surfaces = _surfaces(kept, layers, clip_polygon, s.concave_ratio)
    ov = order_violations(kept, surfaces, layers, osets.order_tol)
    if len(ov):
        flags = pd.concat([flags, ov], ignore_index=True)
    return Model(list(layers), crs_obj, kept, flags, surfaces, order=s.order)


def _links(model: Model, metric: str) -> pd.DataFrame:
    rows = []
    for a, b in zip(model.layers[:-1], model.layers[1:]):
        for p, q in ((a, b), (b, a)):
            sp, sq = model.surfaces[p], model.surfaces[q]
            rp, rq = sp.ring(), sq.ring()
            i, j, d = match_rings(sp.xyz[rp], sq.xyz[rq], metric)
            for ii, jj, dd in zip(i, j, d):
                pa, qb = rp[ii], rq[jj]
                rows.append((p, int(sp.ids[pa]), q, int(sq.ids[qb]), float(dd), sp.x[pa], sp.y[pa], sp.z[pa], sq.x[qb],
                             sq.y[qb], sq.z[qb]))
    return pd.DataFrame(rows, columns=["from_layer", "from_id", "to_layer", "to_id", "distance", "x0", "y0", "z0", "x1", "y1",
                                       "z1"])


def _thickness_grid(upper: Surface, lower: Surface, footprint, cell: float, crs):
    grid = snapped_grid(footprint.bounds, cell, crs)

    def thickness(X, Y):
        zu, _ = height_at(upper, X.ravel(), Y.ravel())
        zl, _ = height_at(lower, X.ravel(), Y.ravel())
        return (zu - zl).reshape(X.shape)

    return evaluate_on_grid(grid, thickness), grid


def compute_units(model: Model, settings: AquiferSettings, within=None, progress: ProgressCallback | None = None) -> None:
    """Walls, closed meshes, volumes and thickness of each unit (S6, S9); links (S6)."""
    s = settings
    model.links = _links(model, s.matching)
    unit_len = horizontal_unit(model.crs)
    within_poly = None
    if within is not None:
        gdf = check_crs(read_layer(within), model.crs, str(within), against="the contacts'", reproject=None)
        within_poly = shapely.union_all(gdf.geometry.to_numpy())
    pairs = list(zip(model.layers[:-1], model.layers[1:]))
    origin = tuple(np.mean([model.surfaces[layer].centre for layer in model.layers], axis=0))
    for k, (up, lo) in enumerate(pairs):
        report(progress, 0.3 + 0.5 * k / len(pairs), f"unit {unit_name(up, lo)}")
        U, L = model.surfaces[up], model.surfaces[lo]
        footprint = common_footprint(U, L)
        if footprint.is_empty or footprint.area <= 0:
            raise InputError(f"layers {up} and {lo} do not overlap in plan, so unit {unit_name(up, lo)} has no footprint",
                             hint=f"Check the layers' x, y (the same CRS, {option('swap_xy')}) and that each layer is "
                                  "the right one")
        region = footprint if within_poly is None else footprint.intersection(within_poly)
        vol = overlay_volume(U, L, region, origin=origin)
        verts, faces = unit_mesh(U, L)
        extent = max(footprint.bounds[2] - footprint.bounds[0], footprint.bounds[3] - footprint.bounds[1])
        cell = (length_to_crs_units(s.cell_size, unit_len, name=option("cell_size")) if s.cell_size
                else _nice(extent / 500))
        grid_t, grid = _thickness_grid(U, L, footprint, cell, model.crs)
        unit = {"upper": up, "lower": lo, "mesh": (verts, faces), "footprint": footprint, "region": region,
                "wall_triangles": len(faces) - len(U.triangles) - len(L.triangles)}  # outer wall (+ hole walls)
        figures = ordered_unit(vol, grid_t, grid, s.order)
        if s.order == "stratigraphic":
            iso = isopach(model.points, up, lo, length_to_crs_units(s.xy_tol, unit_len, name=option("xy_tol")))
            if iso is not None:
                figures.update(_isopach_figures(iso, vol, region, grid, origin))
        model.units[unit_name(up, lo)] = {**unit, **figures}


def ordered_unit(vol: dict, grid_t: np.ndarray, grid, order: str) -> dict:
    """A unit's volume, thickness figures and raster under ``order`` (AquiferSettings), with the crossing of its two
    TINs (where the lower one is above: area from the thickness raster's cells, volume exact) as quality figures."""
    crossing = np.isfinite(grid_t) & (grid_t < 0)
    quality = {"crossing_area": float(np.count_nonzero(crossing) * grid.cell_size ** 2),
               "crossing_volume": float(-vol["volume_negative"]), "volume_raw": float(vol["volume"])}
    if order == "raw":
        return {"volume": vol, "thickness_min": vol["thickness_min"], "thickness_max": vol["thickness_max"],
                "thickness_mean": vol["volume"] / vol["area"] if vol["area"] > 0 else float("nan"),
                "thickness": (grid_t, grid), "thickness_method": "raw", **quality}
    positive = vol["volume_positive"]  # the exact integral of max(upper - lower, 0)
    ordered = {**vol, "volume": positive, "volume_negative": 0.0}
    return {"volume": ordered, "thickness_min": max(vol["thickness_min"], 0.0), "thickness_max": max(vol["thickness_max"], 0.0),
            "thickness_mean": positive / vol["area"] if vol["area"] > 0 else float("nan"),
            "thickness": (np.where(crossing, 0.0, grid_t), grid), "thickness_method": "clipped", **quality}


def _isopach_figures(iso, vol: dict, region, grid, origin) -> dict:
    """A unit's volume, thickness figures and raster from its isopach, where the isopach covers the unit's region
    (to 0.1 %); else nothing (the clipped overlay stands)."""
    total, covered = tin_integral(iso, region, origin=origin)
    if vol["area"] <= 0 or covered < 0.999 * vol["area"]:
        return {}
    X, Y = np.meshgrid(*cell_centres(grid))
    t, inside = height_at(iso, X.ravel(), Y.ravel())
    raster = np.where(inside, t, np.nan).reshape(X.shape)
    inside_w = shapely.contains_xy(region, iso.x, iso.y)
    values = np.concatenate([iso.z[inside_w], raster[np.isfinite(raster)]])
    return {"volume": {**vol, "volume": total, "volume_positive": total, "volume_negative": 0.0},
            "thickness_min": float(values.min()) if values.size else float("nan"),
            "thickness_max": float(values.max()) if values.size else float("nan"),
            "thickness_mean": total / vol["area"], "thickness": (raster, grid), "thickness_method": "isopach"}


def _layers_gpkg(model: Model) -> dict:
    import geopandas as gpd

    crs = model.crs
    out = {}
    p = model.points
    out["points"] = gpd.GeoDataFrame(p.drop(columns=[c for c in ("line", "source") if c in p.columns]),
                                     geometry=shapely.points(p["x"], p["y"], p["z"]), crs=crs)
    f = model.flags
    out["flags"] = gpd.GeoDataFrame(f, geometry=shapely.points(f["x"], f["y"], f["z"]) if len(f) else [], crs=crs)
    for layer, s in model.surfaces.items():
        t = s.triangles
        coords = np.stack([s.xyz[t[:, i]] for i in (0, 1, 2, 0)], axis=1)
        out[f"tin_{layer}"] = gpd.GeoDataFrame({"layer": [layer] * len(t), "v0": s.ids[t[:, 0]], "v1": s.ids[t[:, 1]],
                                                "v2": s.ids[t[:, 2]]}, geometry=shapely.polygons(coords), crs=crs)
        ring = s.ring()
        rc = np.vstack([s.xyz[ring], s.xyz[ring[:1]]])
        out[f"boundary_{layer}"] = gpd.GeoDataFrame(
            {"layer": [layer], "vertices": [len(ring)], "area": [s.outline().area], "ids": [",".join(map(str, s.ids[ring]))]},
            geometry=[shapely.Polygon(rc)], crs=crs)
    lk = model.links
    out["links"] = gpd.GeoDataFrame(lk.drop(columns=["x0", "y0", "z0", "x1", "y1", "z1"]),
                                    geometry=shapely.linestrings(np.stack([lk[["x0", "y0", "z0"]].to_numpy(),
                                                                           lk[["x1", "y1", "z1"]].to_numpy()], axis=1)),
                                    crs=crs)
    walls = []
    for name, u in model.units.items():
        U, L = model.surfaces[u["upper"]], model.surfaces[u["lower"]]
        verts, faces = u["mesh"]  # unit_mesh puts the walls after the two surfaces
        tri = verts[faces[len(U.triangles) + len(L.triangles):]]
        tri = np.concatenate([tri, tri[:, :1]], axis=1)
        walls.append(gpd.GeoDataFrame({"unit": [name] * len(tri)}, geometry=shapely.polygons(tri), crs=crs))
    out["walls"] = pd.concat(walls, ignore_index=True) if walls else gpd.GeoDataFrame({"unit": []}, geometry=[], crs=crs)
    return out


def _figures(model: Model, out: Path, warnings: list) -> list[Path]:
    import matplotlib
    from matplotlib.colors import TwoSlopeNorm

    from ..plot import axes_3d, new_figure, oblique_surfaces, plain_axes

    unit = horizontal_unit(model.crs).name if model.crs is not None else "CRS units"
    paths = []
    fig = new_figure((9, 7))
    ax = axes_3d(fig)
    cmap = matplotlib.colormaps["viridis"].resampled(len(model.layers))
    surfaces = []
    for layer in model.layers:
        s = model.surfaces[layer]
        t = s.triangles
        if len(t) > 4000:  # a readable view (and a quick one): every n-th triangle
            t = t[:: int(np.ceil(len(t) / 4000))]
        surfaces.append((layer, s.x, s.y, s.z, t))
    if ax is not None:
        for k, (layer, x, y, z, t) in enumerate(surfaces):
            ax.plot_trisurf(x, y, z, triangles=t, color=cmap(k), alpha=0.6, linewidth=0, label=layer)
        ax.set_xlabel(f"x ({unit})")
        ax.set_ylabel(f"y ({unit})")
        ax.set_zlabel(f"z ({unit})")
        plain_axes(ax)
        ax.set_title("Aquifer surfaces: " + ", ".join(model.layers))
    else:  # this matplotlib's mpl_toolkits is another version's: the same view drawn in 2D
        warnings.append(f"surfaces_3d.png drawn as a 2D oblique view: this matplotlib {matplotlib.__version__} has no "
                        "3D projection (its mpl_toolkits is another matplotlib's, e.g. the system's python3-matplotlib "
                        "on the path before it)")
        log.warning("%s", warnings[-1])
        ax = fig.subplots()
        oblique_surfaces(ax, surfaces, [cmap(k) for k in range(len(surfaces))])
        ax.set_title("Aquifer surfaces (oblique view, vertical exaggerated): " + ", ".join(model.layers))
    target = out / "surfaces_3d.png"
    with atomic_path(target, overwrite=True) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    paths.append(target)
    for name, u in model.units.items():
        grid_t, grid = u["thickness"]
        fig = new_figure((7, 6))
        ax = fig.subplots()
        w, s_, e, n = grid.bounds
        finite = grid_t[np.isfinite(grid_t)]
        low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if low < 0 < high:  # the layers cross: a diverging scale centred on zero (red: the lower surface on top)
            im = ax.imshow(grid_t, extent=(w, e, s_, n), origin="upper", cmap="RdBu", norm=TwoSlopeNorm(0.0, low, high))
        else:
            im = ax.imshow(grid_t, extent=(w, e, s_, n), origin="upper", cmap="YlGnBu")
        fig.colorbar(im, ax=ax, label=f"thickness ({unit}; below 0: the layers cross)" if low < 0 else f"thickness ({unit})")
        ax.set_xlabel(f"x ({unit})")
        ax.set_ylabel(f"y ({unit})")
        plain_axes(ax)
        ax.set_title(f"Thickness of {name}")
        ax.set_aspect("equal")
        fig.tight_layout()
        target = out / f"thickness_{name.replace('/', '_')}.png"
        with atomic_path(target, overwrite=True) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        paths.append(target)
    return paths


def aquifer_model(source, layers, out, *, crs=None, swap_xy: bool = False, settings: AquiferSettings | None = None,
                  within=None, clip=None, overwrite: bool = False, progress: ProgressCallback | None = None,
                  fields: dict | None = None) -> dict:
    """The aquifer model from layer contacts: ``gistools aquifer model``.

    Cleans the contacts (duplicates, outliers), builds a TIN surface per layer and a closed mesh per unit between two
    layers, and writes under ``out``: ``aquifer.gpkg``, the unit meshes, thickness rasters, figures and
    ``report.json`` (volumes in the CRS unit cubed).

    Parameters
    ----------
    source : str, path or list
        A contacts table (CSV, GeoPackage layer ``file.gpkg:LAYER``, shapefile) with x, y, z and layer, or per-layer
        files given as ``"LAYER=path"``.
    layers : sequence of str
        The layer names, top to bottom (e.g. ``["LS", "AU", "AD", "AQ"]``).
    out : str or path
        Output folder, made when missing.
    crs : str, optional
        The contacts' CRS (e.g. ``"EPSG:3003"``) when the file carries none.
    swap_xy : bool
        Swap x and y (files that label East as North).
    settings : AquiferSettings, optional
        The options (outlier thresholds, ``xy_tol``, ``cell_size``, ``matching``, ...; lengths as text with their unit
        or a number in CRS units). None: the defaults.
    within : str, optional
        A polygon layer: volumes and thickness statistics inside it. None: each unit's common footprint.
    clip : str, optional
        A polygon layer the surfaces are cut to (a concave outline, holes).
    overwrite : bool
        Replace a model already in ``out``.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.
    fields : dict, optional
        ``{field: column}`` where the table names the fields otherwise (id, x, y, z, layer, borehole_id).

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``layers`` (points, flagged, triangles of each
        layer), ``units`` (each unit's volume, area and thickness, in ``volume_unit`` and ``length_unit``),
        ``outputs``.

    Raises
    ------
    InputError
        An option or the contacts are not valid (a missing layer, a column not found, ...), or they carry no CRS
        and ``crs`` is not given.
    OutputExistsError
        ``out`` holds another command's outputs, or a model whose record does not say its settings (and
        ``overwrite`` is False); a model of other settings is refused naming the first that differs (InputError).

    Examples
    --------
    >>> from gistools import aquifer_model
    >>> report = aquifer_model("contacts.csv", ["LS", "AU", "AD", "AQ"], "milan", crs="EPSG:3003")  # doctest: +SKIP
    >>> report["layers"]["AU"]["points"], report["volume_unit"]  # doctest: +SKIP
    (953, 'cubic metre')
    """
    started = time.time()
    s = settings or AquiferSettings()
    s.validate()
    out = output_folder(out)
    now = {**s.__dict__, "layers": list(layers), "crs": crs, "swap_xy": swap_xy, "within": within, "clip": clip,
           "fields": fields}
    inputs = [*(source if isinstance(source, (list, tuple)) else [source]), within, clip]
    kept = rerun_kept(out, "gistools aquifer model", now, inputs, overwrite, started)
    if kept is not None:
        return kept
    model = build_model(source, layers, crs=crs, swap_xy=swap_xy, settings=s, clip=clip, progress=progress,
                        fields=fields)
    compute_units(model, s, within=within, progress=progress)
    report(progress, 0.85, "writing")
    with claim_output(out, "gistools aquifer model"):
        return _write_model(model, s, out, started, progress, swap_xy=swap_xy, within=within, clip=clip, source=source,
                            made=(now, inputs))


def _write_model(model, s: "AquiferSettings", out: Path, started: float, progress, *, swap_xy, within, clip, source,
                 made: tuple) -> dict:
    write_layers(_layers_gpkg(model), out / "aquifer.gpkg", overwrite=True)
    files = {"gpkg": str(out / "aquifer.gpkg"), "meshes": {}, "thickness": {}, "densified": {}}
    densified_counts = {}
    for layer in model.layers:
        surf = model.surfaces[layer]
        densified_counts[layer] = int(s.n_per_edge * len(unique_edges(surf.triangles)))
        if s.densify:
            pts = densify(surf, s.n_per_edge)
            start = int(model.points["id"].max()) + 1 + sum(densified_counts[x] for x in model.layers[:model.layers.index(layer)])
            frame = pd.DataFrame({"id": start + np.arange(len(pts)), "x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2],
                                  "layer": layer})
            target = out / f"densified_{layer}.csv"
            with atomic_path(target, overwrite=True) as tmp:
                frame.to_csv(tmp, index=False)
            files["densified"][layer] = str(target)
    for name, u in model.units.items():
        slug = name.replace("/", "_")
        verts, faces = u["mesh"]
        writer = write_ply if s.mesh_format == "ply" else write_obj
        files["meshes"][name] = str(writer(out / f"unit_{slug}.{s.mesh_format}", verts, faces))
        grid_t, grid = u["thickness"]
        files["thickness"][name] = str(write_raster(out / f"thickness_{slug}.tif", grid_t, grid, overwrite=True,
                                                    tags={"GISTOOLS_PRODUCT": "thickness", "GISTOOLS_UNIT": name},
                                                    description=f"thickness of {name}"))
    warnings: list[str] = []
    if s.figures:
        try:
            files["figures"] = [str(p) for p in _figures(model, out, warnings)]
        except Exception as err:  # a figure never stops the model: matplotlib missing, or a broken mix of two
            files["figures"] = []
            warnings.append(f"no figures: matplotlib failed ({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}); "
                            "the model's files are complete")
            log.warning("%s", warnings[-1])
    counts = model.flags[~model.flags["kept"].astype(bool)].groupby("layer").size() if len(model.flags) else pd.Series(dtype=int)
    by_flag = model.flags.groupby(["layer", "flag"]).size() if len(model.flags) else pd.Series(dtype=int)
    unit_len = horizontal_unit(model.crs)
    rep = {
        "tool": "gistools aquifer model",
        "crs": model.crs.to_string(),
        "crs_wkt": model.crs.to_wkt(),
        "length_unit": unit_len.name,
        "volume_unit": f"cubic {unit_len.name}",
        "layers": {},
        "units": {},
        "settings": {**{k: v for k, v in s.__dict__.items()}, "swap_xy": swap_xy, "within": str(within) if within else None,
                     "clip": str(clip) if clip else None},
        "outputs": files,
        "warnings": warnings,
    }
    for layer in model.layers:
        surf = model.surfaces[layer]
        rep["layers"][layer] = {
            "points": int((model.points["layer"] == layer).sum()),
            "input_points": int((model.points["layer"] == layer).sum() + counts.get(layer, 0)),
            "flagged": int(counts.get(layer, 0)),
            "flags": {f: int(n) for (lay, f), n in by_flag.items() if lay == layer},
            "triangles": int(len(surf.triangles)),
            "boundary_vertices": int(len(surf.ring())),
            "boundary_area": float(surf.outline().area),
            "densified_points": densified_counts[layer],
        }
    for name, u in model.units.items():
        v = u["volume"]
        rep["units"][name] = {
            "volume": v["volume"], "volume_positive": v["volume_positive"], "volume_negative": v["volume_negative"],
            "area": v["area"], "thickness_min": u["thickness_min"], "thickness_mean": u["thickness_mean"],
            "thickness_max": u["thickness_max"], "wall_triangles": int(u["wall_triangles"]),
            "upper": u["upper"], "lower": u["lower"], "order": s.order, "thickness_method": u["thickness_method"],
            "crossing_area": u["crossing_area"], "crossing_volume": u["crossing_volume"],
            "volume_raw": u["volume_raw"],
            "mesh_faces": int(len(u["mesh"][1])),
            "mesh_closed": is_closed(u["mesh"][1]),
        }
    rep["made"] = run_record(*made, files)
    rep["seconds"] = round(time.time() - started, 3)
    rep = write_folder_report(out, rep)
    report(progress, 1.0, "done")
    return rep


def load_model(out) -> Model:
    """The surfaces of a written model (``out/aquifer.gpkg`` cleaned points + report.json settings)."""
    import geopandas as gpd

    out = output_folder(out)
    path = out / "report.json"
    if not path.exists():
        raise InputError(f"{out}: no report.json of an aquifer model", hint="Run gistools aquifer model first")
    rep = json.loads(path.read_text(encoding="utf-8"))
    pts = gpd.read_file(out / "aquifer.gpkg", layer="points")
    layers = list(rep["layers"])
    st = rep["settings"]
    clip = None
    if st.get("clip"):
        clip = shapely.union_all(read_layer(st["clip"]).geometry.to_numpy())
    surfaces = _surfaces(pd.DataFrame(pts.drop(columns="geometry")), layers, clip, st.get("concave_ratio"))
    return Model(layers, pyproj.CRS.from_wkt(rep["crs_wkt"]), pts, pd.DataFrame(), surfaces,
                 order=st.get("order", "raw"))  # models written before the order was applied are raw


def aquifer_query(out, x, y, method: str = "tin", *, k: int = 10) -> dict:
    """Each surface's height and each unit's thickness at (x, y) of a written model: ``gistools aquifer query``.

    Parameters
    ----------
    out : str or path
        The folder of a model written by `aquifer_model`.
    x, y : float
        The point, in the model's CRS units.
    method : str
        ``"tin"`` (each surface's TIN; nothing outside its boundary), ``"knn"`` (mean of the ``k`` nearest contacts)
        or ``"idw"`` (inverse-distance weighted contacts).
    k : int
        Neighbours of ``"knn"`` and ``"idw"``.

    Returns
    -------
    dict
        ``heights`` ({layer: {"z": height in the CRS unit, "inside": bool}}) and ``thickness`` ({"TOP/BASE":
        thickness}), with ``x``, ``y`` and ``method``.

    Raises
    ------
    InputError
        ``method``, ``k``, ``x`` or ``y`` is not valid, or ``out`` holds no model.

    Examples
    --------
    >>> from gistools import aquifer_model, aquifer_query
    >>> report = aquifer_model("contacts.csv", ["LS", "AU", "AD", "AQ"], "milan", crs="EPSG:3003")  # doctest: +SKIP
    >>> answer = aquifer_query("milan", 1517365, 5031638, "knn", k=10)  # doctest: +SKIP
    >>> sorted(answer["thickness"])  # doctest: +SKIP
    ['AD/AQ', 'AU/AD', 'LS/AU']
    """
    return query_model(load_model(out), x, y, method, k=k)


def query_model(model: Model, x, y, method: str = "tin", *, k: int = 10) -> dict:
    """:func:`aquifer_query` on a loaded model (load it once for many points)."""
    if method not in HEIGHT_METHODS:  # the parameter height_method (method is the ground / CHM methods')
        raise InputError(f"{option('method')} {method!r} is not one of {', '.join(HEIGHT_METHODS)}",
                         hint=f"Use {option('method', 'tin')}")
    check_count(k, "k", example="10")
    check_number(x, "x", example="1517365")
    check_number(y, "y", example="5031638")
    heights, above = {}, None
    for layer in model.layers:
        z, inside = height_at(model.surfaces[layer], [x], [y], method, k=k)
        h = {"z": None if not np.isfinite(z[0]) else float(z[0]), "inside": bool(inside[0])}
        if model.order == "stratigraphic" and h["z"] is not None and above is not None and h["z"] > above:
            h.update(z=above, z_raw=h["z"])  # a surface is never above the one above it
        above = h["z"] if h["z"] is not None else above
        heights[layer] = h
    thick = {}
    for up, lo in zip(model.layers[:-1], model.layers[1:]):
        a, b = heights[up]["z"], heights[lo]["z"]
        thick[unit_name(up, lo)] = None if a is None or b is None else a - b
    return {"x": x, "y": y, "method": method, "heights": heights, "thickness": thick}



