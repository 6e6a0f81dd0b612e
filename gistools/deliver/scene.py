"""The 3D scene of a shrub chain's output folder (``gistools scene OUT``, ``gistools:scene``): ``OUT/scene.glb``, the
DSM (the DEM where the DSM has no value) as a mesh in metres with the shrub classes as vertex colours, for QGIS 3D,
Cesium or Blender.

glTF binary through trimesh (MIT, widely used; it writes vertex colours and lets the asset carry extras; pygltflib
would have us pack the buffers by hand). Axes as glTF has them: x east, y up, z south, metres from the scene's
origin (the south-west corner of the mosaic, in ``asset.extras`` with the CRS), heights times ``exaggeration``.
Beside it ``scene.prj`` (the CRS) and ``scene.wld`` (a world file taking mesh x, -z metres back to CRS x, y). The
mesh is decimated (every k-th cell) so the file stays under ``max_mb``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..errors import InputError, OutputExistsError
from ..io.outdir import claim_output, output_folder
from ..io.atomic import atomic_path
from ..io.raster import read_raster
from ..lidar.shrub import CLASS_STYLE
from ..parameters import check, choices, option
from ..scene import decimation_step, grid_mesh
from ..engine.record import add_run, read_folder_report

__all__ = ["scene_glb", "read_extras", "SCENE_SURFACES", "GROUND_COLOUR"]

SCENE_SURFACES = choices("surface")  # declared in gistools.parameters.deliver
GROUND_COLOUR = "#e2dac4"  # class 0 (no vegetation): pale earth in 3D, where the map's white would vanish


def _rgb(hex_colour: str) -> tuple[int, int, int]:
    return tuple(int(hex_colour[i:i + 2], 16) for i in (1, 3, 5))


MAX_EXAGGERATION = 100.0  # scenes exaggerate heights 1 to 10 times; past 100 a terrain is a wall of spikes


def _check(exaggeration, max_mb, surface) -> None:
    if not (isinstance(exaggeration, (int, float)) and 0 < exaggeration <= MAX_EXAGGERATION):
        raise InputError(f"{option('exaggeration')} {exaggeration!r} must be a number above 0 and at most "
                         f"{MAX_EXAGGERATION:g} (heights times it must stay heights a viewer can draw)",
                         hint=f"e.g. {option('exaggeration', '2')}")
    if not (isinstance(max_mb, (int, float)) and max_mb > 0):
        raise InputError(f"{option('max_mb')} {max_mb!r} must be a positive number of megabytes",
                         hint=f"e.g. {option('max_mb', '50')}")
    check("surface", surface)


def _surface(out: Path, surface: str):
    """(heights, classes, grid) of the folder's mosaics: the DSM with the DEM where it has no value, or the DEM."""
    names = ("dsm", "dem") if surface == "dsm" else ("dem",)
    if not all((out / f"{n}.vrt").exists() for n in names) or not (out / "classes.vrt").exists():
        raise InputError(f"{out}: no {' and '.join(n + '.vrt' for n in names)} and classes.vrt to build a scene from",
                         hint="Run gistools shrub into this folder first")
    z, grid, _ = read_raster(out / f"{names[0]}.vrt")
    if surface == "dsm":
        dem, dgrid, _ = read_raster(out / "dem.vrt")
        if dgrid.transform == grid.transform and dem.shape == z.shape:
            z = np.where(np.isfinite(z), z, dem)
    classes, cgrid, _ = read_raster(out / "classes.vrt")
    if cgrid.transform != grid.transform or classes.shape != z.shape:
        classes = None
    return z, classes, grid


@shared_sections
def scene_glb(out, *, exaggeration: float = 1.0, max_mb: float = 50.0, surface: str = "dsm") -> dict:
    """A 3D scene (glTF binary) of a shrub chain's surface and classes: ``gistools scene``.

    Writes ``out/scene.glb`` with ``scene.prj`` and ``scene.wld`` (its CRS and placement).

    Parameters
    ----------
    out : str or path
        The folder of a shrub chain run.
    exaggeration : float
        Heights times this.
    max_mb : float
        The file stays under this many megabytes: the grid is decimated (every k-th cell) to fit.
    surface : str
        ``"dsm"`` (the DSM, the DEM where it has no value) or ``"dem"`` (the bare ground).

    Returns
    -------
    dict
        ``glb`` (the path, as text), ``bytes``, ``vertices``, ``faces``, ``step`` (cells per vertex) and
        ``height_range_m``.

    {deliverable_raise}

    Examples
    --------
    >>> from gistools import scene_glb, shrub_from_tiles
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> scene_glb("shrub", exaggeration=2.0)["glb"]  # doctest: +SKIP
    'shrub/scene.glb'
    """
    import time

    started = time.time()
    _check(exaggeration, max_mb, surface)  # every option before the folder is touched
    out = output_folder(out)
    if not out.is_dir():
        raise InputError(f"{out}: no such folder", hint="Run gistools shrub into it first")
    with claim_output(out, "gistools scene"):  # the folder's lock; a killed run's partial file is removed first
        result = _scene_glb(out, exaggeration=exaggeration, max_mb=max_mb, surface=surface)
        add_run(out, {"tool": "gistools scene", "seconds": round(time.time() - started, 3), "settings": {"exaggeration": exaggeration, "max_mb": max_mb, "surface": surface}})
    return result


