"""Structure reconstruction (dissertation ch. 6): a building's point cloud to levels, clusters, loops, matched
walls and a closed 3D mesh. ``reconstruct`` works in memory; ``structure_model`` writes the outputs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import shapely

from ..engine.record import write_folder_report
from ..errors import InputError
from ..engine.resume import rerun_kept, run_record
from ..io.outdir import claim_output, output_folder
from ..io.raster import atomic_path
from ..parameters import check as check_parameter, option
from ..validation import check_number
from scipy.spatial import QhullError
from ..io.text import read_cloud
from ..structure.analysis import (Cluster, check_points, classify_cluster, cluster_level, estimate_parameters,
                                  split_levels, transform_points)
from ..structure.envelope import chain_loops, envelope, match_clusters, sown_footprint
from ..progress import ProgressCallback, report

__all__ = ["Structure", "read_points", "reconstruct", "mesh_from_triangles", "structure_model"]


def read_points(source, *, columns: str = "123", scales=(1.0, 1.0, 1.0), rotations=(0.0, 0.0, 0.0)) -> pd.DataFrame:
    """The structure's cloud (S0) as id, x, y, z: read (``ID X Y Z`` text or LAS/LAZ), then columns permuted,
    scaled and rotated (structure.analysis.transform_points)."""
    ids, xyz = read_cloud(source)
    xyz = transform_points(xyz, columns=columns, scales=scales, rotations=rotations)
    return pd.DataFrame({"id": ids, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})


@dataclass
class Structure:
    points: pd.DataFrame
    log: pd.DataFrame
    parameters: object
    levels: list  # [(z, [clusters])]
    pairs: list = field(default_factory=list)
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None

    @property
    def clusters(self):
        return [c for _, cs in self.levels for c in cs]


def mesh_from_triangles(tris: np.ndarray, decimals: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) with vertices shared where triangles meet (coordinates equal to ``decimals``)."""
    flat = tris.reshape(-1, 3)
    key = np.round(flat, decimals)
    vertices, inverse = np.unique(key, axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    good = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    return vertices, faces[good]


def reconstruct(points: pd.DataFrame, *, h=None, d=None, t=None, eps_z: float = 0.1, check: bool = True,
                progress: ProgressCallback | None = None, source=None) -> Structure:
    """A building's structure from its points, in memory: levels, clusters, loops and a closed mesh.

    Parameters
    ----------
    points : pandas.DataFrame
        Columns id, x, y, z (metres), as `gistools.products.structure.read_points` gives them.
    h : float, optional
        Largest height step between consecutive levels (m); None or 0: estimated.
    d : float, optional
        Planimetric distance joining points into a cluster (m); None or 0: estimated.
    t : float, optional
        Planimetric tolerance of matching and of the chain / sown split (m); None or 0: 4 m.
    eps_z : float
        Points within this height (m) are on one level.
    check : bool
        First clean the points (duplicates, reused ids, near points merged, isolated points left out).
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.
    source : str or path, optional
        The file the points came from, named in errors.

    Returns
    -------
    Structure
        ``points``, ``log`` (the cleaning's), ``parameters`` (h, d, t used), ``levels`` ([(z, clusters)]), ``pairs``,
        and the mesh's ``vertices`` and ``faces`` (numpy arrays).

    Raises
    ------
    InputError
        Too few points or levels, coordinates not finite, or points that do not span an area in plan.

    Examples
    --------
    >>> from gistools import reconstruct
    >>> from gistools.products.structure import read_points
    >>> structure = reconstruct(read_points("cctv.txt"))  # doctest: +SKIP
    >>> structure.faces.shape[1]  # doctest: +SKIP
    3
    """
    if len(points) < 2:
        raise InputError(f"{len(points)} point(s): a structure needs levels of points", hint="Give the building's cloud",
                         path=source)
    xyz = points[["x", "y", "z"]].to_numpy(np.float64)
    if not np.all(np.isfinite(xyz)):
        raise InputError("coordinates must be finite (NaN or inf found)", path=source, hint="Fix or remove those rows")
    xy = xyz[:, :2] - xyz[:, :2].mean(axis=0)
    span = np.linalg.svd(xy, compute_uv=False) if len(xy) >= 2 else np.zeros(2)
    if span[0] <= 1e-9 * max(1.0, float(np.abs(xyz[:, :2]).max())) or span[1] <= 1e-9 * span[0]:
        raise InputError("the points do not span an area in plan (all identical or on one line)", path=source,
                         hint="Give the building's whole cloud, with x, y, z in the columns given by "
                              f"{option('columns')}")
    pts, log = check_points(points, eps_z=eps_z) if check else (points.reset_index(drop=True), pd.DataFrame())
    level = split_levels(pts["z"].to_numpy(), eps_z)
    if level.max() + 1 < 3:
        raise InputError(f"{level.max() + 1} level(s); a structure needs at least 3 (floor, walls, roof)",
                         hint="Check the heights (levels are split where z jumps by more than eps_z)", path=source)
    try:
        return _reconstruct_levels(pts, log, level, h=h, d=d, t=t, eps_z=eps_z, progress=progress)
    except QhullError as err:
        raise InputError(f"a level's points are degenerate (all on one line or one point): {str(err).splitlines()[0]}",
                         path=source,
                         hint=f"Check the cloud ({option('columns')}, {option('scales')}) or remove the stray "
                              "level") from None


def _reconstruct_levels(pts, log, level, *, h, d, t, eps_z, progress) -> Structure:
    params = estimate_parameters(pts, h=h, d=d, t=t, eps_z=eps_z)
    report(progress, 0.2, "clusters")
    levels = []
    index = 0
    xy_all = pts[["x", "y"]].to_numpy(np.float64)
    for lev in range(int(level.max()) + 1):
        sel = np.flatnonzero(level == lev)
        z = float(pts["z"].to_numpy()[sel].mean())
        labels = cluster_level(xy_all[sel], params.d)
        clusters = []
        for lab in np.unique(labels):
            idx = sel[labels == lab]
            clusters.append(_cluster(Cluster(index, lev, z, pts["id"].to_numpy()[idx], xy_all[idx]),
                                     params.estimated["spacing"], params.t))
            index += 1
        _mark_holes(clusters)
        levels.append((z, clusters))
    report(progress, 0.5, "matching")
    pairs = _matched_pairs(levels, params)
    report(progress, 0.7, "envelope")
    tris = envelope(levels, pairs, params.t)
    vertices, faces = mesh_from_triangles(tris)
    return Structure(pts, log, params, levels, pairs, vertices, faces)


def _cluster(c: Cluster, spacing: float, t: float) -> Cluster:
    """Kind, rings and footprint of a cluster: a plate ("sown") closes faces between its points and has points
    off their outline; else an outline ("chain") through its points."""
    xy = c.xy
    foot = sown_footprint(xy) if len(xy) >= 3 else shapely.Polygon()
    c.kind = classify_cluster(xy, foot, spacing, t) if not foot.is_empty else "chain"
    if c.kind == "chain":
        c.rings = [xy[r] for r in chain_loops(xy)]
        c.footprint = shapely.Polygon(c.rings[0])
    else:
        c.rings = [np.asarray(r.coords)[:-1] for r in shapely.get_parts(foot.boundary)]
        c.footprint = foot
    return c


def _mark_holes(clusters: list) -> None:
    """Even-odd nesting of the chain loops of a level: a loop inside another is a hole, wound clockwise."""
    chains = [c for c in clusters if c.kind == "chain"]
    for c in chains:
        inside = sum(1 for o in chains if o is not c and o.footprint.contains(c.footprint))
        c.hole = inside % 2 == 1
        if c.hole:
            c.rings = [r[::-1] for r in c.rings]


def _matched_pairs(levels: list, params) -> list:
    """(level, cluster, level + 1, cluster) of consecutive levels within h whose clusters match (two plates never)."""
    pairs = []
    for i in range(len(levels) - 1):
        if levels[i + 1][0] - levels[i][0] > params.h + 1e-9:
            continue
        for lc in levels[i][1]:
            pairs += [(i, lc, i + 1, uc) for uc in levels[i + 1][1]
                      if not (lc.kind == "sown" and uc.kind == "sown") and match_clusters(lc, uc, params.t)]
    return pairs


def _mesh_stats(vertices, faces) -> dict:
    from ..mesh import is_closed, mesh_volume

    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    n_edges = len(np.unique(e, axis=0))
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    area = float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
    return {"vertices": int(len(vertices)), "faces": int(len(faces)), "edges": int(n_edges),
            "euler": int(len(vertices) - n_edges + len(faces)), "watertight": is_closed(faces),
            "volume": mesh_volume(vertices, faces), "surface_area": area}


def _figure(s: Structure, out: Path) -> Path:
    """A 3D view of the mesh (matplotlib), PNG."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from ..plot import new_figure

    fig = new_figure((8, 8))
    ax = fig.add_subplot(projection="3d")
    tri = s.vertices[s.faces]
    ax.add_collection3d(Poly3DCollection(tri, facecolor="#9fb8d8", edgecolor="#3b5a80", linewidths=0.2, alpha=0.9))
    lo, hi = s.vertices.min(axis=0), s.vertices.max(axis=0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.maximum(hi - lo, 1e-9))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title(f"{len(s.levels)} levels, {len(s.faces)} triangles")
    target = out / "structure_3d.png"
    with atomic_path(target, overwrite=True) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    return target


def _check_options(h, d, t, scales, rotations, loop_mode) -> None:
    """structure_model's options (gistools.parameters.structure), before anything is read or written."""
    check_parameter("loop_mode", loop_mode)
    for name, value in (("h", h), ("d", d), ("t", t)):
        if value is not None:
            check_number(value, name, low=0, low_open=True, example="8")
    if len(scales) != 3 or any(not np.isfinite(v) or v == 0 for v in map(float, scales)):
        raise InputError(f"{option('scales')} {','.join(map(str, scales))}: three finite, non-zero factors",
                         hint=f"e.g. {option('scales', '1,1,1')} (-1 flips an axis)")
    if len(rotations) != 3 or any(not np.isfinite(float(v)) for v in rotations):
        raise InputError(f"{option('rotations')} {','.join(map(str, rotations))}: three finite angles in degrees",
                         hint=f"e.g. {option('rotations', '0,0,90')}")


def structure_model(source, out, *, h=None, d=None, t=None, columns="123", scales=(1, 1, 1), rotations=(0, 0, 0),
                    loop_mode: str = "classic", overwrite: bool = False, progress: ProgressCallback | None = None) -> dict:
    """A closed mesh of a building's point cloud: ``gistools structure``.

    Reads the cloud, reconstructs it level by level (`reconstruct`) and writes under ``out``: ``structure.ply``,
    ``structure.obj``, the loops (``structure.gpkg``), a figure and ``report.json``.

    Parameters
    ----------
    source : str or path
        The cloud: ``ID X Y Z`` text, or a LAS / LAZ file.
    out : str or path
        Output folder, made when missing.
    h : float, optional
        Largest height step between consecutive levels, in the cloud's unit (m); None or 0: estimated.
    d : float, optional
        Planimetric distance joining points into a cluster (m); None or 0: estimated.
    t : float, optional
        Planimetric tolerance of matching and of the chain / sown split (m); None or 0: 4 m.
    columns : str
        Which input columns are x, y, z (``"213"`` swaps x and y).
    scales : sequence of float
        Signed scale per axis (x, y, z; -1 flips an axis).
    rotations : sequence of float
        Rotations about x, y, z, in degrees.
    loop_mode : str
        ``"classic"`` (loops through the points as they are) or ``"catmull-rom"`` (also piecewise Catmull-Rom loops).
    overwrite : bool
        Replace a structure already in ``out``.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``levels``, ``watertight``, ``volume`` (m3),
        ``surface_area`` (m2), ``outputs``, ...

    Raises
    ------
    InputError
        An option or the cloud is not valid (fewer than 3 levels, points on a line, ...).
    DataFileError
        The cloud cannot be read.
    OutputExistsError
        ``out`` holds another command's outputs, or a run whose record does not say its settings (and
        ``overwrite`` is False); a run of other settings is refused naming the first that differs (InputError).

    Examples
    --------
    >>> from gistools import structure_model
    >>> report = structure_model("cctv.txt", "f4")  # doctest: +SKIP
    >>> report["watertight"], sorted(report["outputs"])  # doctest: +SKIP
    (True, ['figure', 'gpkg', 'obj', 'ply'])
    """
    _check_options(h, d, t, scales, rotations, loop_mode)
    started = time.time()
    out = output_folder(out)
    now = {"h": h, "d": d, "t": t, "columns": columns, "scales": list(scales), "rotations": list(rotations),
           "loop_mode": loop_mode}
    kept = rerun_kept(out, "gistools structure", now, source, overwrite, started)
    if kept is not None:
        return kept
    pts = read_points(source, columns=columns, scales=scales, rotations=rotations)
    s = reconstruct(pts, h=h, d=d, t=t, progress=progress, source=source)
    stats = _mesh_stats(s.vertices, s.faces)
    with claim_output(out, "gistools structure"):
        rep = _write_structure(s, stats, out, loop_mode, started)
        rep["settings"] = now
        rep["made"] = run_record(now, source, rep["outputs"])
        return write_folder_report(out, rep)


def _write_structure(s: "Structure", stats: dict, out: Path, loop_mode: str, started: float) -> dict:
    from ..io.meshes import write_obj, write_ply

    write_ply(out / "structure.ply", s.vertices, s.faces)
    write_obj(out / "structure.obj", s.vertices, s.faces)
    import geopandas as gpd

    from ..io.vector import write_layers

    rows = []
    for z, clusters in s.levels:
        for c in clusters:
            for r in c.rings:
                rc = np.vstack([r, r[:1]])
                rows.append({"cluster": c.index, "z": z, "kind": c.kind, "points": len(c.ids),
                             "geometry": shapely.LineString(np.column_stack([rc, np.full(len(rc), z)]))})
    extra = {}
    if loop_mode == "catmull-rom":
        from ..structure.envelope import catmull_rom_loop

        new_pts, line_rows = [], []
        for z, clusters in s.levels:
            for c in clusters:
                for r in c.rings:
                    cr, lines = catmull_rom_loop(r)
                    for k, ((px, py), (kind, slope, icpt)) in enumerate(zip(cr, lines)):
                        line_rows.append({"cluster": c.index, "z": z, "vertex": k, "kind": kind, "slope": slope,
                                          "intercept": icpt, "geometry": shapely.Point(r[k, 0], r[k, 1], z)})
                        if np.isfinite(px):
                            new_pts.append({"cluster": c.index, "z": z, "side": k, "geometry": shapely.Point(px, py, z)})
        extra = {"catmull_rom_points": gpd.GeoDataFrame(new_pts, geometry="geometry"),
                 "catmull_rom_lines": gpd.GeoDataFrame(line_rows, geometry="geometry")}
    levels_df = pd.DataFrame([{"level": i, "z": z, "clusters": len(cs), "points": int(sum(len(c.ids) for c in cs))}
                              for i, (z, cs) in enumerate(s.levels)])
    import warnings

    with warnings.catch_warnings():  # a local frame: the layers carry no CRS, on purpose
        warnings.filterwarnings("ignore", message=".*crs.*was not provided")
        write_layers({"loops": gpd.GeoDataFrame(rows, geometry="geometry"),
                      "levels": gpd.GeoDataFrame(levels_df, geometry=shapely.points(np.zeros(len(levels_df)),
                                                                                     np.zeros(len(levels_df)), levels_df["z"])),
                      **extra},
                     out / "structure.gpkg")
    chain_chain = sum(1 for _, a, _, b in s.pairs if a.kind == b.kind == "chain")
    rep = {
        "tool": "gistools structure",
        "levels": len(s.levels), "clusters": len(s.clusters),
        "sowns": sum(c.kind == "sown" for c in s.clusters), "chains": sum(c.kind == "chain" for c in s.clusters),
        "matched_pairs": len(s.pairs), "matched_chain_chain": chain_chain, "matched_sown_chain": len(s.pairs) - chain_chain,
        "triangles": stats["faces"], "volume": stats["volume"], "surface_area": stats["surface_area"],
        "watertight": stats["watertight"], "euler": stats["euler"],
        "parameters": {"height_interval": s.parameters.h, "distance": s.parameters.d, "tolerance": s.parameters.t},
        "estimated": s.parameters.estimated, "voxel_counts": s.parameters.voxel_counts, "k_opt": s.parameters.k_opt,
        "loop_mode": loop_mode,
        "log": {k: int(v) for k, v in s.log["change"].value_counts().items()} if len(s.log) else {},
        "outputs": {"ply": str(out / "structure.ply"), "obj": str(out / "structure.obj"), "gpkg": str(out / "structure.gpkg")},
    }
    try:
        rep["outputs"]["figure"] = str(_figure(s, out))
    except ImportError:
        pass
    rep["seconds"] = round(time.time() - started, 3)
    return rep
