"""LAS / LAZ tiles to point layers (the dissertation's LAS To Multipoint, S1).

One layer per tile with x, y, z, class, return number and intensity, streamed in
chunks: GeoPackage by default, GeoParquet (needs pyarrow) for tiles of millions of points.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..docstrings import shared_sections
from ..engine.batch import run_each
from ..engine.passes import TileState
from ..engine.record import write_folder_report
from ..errors import GistoolsError, InputError, raise_if_every_tile_failed
from ..io.outdir import output_folder
from ..io.points import DEFAULT_CHUNK_SIZE, common_crs, crs_label, iter_chunks, parse_crs_text, read_tile_info
from ..io.outdir import claim_output
from ..io.raster import atomic_path
from ..io.vector import GPKG_OPTIONS
from ..parameters import check, choices, default_for, option
from ..parameters.lidar import COMMAND_DEFAULTS, current_word
from ..io.tiles import find_tiles
from ..progress import ProgressCallback, report

__all__ = ["points_from_tiles", "RETURNS"]

RETURNS = choices("returns")  # declared in gistools.parameters.lidar: the same words as gistools metrics


def _select(chunk, classes, returns):
    keep = ~chunk.withheld
    if classes is not None:
        keep &= np.isin(chunk.classification, classes)
    if returns == "first":
        keep &= chunk.return_number <= 1
    elif returns == "last":
        keep &= chunk.return_number >= chunk.number_of_returns
    return keep


def _write_tile(info, path: Path, classes, returns, fmt, chunk_size) -> int:
    import geopandas as gpd
    import shapely

    crs = info.crs.sub_crs_list[0] if info.crs.is_compound else info.crs
    written = 0
    with atomic_path(path, overwrite=True, keep_suffix=True) as tmp_named:
        parts = []
        for chunk in iter_chunks(info, chunk_size, intensity=True, only_fields=True):
            keep = _select(chunk, classes, returns)
            if not keep.any():
                continue
            gdf = gpd.GeoDataFrame(
                {"z": chunk.z[keep], "class": chunk.classification[keep], "return_number": chunk.return_number[keep],
                 "intensity": chunk.intensity[keep]},
                geometry=shapely.points(chunk.x[keep], chunk.y[keep]), crs=crs)
            gdf.insert(0, "y", chunk.y[keep])
            gdf.insert(0, "x", chunk.x[keep])
            written += len(gdf)
            if fmt == "gpkg":
                first = not tmp_named.exists()
                gdf.to_file(tmp_named, layer="points", driver="GPKG", mode="w" if first else "a",
                            **(GPKG_OPTIONS if first else {}))
            else:
                parts.append(gdf)
        if fmt == "parquet":
            frame = gpd.GeoDataFrame(gpd.pd.concat(parts, ignore_index=True), crs=crs) if parts else \
                gpd.GeoDataFrame({"x": [], "y": [], "z": []}, geometry=[], crs=crs)
            frame.to_parquet(tmp_named)
        elif not tmp_named.exists():  # no point selected: an empty layer
            gpd.GeoDataFrame({"x": [], "y": [], "z": []}, geometry=gpd.GeoSeries([], crs=crs)).to_file(
                tmp_named, layer="points", driver="GPKG", **GPKG_OPTIONS)
    return written


@shared_sections
def points_from_tiles(inputs, out, *, classes=COMMAND_DEFAULTS["points"]["classes"], returns: str = default_for("returns"),
                      fmt: str = default_for("fmt"), crs: str | None = None, overwrite: bool = False,
                      chunk_size: int = DEFAULT_CHUNK_SIZE, progress: ProgressCallback | None = None) -> dict:
    """Point layers of the chosen classes and returns of each tile of ``inputs``: ``gistools points``.

    Writes ``out/<tile>.gpkg`` (or ``.parquet``: a point per LiDAR point, with x, y, z, class, return number and
    intensity) and ``out/report.json``. Tiles whose output exists are kept unless ``overwrite``; a tile that fails
    is reported and the others go on.

    Parameters
    ----------
    {tiles_in}
    classes : sequence of int, optional
        ASPRS class codes kept; None: every class.
    returns : str
        ``"first"``, ``"last"`` or ``"all"``.
    fmt : str
        ``"gpkg"`` (GeoPackage) or ``"parquet"`` (GeoParquet, needs pyarrow).
    crs : str, optional
        The tiles' CRS (e.g. ``"EPSG:2882"``) when their headers carry none or a wrong one.
    overwrite : bool
        Remake tiles whose output exists.
    chunk_size : int
        Points read at a time (bounds memory).
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels the run.

    Returns
    -------
    dict
        The run's report, also written to ``out/report.json``: ``counts`` (ok, failed, skipped), ``tiles`` (each
        with its point count and output).

    {tiles_raise}

    Examples
    --------
    >>> from gistools import points_from_tiles
    >>> points_from_tiles("sample_tiles", "ground_points", classes=[2])["counts"]  # doctest: +SKIP
    {'ok': 4, 'failed': 0, 'skipped': 0}
    """
    returns = current_word("returns", returns)
    check("classes", classes)
    check("returns", returns)
    check("fmt", fmt)
    if fmt == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError as err:
            raise InputError(f"GeoParquet needs pyarrow, which does not import ({err})",
                             hint=f"pip install 'gistools[parquet]', or use {option('fmt', 'gpkg')}") from None
    check("chunk_size", chunk_size)
    out = output_folder(out)
    override = parse_crs_text(crs) if crs else None
    paths = find_tiles(inputs)
    started = time.time()
    with claim_output(out, "gistools points"):
        rep = _points_in(paths, out, override, classes, returns, fmt, overwrite, chunk_size, progress)
        rep["settings"] = {"classes": rep["classes"], "returns": returns, "fmt": fmt, "crs": crs, "chunk_size": chunk_size}
        rep["seconds"] = round(time.time() - started, 3)
        return raise_if_every_tile_failed(write_folder_report(out, rep))


@dataclass
class _TileState(TileState):
    points: int = 0
    output: str | None = None
    seconds: float = 0.0


def _write_named(name: str, info, target: Path, classes, returns, fmt, chunk_size) -> int:
    """_write_tile of the tile ``name`` (the engine's task: its first argument names the tile)."""
    return _write_tile(info, target, classes, returns, fmt, chunk_size)


def _points_in(paths, out: Path, override, classes, returns, fmt, overwrite, chunk_size, progress) -> dict:
    states = {p.stem: _TileState(p.stem, str(p)) for p in paths}
    infos = {}
    for p in paths:
        try:
            infos[p.stem] = read_tile_info(p, override)
        except GistoolsError as err:
            states[p.stem].status, states[p.stem].error = "failed", str(err)
    if infos:
        common_crs(list(infos.values()))
    targets = {name: out / f"{info.name}.{fmt}" for name, info in infos.items()}
    todo = [name for name in infos if overwrite or not targets[name].exists()]
    for name in set(infos) - set(todo):
        states[name].status, states[name].output = "skipped", str(targets[name])
    keep = None if classes is None else tuple(classes)
    done = []

    def on_done(name, points, seconds):
        states[name].points, states[name].output, states[name].seconds = points, str(targets[name]), round(seconds, 3)

    def tick(message):
        done.append(message)
        report(progress, len(done) / len(todo), message)

    # the engine's task loop, in this process: each tile read in chunks; a bad tile reported, a full disk stops
    run_each(_write_named, [(n, infos[n], targets[n], keep, returns, fmt, chunk_size) for n in todo], None, states,
             todo, on_done, tick, "written", out)
    tiles = [asdict(st) for st in states.values()]
    return {
        "tool": "gistools points",
        "crs": crs_label(next(iter(infos.values())).crs) if infos else None,
        "classes": None if classes is None else list(classes),
        "returns": returns,
        "tiles": tiles,
        "counts": {s: sum(t["status"] == s for t in tiles) for s in ("ok", "failed", "skipped")},
    }
