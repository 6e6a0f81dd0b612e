"""Header facts, CRS, units and point counts of tiles (``gistools info``, ``gistools:info``)."""

from __future__ import annotations

import json

import numpy as np

from ..errors import GistoolsError
from ..parameters import option, render
from ..io.atomic import atomic_path
from ..io.points import crs_label, iter_chunks, read_tile_info
from ..io.tiles import find_tiles
from ..progress import ProgressCallback, report

__all__ = ["tile_summary", "tiles_summary"]


def tile_summary(path, crs=None) -> dict:
    """Header facts plus point counts by class and by return (reads every point, in chunks). A file without a
    usable CRS is summarised too: ``crs`` "no CRS", units None, and ``crs_note`` says what is wrong."""
    info = read_tile_info(path, crs, require_crs=False)
    by_class = np.zeros(256, np.int64)
    by_return = np.zeros(16, np.int64)
    for chunk in iter_chunks(info, only_fields=True):
        by_class += np.bincount(chunk.classification, minlength=256)[:256]
        by_return += np.bincount(np.minimum(chunk.return_number, 15), minlength=16)[:16]
    return {
        "file": str(info.path),
        "las_version": info.version,
        "point_format": info.point_format,
        "compressed": info.compressed,
        "points": info.point_count,
        "bounds": info.bounds,
        "z_range": info.z_range,
        "scales": info.scales,
        "offsets": info.offsets,
        "crs": crs_label(info.crs),
        "crs_source": None if info.crs is None else "file" if info.crs_from_file else "given",
        "crs_note": info.crs_note if info.crs is not None or info.crs_note else
        render(f"the header has no CRS: give one with {option('crs')} to use the file"),
        "horizontal_unit": _unit_name(info, "unit"),
        "vertical_unit": _unit_name(info, "z_unit"),
        "points_by_class": {int(c): int(n) for c, n in enumerate(by_class) if n},
        "points_by_return": {int(r): int(n) for r, n in enumerate(by_return) if n},
    }


def _unit_name(info, which: str):
    if info.crs is None:
        return None
    try:
        return getattr(info, which).name
    except GistoolsError:  # a geographic CRS: no linear unit
        return None


def tiles_summary(inputs, *, crs=None, out=None, progress: ProgressCallback | None = None) -> dict:
    """:func:`tile_summary` of every tile of ``inputs``; a tile that cannot be read is listed with its error.

    ``out``: also write the summary there as JSON (atomically; an existing file is replaced).
    """
    paths = find_tiles(inputs)
    tiles = []
    for k, path in enumerate(paths):
        try:
            tiles.append({"status": "ok", **tile_summary(path, crs)})
        except GistoolsError as err:
            tiles.append({"status": "failed", "file": str(path), "error": str(err)})
        report(progress, (k + 1) / len(paths), path.name)
    ok = [t for t in tiles if t["status"] == "ok"]
    summary = {
        "tool": "gistools info",
        "tiles": tiles,
        "counts": {s: sum(t["status"] == s for t in tiles) for s in ("ok", "failed")},
        "points": sum(t["points"] for t in ok),
        "crs": sorted({t["crs"] for t in ok}),
    }
    if out is not None:
        with atomic_path(out, overwrite=True) as tmp:
            tmp.write_text(json.dumps(summary, indent=2, default=str))
    return summary
