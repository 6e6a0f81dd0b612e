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
    """Header facts and point counts by class and by return of one LAS / LAZ file: ``gistools info``.

    Reads every point, in chunks. A file without a usable CRS is summarised too: its ``crs`` reads "no CRS", its units
    None, and ``crs_note`` says what is wrong.

    Parameters
    ----------
    path : str or path
        The LAS / LAZ file.
    crs : str, optional
        A CRS to use instead of the header's (e.g. ``"EPSG:2882"``).

    Returns
    -------
    dict
        ``file``, ``las_version``, ``point_format``, ``points``, ``bounds`` (CRS units), ``z_range`` (vertical unit),
        ``crs``, ``horizontal_unit``, ``vertical_unit``, ``points_by_class``, ``points_by_return``, ...

    Raises
    ------
    DataFileError
        The file is missing or not a readable LAS / LAZ file.

    Examples
    --------
    >>> from gistools import tile_summary
    >>> summary = tile_summary("sample_tiles/35712.las")  # doctest: +SKIP
    >>> summary["horizontal_unit"], summary["points_by_class"]  # doctest: +SKIP
    ('US survey foot', {1: 7556, 2: 59503})
    """
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
    """`tile_summary` of every tile of ``inputs``; a tile that cannot be read is listed with its error.

    Parameters
    ----------
    inputs : str, path or list
        LAS / LAZ files, folders (their tiles), glob patterns or a ``.vpc``.
    crs : str, optional
        A CRS to use instead of the headers' (e.g. ``"EPSG:2882"``).
    out : str or path, optional
        Also write the summary there as JSON (an existing file is replaced).
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels.

    Returns
    -------
    dict
        ``tiles`` (each tile's summary, with its ``status``), ``counts`` (ok, failed), ``points`` (their total) and
        ``crs`` (the CRS names found).

    Raises
    ------
    InputError
        ``inputs`` holds no tile.

    Examples
    --------
    >>> from gistools import tiles_summary
    >>> summary = tiles_summary("sample_tiles")  # doctest: +SKIP
    >>> summary["counts"], summary["points"]  # doctest: +SKIP
    ({'ok': 4, 'failed': 0}, 258950)
    """
    from ..engine.batch import run_each
    from ..engine.passes import TileState

    paths = find_tiles(inputs)
    keys = [str(k) for k in range(len(paths))]  # two folders may hold tiles of one name
    states = {k: TileState(p.name, str(p)) for k, p in zip(keys, paths)}
    found, ticks = {}, []

    def on_done(key, summary, _seconds):
        found[key] = summary

    def tick(_message):
        ticks.append(1)
        report(progress, len(ticks) / len(paths), paths[len(ticks) - 1].name)

    # the engine's task loop, in this process: a tile that cannot be read is listed with its error, the rest go on
    run_each(lambda key: tile_summary(paths[int(key)], crs), [(k,) for k in keys], None, states, keys, on_done, tick,
             "read")
    tiles = [{"status": "ok", **found[k]} if k in found else
             {"status": "failed", "file": str(paths[int(k)]), "error": states[k].error} for k in keys]
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
            tmp.write_text(json.dumps(summary, indent=2, default=str), encoding="utf-8")
    return summary
