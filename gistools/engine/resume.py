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

__all__ = ["TileMarks", "run_fingerprint", "check_targets", "written_by_gistools", "input_stamp", "rerun_plan", "made_record",
           "TILE_FIELDS", "tile_report_file", "run_settings", "write_tile_report", "read_tile_report",
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
                                   "stamps": stamps}, indent=1), encoding="utf-8")


def read_tile_report(out: Path, name: str) -> dict | None:
    try:
        rep = json.loads(tile_report_file(out, name).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # none (a run killed after the rasters, or before this version) or unreadable
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



# --- the marks of the other tile commands (chm, metrics, fuels, normalize, ground) ------------------------------------

def run_fingerprint(run) -> dict:
    """The settings a tile's outputs depend on, as JSON values: the fields of the command's resolved run (lengths in
    the tiles' units), without where it writes."""
    import dataclasses

    fields = dataclasses.asdict(run) if dataclasses.is_dataclass(run) else dict(run)
    fields.pop("out", None)
    return json.loads(json.dumps(fields, default=str))


HORIZONTAL = ("cell_size", "buffer", "column", "tin_max_edge")  # run fields in the tiles' horizontal unit


def _shown(key: str, value, unit: str = "") -> str:
    if key in HORIZONTAL and isinstance(value, (int, float)) and unit:
        return f"{value:.6g} {unit}"
    if key == "crs_wkt" and value:
        try:
            return crs_label(crs_from_wkt(value))
        except Exception:  # noqa: BLE001 - a damaged record: shown as it is
            return str(value)[:60]
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return ",".join(_shown("", v) for v in value)
    return "none" if value is None else str(value)[:80]


def _named(key: str) -> str:
    """A setting's name in a message: its option where it is a declared parameter (``--cell-size`` on the command
    line), else the record's own word."""
    from ..parameters.core import PARAMETERS

    return option(key) if key in PARAMETERS else key.replace("_", " ")


def _keys(earlier: dict, now: dict) -> list:
    """The settings' names in the run's order, then those only the earlier record has."""
    return [*now, *(k for k in earlier if k not in now)]


def _same(key: str, old, new) -> bool:
    if key == "crs_wkt" and old and new and old != new:
        try:
            return crs_from_wkt(old).equals(crs_from_wkt(new))
        except Exception:  # noqa: BLE001
            return False
    return old == new


def written_by_gistools(path: Path) -> bool:
    """Whether the raster ``path`` carries the tag every gistools raster has (``GISTOOLS_PRODUCT``)."""
    try:
        import rasterio

        with rasterio.open(path) as src:
            return "GISTOOLS_PRODUCT" in src.tags()
    except Exception:  # noqa: BLE001 - not a raster, unreadable: not known to be ours
        return False


def check_targets(targets) -> None:
    """Refuse, before any work, outputs gistools may not write: a product folder that is a link (the run would write
    into the folder it points to) or a file at an output's name that is a link."""
    from ..errors import OutputExistsError

    for target in targets:
        target = Path(target)
        for place in (target.parent, target):
            if place.is_symlink():
                raise OutputExistsError(f"{place} is a link (to {place.resolve()}); gistools writes only into "
                                        "folders and files it makes", path=place,
                                        hint="Remove the link or choose another output folder")


class TileMarks:
    """``OUT/tile_reports/<tile>.json`` of a command that writes files per tile: the settings the tile was made with,
    each output's stamp (size, time) as written and checked, and what the tile's run found. A rerun keeps a tile
    whose outputs are whole and whose settings are this run's, refuses one made with other settings (naming both
    values), remakes a damaged one, and refuses an output file gistools did not write (it is never replaced)."""

    def __init__(self, out: Path, command: str, settings: dict, check=raster_is_readable, ours=written_by_gistools,
                 unit: str = ""):
        self.out, self.command, self.settings, self.unit = Path(out), command, settings, unit
        self.check, self.ours = check, ours

    def file(self, name: str) -> Path:
        return tile_report_file(self.out, name)

    def read(self, name: str) -> dict | None:
        try:
            value = json.loads(self.file(name).read_text(encoding="utf-8"))
        except (OSError, ValueError, UnicodeDecodeError, RecursionError):
            return None
        return value if isinstance(value, dict) and isinstance(value.get("settings"), dict) else None

    def kept(self, name: str, targets: dict, overwrite: bool) -> dict | None:
        """What the tile's earlier run found when its outputs ``targets`` ({key: path}) are kept, else None (the tile
        is made). Raises OutputExistsError for an output gistools did not write (also with ``overwrite``) and
        InputError for a complete tile made with other settings (unless ``overwrite``)."""
        from ..errors import OutputExistsError

        check_targets(targets.values())
        mark = self.read(name)
        listed = (mark or {}).get("stamps") if isinstance((mark or {}).get("stamps"), dict) else {}
        for key, path in targets.items():
            path = Path(path)
            if path.exists() and listed.get(key) != file_stamp(path) and not self.ours(path) and (
                    key not in listed or self.check(path)):  # not a damaged file of ours: someone else's
                raise OutputExistsError(f"a file gistools did not write is in the way of tile {name}'s output",
                                        path=path, hint="Move or rename it, or choose another output folder")
        if overwrite or mark is None or not all(Path(p).exists() for p in targets.values()):
            return None
        earlier = mark["settings"]
        for key in _keys(earlier, self.settings):
            if not _same(key, earlier.get(key), self.settings.get(key)):
                raise InputError(
                    f"{self.out}: tile {name} was made with {_named(key)} {_shown(key, earlier.get(key), self.unit)}, this "
                    f"run asks {_shown(key, self.settings.get(key), self.unit)}",
                    hint=f"Pass {option('overwrite')} to redo the tiles with the new settings, or choose another "
                         f"{option('out')}")
        for key, path in targets.items():
            if listed.get(key) != file_stamp(path) and not self.check(path):
                log.warning("%s: damaged, recomputing the tile", path)
                return None
        return mark.get("found") if isinstance(mark.get("found"), dict) else {}

    def write(self, name: str, outputs: dict, found: dict) -> None:
        """The tile's mark, once all its ``outputs`` ({key: path}) are written and checked."""
        stamps = {k: file_stamp(p) for k, p in outputs.items()}
        with atomic_path(self.file(name), overwrite=True) as tmp:
            tmp.write_text(json.dumps({"command": self.command, "settings": self.settings, "stamps": stamps,
                                       "found": json.loads(json.dumps(found, default=str))}, indent=1),
                           encoding="utf-8")


def input_stamp(path) -> dict | None:
    """What a rerun compares to tell an input changed: its size, modification time and the SHA-256 of its first and
    last MiB (a rewritten file differs in one of them, without reading a large raster whole); None where it cannot
    be read."""
    import hashlib

    try:
        path = Path(path)
        st = path.stat()
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            digest.update(fh.read(1 << 20))
            if st.st_size > 2 << 20:
                fh.seek(-(1 << 20), 2)
                digest.update(fh.read(1 << 20))
        return {"size": int(st.st_size), "mtime_ns": int(st.st_mtime_ns), "sha256_ends": digest.hexdigest()}
    except OSError:
        return None


def rerun_plan(previous: dict | None, tool: str, source: str, settings: dict, targets: dict, overwrite: bool,
               ignore=("products",)) -> list:
    """The outputs (keys of ``targets``: {key: path}) a rerun of a one-input command keeps; every other target is
    (re)made. ``previous`` is the folder's report.json, whose ``made`` (made_record) says how each output was made.
    Kept: made by the same command from the same input, unchanged since (input_stamp), with the same settings (but
    ``ignore``), and whole (its recorded stamp, or opened and read whole now). Made again with a log line: a damaged
    output, one of an input that changed since, one of gistools with no record (a run stopped before writing it).
    Refused before any work: an output of other settings or another input unless ``overwrite`` (InputError naming
    both values); with or without ``overwrite``, a file gistools did not write or a link (OutputExistsError)."""
    check_targets(targets.values())
    existing = {k: Path(p) for k, p in targets.items() if Path(p).exists()}
    made = (previous or {}).get("made") if (previous or {}).get("tool") == tool else None
    made = made if isinstance(made, dict) else {}
    _refuse_foreign(existing, made)
    if overwrite or not existing:
        return []
    now = {**{k: v for k, v in settings.items() if k not in ignore}, "input": source}
    return [key for key, path in existing.items() if _keeps(path, made.get(key), now, source, ignore)]


def _refuse_foreign(existing: dict, made: dict) -> None:
    """OutputExistsError for an output file gistools did not write (a damaged file of its own is not refused)."""
    from ..errors import OutputExistsError

    for key, path in existing.items():
        damaged_ours = isinstance(made.get(key), dict) and not raster_is_readable(path)
        if not damaged_ours and not written_by_gistools(path):
            raise OutputExistsError("a file gistools did not write is in the way", path=path,
                                    hint="Move or rename it, or choose another output folder")


def refuse_other_settings(what: str, before: dict, now: dict) -> None:
    """InputError at the first setting whose value differs between an earlier run (``before``) and this one:
    "<what> with --code 4E, this run asks 4D", and the fix (--overwrite, or another --out)."""
    for name in _keys(before, now):
        if before.get(name) != now.get(name):
            raise InputError(f"{what} with {_named(name)} {_shown(name, before.get(name))}, this run asks "
                             f"{_shown(name, now.get(name))}",
                             hint=f"Pass {option('overwrite')} to make it again with the new settings, or choose "
                                  f"another {option('out')}")


def _keeps(path: Path, entry, now: dict, source: str, ignore) -> bool:
    """Whether the existing output ``path``, made as ``entry`` says (made_record), is kept by a run of ``now``."""
    if not isinstance(entry, dict) or not isinstance(entry.get("settings"), dict):
        log.info("%s: no record of how it was made: making it again", path)
        return False
    before = {**{k: v for k, v in entry["settings"].items() if k not in ignore}, "input": entry.get("input")}
    refuse_other_settings(f"{path} was made", before, now)
    if entry.get("input_stamp") != input_stamp(source):
        log.warning("%s changed since %s was made: making it again", source, path.name)
        return False
    if entry.get("stamp") == file_stamp(path) or raster_is_readable(path):
        return True
    log.warning("%s: damaged, made again", path)
    return False


def made_record(previous: dict | None, tool: str, source: str, settings: dict, paths: dict) -> dict:
    """report.json's ``made``: how each output of the folder was made ({key: path, stamp, settings, input,
    input_stamp}), the earlier runs' entries whose files are still there as they were, and this run's ``paths``."""
    made = (previous or {}).get("made") if (previous or {}).get("tool") == tool else None
    made = {k: v for k, v in (made or {}).items() if isinstance(v, dict) and k not in paths
            and Path(str(v.get("path"))).exists() and v.get("stamp") == file_stamp(v.get("path"))}
    stamp = input_stamp(source)
    for key, path in paths.items():
        made[key] = {"path": str(path), "stamp": file_stamp(path), "settings": settings, "input": str(source),
                     "input_stamp": stamp}
    return made


def _json_normal(value):
    """``value`` as report.json gives it back (tuples as lists, paths and other objects as text)."""
    return json.loads(json.dumps(value, default=str))


def _input_paths(inputs) -> list[Path]:
    """The files behind ``inputs``: a path, a layer ``file.gpkg:LAYER``, a per-layer file ``LAYER=path``, a dict of
    them, or a list; a shapefile with its sidecars (.dbf, .shx, .prj hold what it reads too)."""
    from ..io.contacts import is_layer_file
    from ..io.vector import split_layer_spec

    if isinstance(inputs, dict):
        inputs = list(inputs.values())
    items = inputs if isinstance(inputs, (list, tuple)) else [inputs]
    paths = []
    for item in items:
        if item is None or (hasattr(item, "geom_type") and not isinstance(item, (str, Path))):
            continue  # a geometry given as such: its value is among the settings
        text = str(item).split("=", 1)[1] if is_layer_file(item) else str(item)
        path = split_layer_spec(text)[0]
        paths.append(path)
        if path.suffix.lower() == ".shp":
            paths += [path.with_suffix(s) for s in (".dbf", ".shx", ".prj") if path.with_suffix(s).exists()]
    return paths


def _output_files(outputs) -> list[str]:
    """Every file path of a report's ``outputs`` (nested dicts and lists of paths)."""
    if isinstance(outputs, dict):
        return [p for v in outputs.values() for p in _output_files(v)]
    if isinstance(outputs, (list, tuple)):
        return [p for v in outputs for p in _output_files(v)]
    return [str(outputs)] if isinstance(outputs, str) and Path(outputs).suffix else []


def run_record(settings: dict, inputs, outputs) -> dict:
    """report.json's ``made`` of a command that makes its outputs together (aquifer, runway, structure): the
    settings, each input's stamp and each output's stamp, what ``kept_run`` compares on a rerun."""
    return {"settings": _json_normal(settings),
            "inputs": {str(p): input_stamp(p) for p in _input_paths(inputs)},
            "outputs": {p: file_stamp(p) for p in _output_files(outputs) if Path(p).is_file()}}


def kept_run(out: Path, tool: str, settings: dict, inputs, overwrite: bool) -> dict | None:
    """The rerun of a command that makes its outputs together, as every command reruns: the record of an earlier
    run of ``tool`` in ``out`` that is kept (made with these ``settings`` from the same ``inputs``, unchanged
    since, its outputs all there as written), or None: none there, ``overwrite``, or an input changed or an output
    is missing or changed since (made again, with a log line). Refused before any work unless ``overwrite``: an
    earlier run of other settings (InputError naming the first difference), or one that did not record how it
    was made (OutputExistsError)."""
    from ..errors import OutputExistsError
    from ..io.outdir import check_record
    from .record import read_folder_report

    check_record(out, tool)  # a folder of another command, or a report.json gistools did not write: refused now
    previous = read_folder_report(out)
    if overwrite or not previous or previous.get("tool") != tool:
        return None
    made = previous.get("made")
    if not isinstance(made, dict) or not isinstance(made.get("settings"), dict):
        raise OutputExistsError(f"the outputs of an earlier {tool} that did not record its settings are there",
                                path=out, hint=f"Pass {option('overwrite')} to replace them, or choose another "
                                               f"{option('out')}")
    before, now = made["settings"], _json_normal(settings)
    refuse_other_settings(f"{out} holds a run of {tool}", before, now)
    inputs_now = {str(p): input_stamp(p) for p in _input_paths(inputs)}
    if made.get("inputs") != _json_normal(inputs_now) or None in inputs_now.values():
        log.warning("%s: an input changed since the earlier run (or cannot be checked): making the outputs again", out)
        return None
    outputs = made.get("outputs") or {}
    changed = [p for p, stamp in outputs.items() if not Path(p).is_file() or file_stamp(p) != stamp]
    if changed or not outputs:
        log.warning("%s: %s missing or changed since it was written: making the outputs again", out,
                    changed[0] if changed else "an output")
        return None
    log.info("%s: the outputs of an earlier run with the same settings are there: kept", out)
    return previous


def rerun_kept(out: Path, tool: str, settings: dict, inputs, overwrite: bool, started: float) -> dict | None:
    """``kept_run``; when the earlier run is kept, its record written again with this run's line (``kept``: its
    outputs' keys) and returned. None: the command makes its outputs."""
    import time

    from ..io.outdir import claim_output
    from .record import write_folder_report

    previous = kept_run(out, tool, settings, inputs, overwrite)
    if previous is None:
        return None
    rep = {k: v for k, v in previous.items() if k not in ("schema", "version")}
    rep.update(kept=sorted(previous.get("outputs") or {}), seconds=round(time.time() - started, 3))
    with claim_output(out, tool):
        return write_folder_report(out, rep)
