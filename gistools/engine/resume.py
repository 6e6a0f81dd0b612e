"""The resume protocol of the rasters: a tile's own report, the mark of a complete tile.

``OUT/tile_reports/<tile>.json`` is written once all of a tile's rasters are: what the run found (point counts,
first returns per band, outputs, warnings, the neighbours whose points it used) and the settings its rasters
depend on. A resumed run keeps a tile whose report and rasters are there and whole, refuses one made with other
settings, and recomputes one made without a neighbour that reads now.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from ..errors import InputError
from ..parameters import option
from ..io.atomic import atomic_path
from ..io.points import crs_label
from ..io.raster import crs_from_wkt, file_stamp, raster_is_readable

log = logging.getLogger("gistools.products.rasters")

__all__ = ["TILE_FIELDS", "tile_report_file", "run_settings", "write_tile_report", "read_tile_report",
           "check_same_settings", "complete_tile", "kept_tiles"]


# What a tile's run found (point counts, first returns per band, outputs), written beside the rasters once they
# are all written: the mark of a complete tile, and what a resumed run reports for the tiles it keeps.
TILE_FIELDS = ("points", "points_by_class", "points_by_return", "points_outside_header_bounds", "outputs",
                "first_return_bands", "shore_minima", "shore_profile", "dem_filled_cells", "dsm_filled_cells",
               "warnings", "neighbours", "seconds", "grid")


def tile_report_file(out: Path, name: str) -> Path:
    return Path(out) / "tile_reports" / f"{name}.json"


def run_settings(run) -> dict:
    """The settings a tile's rasters depend on (of the rasters' run parameters ``run``), as in its tile report."""
    settings = {"cell_size": run.cell_size, "dem_method": run.dem_method, "dem_max_distance": run.max_distance,
                "buffer": run.buffer, "dsm_classes": None if run.dsm_classes is None else list(run.dsm_classes),
                "z_unit": run.z_unit, "crs_wkt": run.crs_wkt}
    if getattr(run, "dem_fill", "none") != "none":
        settings["dem_fill"] = run.dem_fill
    if getattr(run, "dsm_fill", "none") != "none":
        settings["dsm_fill"] = f"subcircle {run.subcircle:.6g}" if run.dsm_fill == "subcircle" else run.dsm_fill
    if getattr(run, "water_key", None):  # the shore minima of pass 1 depend on the water layer
        settings["hydro_flatten"] = run.water_key
    return settings


def write_tile_report(out: Path, result, settings: dict) -> None:
    """The tile's report, with each raster's stamp (size, mtime) as it was written and checked."""
    stamps = {p: file_stamp(path) for p, path in (result.outputs or {}).items()}
    with atomic_path(tile_report_file(out, result.name), overwrite=True) as tmp:
        tmp.write_text(json.dumps({**{k: getattr(result, k) for k in TILE_FIELDS}, "settings": settings,
                                   "stamps": stamps}, indent=1))


def read_tile_report(out: Path, name: str) -> dict | None:
    try:
        rep = json.loads(tile_report_file(out, name).read_text())
    except (OSError, ValueError):  # none (a run killed after the rasters, or before this version) or unreadable
        return None
    for key in ("points_by_class", "points_by_return"):  # JSON keys are strings; class and return numbers are ints
        rep[key] = {int(k): v for k, v in (rep.get(key) or {}).items()}
    return rep


SETTING_NAMES = {"cell_size": "cell size", "dem_method": "DEM method", "dem_max_distance": "DEM max distance",
                  "buffer": "buffer", "dsm_classes": "DSM classes", "z_unit": "z unit", "crs_wkt": "CRS",
                  "hydro_flatten": f"{option('hydro_flatten')} layer and shore width", "dem_fill": option("dem_fill"),
                  "dsm_fill": option("dsm_fill")}


def check_same_settings(out: Path, name: str, earlier: dict | None, now: dict) -> None:
    """Refuse to resume over a tile made with other settings (the mosaic would mix them)."""
    if earlier is None:
        return
    crs = crs_from_wkt(now["crs_wkt"])
    unit = crs.axis_info[0].unit_name if crs.axis_info else "CRS units"
    for key, value in now.items():
        old = earlier.get(key)
        if key == "crs_wkt":
            same = old is not None and crs_from_wkt(old).equals(crs)
            shown = (crs_label(crs_from_wkt(old)) if old else "none", crs_label(crs))
        elif isinstance(value, float):
            same = old == value
            shown = tuple("none" if v is None else f"{v:.6g} {unit}" for v in (old, value))
        else:
            same = old == value
            shown = tuple("all but noise" if v is None and key == "dsm_classes" else v for v in (old, value))
        if not same:
            raise InputError(
                f"{out}: tile {name} was made with {SETTING_NAMES[key]} {shown[0]}, this run asks {shown[1]}",
                hint=f"Pass {option('overwrite')} to redo the tiles with the new settings, or choose another {option('out')}")


def _kept_raster_whole(path: Path, stamp) -> bool:
    """A kept raster is whole: untouched since gistools wrote and checked it (its recorded size and time), or
    opening and reading whole now; a damaged one is recomputed."""
    if stamp == file_stamp(path):
        return True
    if raster_is_readable(path):
        return True
    log.warning("%s: damaged, recomputing the tile", path)
    return False


def complete_tile(out: Path, name: str, rep: dict | None, products, return_breaks=None) -> dict | None:
    """The tile report ``rep`` of a tile whose outputs are all written (with first-return counts at
    ``return_breaks`` when those are asked for), else None: the tile is (re)computed."""
    if rep is None or not all((out / p / f"{name}.tif").exists() for p in products):
        return None
    stamps = rep.get("stamps") if isinstance(rep.get("stamps"), dict) else {}
    if not all(_kept_raster_whole(out / p / f"{name}.tif", stamps.get(p)) for p in products):
        return None
    if return_breaks is not None and (rep.get("first_return_bands") or {}).get("breaks") != list(return_breaks):
        return None
    return rep


def kept_tiles(out: Path, infos, neighbours: dict, run, settings: dict) -> dict:
    """{tile: its earlier report, or None when it is to be made}: complete tiles of an earlier run with the same
    settings (another setting is refused), except those made without a neighbour that reads now (stale edge)."""
    kept = {}
    for i in infos:
        rep = read_tile_report(out, i.name)
        if rep is not None:
            check_same_settings(out, i.name, rep.get("settings"), settings)
        kept[i.name] = complete_tile(out, i.name, rep, run.products, run.return_breaks)
        missing = {n.name for n in neighbours[i.name]} - set((rep or {}).get("neighbours") or [])
        if kept[i.name] is not None and missing:
            log.info("%s: recomputed, its neighbours %s were not read when it was made", i.name, sorted(missing))
            kept[i.name] = None
    return kept

