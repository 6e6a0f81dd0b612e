"""report.json: the record of an output folder (what its products were made with) and of each command run on it.

Every command that writes into a folder adds its line to ``runs`` (tool, when, seconds, counts, settings), so a
rerun records what it used. A command that makes only part of a folder's products (``gistools rasters`` on a folder
of the shrub chain) updates its own keys and keeps the others (class and band areas, the steps' settings).

Every record has the envelope of ``gistools/schemas/report.schema.json`` (schema, tool, version, counts, seconds,
warnings, runs; tiles where the command has tiles); :func:`write_folder_report` is the one writer.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from ..io.raster import atomic_path

__all__ = ["run_record", "write_folder_report", "read_folder_report", "add_run", "MAX_RUNS", "SCHEMA", "SCHEMA_FILE"]

SCHEMA = "gistools-report/1"  # the envelope's name and version (report.schema.json)
SCHEMA_FILE = Path(__file__).resolve().parent.parent / "schemas" / "report.schema.json"
MAX_RUNS = 50  # the lines kept in report.json["runs"], newest last

# the keys of the shrub chain's record that gistools rasters does not make (kept when it reruns on such a folder)
CHAIN_KEYS = ("area_unit", "band_thresholds", "band_unit", "density_radius", "density_bands", "class_breaks", "class_method",
              "band_area", "band_area_from_returns", "class_area", "class_area_acres", "nodata_share", "nodata_by_cause",
              "settings", "map_title")


def run_record(report: dict) -> dict:
    """One command's line in report.json["runs"]: what ran, when, how long, with what, and how it went."""
    from .._version import __version__

    return {"tool": report.get("tool"), "version": __version__, "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "seconds": report.get("seconds"), "counts": report.get("counts"),
            **({"settings": report["settings"]} if "settings" in report else {}),
            "warnings": len(report.get("warnings") or [])}


def envelope(report: dict) -> dict:
    """``report`` with the keys every record has: schema, version, counts (one input made where a command has no
    tiles), each tile's warnings as a list, and ``warnings``: the run's own and each tile's, named by tile."""
    from .._version import __version__

    rep = {"schema": SCHEMA, "tool": report.get("tool"), "version": __version__}
    rep.update((k, v) for k, v in report.items() if k not in ("schema", "version"))
    rep.setdefault("counts", {"ok": 1, "skipped": 0, "failed": 0})
    if isinstance(report.get("tiles"), list):
        rep["tiles"] = [{**t, "warnings": list(t.get("warnings") or [])} for t in report["tiles"]]
    rep["warnings"] = _run_warnings(report.get("warnings"), rep.get("tiles") or [])
    return rep


def _run_warnings(own, tiles: list) -> list[str]:
    """The run's own warnings (those not already a tile's) and each tile's, named by its tile."""
    by_tile = [f"{t.get('name')}: {w}" for t in tiles for w in t["warnings"]]
    from ..parameters import render

    return [render(w) for w in map(str, own or []) if w not in by_tile] + [render(w) for w in by_tile]


def _plain(value):
    """JSON for what json does not know: numpy numbers and arrays as numbers, anything else (paths) as text."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


def read_folder_report(out) -> dict | None:
    """The folder's report.json, or None where there is none (or it is not a JSON object)."""
    path = Path(out) / "report.json"
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return value if isinstance(value, dict) else None


def write_folder_report(out, report: dict, *, partial: bool = False) -> dict:
    """Write ``report`` as ``out/report.json`` (atomic), with the earlier runs' lines and this one's; returns what was
    written. ``partial``: the command made only some of the folder's products (gistools rasters): the earlier
    record's keys of the chain and its tiles' other fields are kept, where it is of the same CRS."""
    previous = read_folder_report(out) or {}
    merged = envelope(report)
    if partial and previous.get("crs_wkt") == report.get("crs_wkt") and "class_area" in previous:
        merged = {**{k: previous[k] for k in CHAIN_KEYS if k in previous}, **merged}
        before = {t.get("name"): t for t in previous.get("tiles", []) if isinstance(t, dict)}
        merged["tiles"] = [{**before.get(t["name"], {}), **t} for t in merged.get("tiles", [])]
        merged["mosaics"] = {**previous.get("mosaics", {}), **report.get("mosaics", {})}
        if any(t.get("status") == "ok" for t in report.get("tiles", [])):
            merged["steps_predate_rasters"] = True  # rasters remade: the bands ... classes are of the earlier ones
    runs = previous.get("runs") if isinstance(previous.get("runs"), list) else []
    merged["runs"] = [*runs[-(MAX_RUNS - 1):], run_record(merged)]
    with atomic_path(Path(out) / "report.json", overwrite=True) as tmp:
        tmp.write_text(json.dumps(merged, indent=2, default=_plain), encoding="utf-8")
    return merged


def add_run(out, report: dict) -> None:
    """Add one command's line to ``out/report.json``'s ``runs``, the rest of the record as it was (the field
    deliverables: a web map, a scene, a map book made from the chain's folder)."""
    previous = read_folder_report(out)
    if previous is None:
        return
    runs = previous.get("runs") if isinstance(previous.get("runs"), list) else []
    previous["runs"] = [*runs[-(MAX_RUNS - 1):], run_record(report)]
    with atomic_path(Path(out) / "report.json", overwrite=True) as tmp:
        tmp.write_text(json.dumps(previous, indent=2, default=_plain), encoding="utf-8")