def _scene_glb(out, *, exaggeration: float = 1.0, max_mb: float = 50.0, surface: str = "dsm") -> dict:
    """Write ``out/scene.glb`` (+ ``scene.prj``, ``scene.wld``) from the chain's mosaics in ``out``; returns
    {"glb", "bytes", "vertices", "faces", "step", "height_range_m"}."""
    _check(exaggeration, max_mb, surface)
    try:
        import trimesh
    except ImportError:
        raise InputError("gistools scene needs trimesh, which is not installed",
                         hint="pip install trimesh (a dependency of gistools: reinstall gistools)") from None
    out = output_folder(out)
    report = read_folder_report(out) or {}
    unit_m, z_unit_m = report.get("horizontal_unit_m"), report.get("vertical_unit_m")
    if not unit_m or not z_unit_m or not report.get("crs_wkt"):
        raise InputError(f"{out}: report.json gives no units or CRS", hint="Run gistools shrub into this folder first")
    _refuse_foreign(out)
    z, classes, grid = _surface(out, surface)
    step = decimation_step(*z.shape, max_mb * 1e6 * 0.95)
    zs = z[::step, ::step]
    cs = classes[::step, ::step] if classes is not None else None
    west, south, _east, north = grid.bounds
    cell = grid.cell_size
    x0 = cell / 2  # the first cell's centre, from the origin (the mosaic's west edge, south edge)
    y0 = (north - cell / 2) - south
    colours = {c: _rgb(GROUND_COLOUR if c == 0 else colour) for c, (_name, colour) in CLASS_STYLE.items()}
    vertices, faces, rgba = grid_mesh(zs, cs, colours, x0=x0, y0=y0, cell=cell * step, unit_m=unit_m,
                                      z_unit_m=z_unit_m, exaggeration=exaggeration)
    if len(faces) == 0:
        raise InputError(f"{out}: the surface has no cells with values", hint="Check the DSM / DEM mosaics")
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, vertex_colors=rgba, process=False)
    extras = {"crs_wkt": report["crs_wkt"], "crs": report.get("crs"), "origin_crs": [west, south, 0.0],
              "axes": "x east, y up, z south; metres from origin_crs", "horizontal_unit_m": unit_m,
              "vertical_unit_m": z_unit_m, "exaggeration": exaggeration, "decimation_step": step,
              "surface": surface, "generator": "gistools scene"}

    def add_extras(tree):
        tree.setdefault("asset", {})["extras"] = extras

    data = trimesh.Scene(mesh).export(file_type="glb", tree_postprocessor=add_extras)
    with atomic_path(out / "scene.glb", overwrite=True) as tmp:
        tmp.write_bytes(data)
    _sidecars(out, report["crs_wkt"], west, south, unit_m)
    up = vertices[:, 1]
    return {"glb": str(out / "scene.glb"), "bytes": len(data), "vertices": len(vertices), "faces": len(faces),
            "step": step, "height_range_m": [float(up.min()), float(up.max())]}


def _refuse_foreign(out: Path) -> None:
    """scene.glb, .prj and .wld are replaced only when the scene there is gistools' own (its extras say so)."""
    glb = out / "scene.glb"
    ours = False
    if glb.exists():
        try:
            ours = read_extras(glb).get("generator") == "gistools scene"
        except (OSError, ValueError, KeyError):
            ours = False
    for name in ("scene.glb", "scene.prj", "scene.wld"):
        if (out / name).exists() and not ours:
            raise OutputExistsError("a file gistools did not write is in the way", path=out / name,
                                    hint="Move it, or write the scene from another folder")


def _sidecars(out: Path, crs_wkt: str, west: float, south: float, unit_m: float) -> None:
    """scene.prj (the CRS, ESRI WKT) and scene.wld: CRS x = west + mesh x / unit_m, CRS y = south + (-mesh z) / unit_m."""
    import pyproj

    crs = pyproj.CRS.from_wkt(crs_wkt)
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    try:
        prj = horizontal.to_wkt("WKT1_ESRI")
    except Exception:  # a CRS ESRI WKT cannot express
        prj = horizontal.to_wkt()
    with atomic_path(out / "scene.prj", overwrite=True) as tmp:
        tmp.write_text(prj, encoding="utf-8")
    lines = [1 / unit_m, 0.0, 0.0, 1 / unit_m, west, south]
    with atomic_path(out / "scene.wld", overwrite=True) as tmp:
        tmp.write_text("\n".join(f"{v:.10f}" for v in lines) + "\n", encoding="utf-8")


def read_extras(path) -> dict:
    """The asset extras of a .glb gistools wrote (its JSON chunk)."""
    data = Path(path).read_bytes()
    length = int.from_bytes(data[12:16], "little")
    return json.loads(data[20:20 + length])["asset"].get("extras", {})
