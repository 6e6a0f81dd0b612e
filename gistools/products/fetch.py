"""The points of an area from a point cloud service (EPT, COPC; over HTTP(S) or a local copy) as LAS/LAZ tiles on
an absolute lattice: the tiles every command of gistools takes, each node of the service fetched once.

The area's octree nodes (gistools.io.area) are fetched once each into ``out/.nodes/`` (numpy archives, written
whole or not at all), then cut into tiles of ``tile_size`` on the lattice of its multiples (a point on a tile's
west or south edge belongs to it, one on its east or north edge to the next), each tile keeping only the points
inside the area. A rerun keeps the nodes and the tiles it finds, so it fetches nothing.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..engine.record import write_folder_report
from ..engine.resume import rerun_kept, run_record
from ..errors import InputError
from ..io.area import FIELDS, area_box, open_source
from ..io.atomic import atomic_path
from ..io.http import RangeClient, is_url
from ..io.outdir import claim_output, output_folder
from ..progress import ProgressCallback, report

NODES = ".nodes"


def _write_points(path: Path, points: dict, crs_wkt, scales, offsets, origin) -> None:
    """A LAZ tile (LAS 1.4, point format 6) of ``points``, on the source's scales (offsets moved by whole steps of
    them, so every coordinate keeps its value)."""
    import laspy
    import pyproj

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.asarray(scales, np.float64)
    header.offsets = np.array([offsets[i] + round((origin[i] - offsets[i]) / scales[i]) * scales[i] for i in range(3)])
    if crs_wkt:
        header.add_crs(pyproj.CRS.from_user_input(crs_wkt))
    las = laspy.LasData(header)
    las.x, las.y, las.z = points["x"], points["y"], points["z"]
    for name in ("classification", "return_number", "number_of_returns", "intensity"):
        setattr(las, name, points[name])
    with atomic_path(path, overwrite=True) as tmp:
        las.write(str(tmp), laz_backend=laspy.LazBackend.Lazrs if tmp.suffix == ".laz" else None)


def _cached_node(source, node, folder: Path) -> dict:
    """A node's points, from the cache when fetched before, else fetched and kept there."""
    path = folder / f"{node.name}.npz"
    if path.exists():
        with np.load(path) as cached:
            return {name: cached[name] for name in FIELDS}
    points = source.node_points(node)
    with atomic_path(path, overwrite=True) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **points)
    return points


def fetch_area(source, out, *, aoi, resolution: float | None = None, tile_size: float = 500.0,
               max_download: float | None = None, overwrite: bool = False, client: RangeClient | None = None,
               progress: ProgressCallback | None = None) -> dict:
    """The points of an area of a point cloud service as LAZ tiles on an absolute lattice.

    Parameters
    ----------
    source : str or path
        An EPT dataset (``https://host/path/ept.json``) or a COPC file (``https://host/x.copc.laz``), or a local
        copy of either.
    out : str or path
        The tiles' folder, made when missing (the fetched nodes are kept in ``out/.nodes``).
    aoi : sequence of 4 floats or shapely geometry
        The area, in the dataset's CRS: (minx, miny, maxx, maxy) or a polygon.
    resolution : float, optional
        Read only the octree depths whose point spacing is at least this fine (CRS units); None: every point.
    tile_size : float
        The tiles' side, CRS units, on the lattice of its multiples.
    max_download : float, optional
        Refuse an area whose nodes hold more bytes (COPC: the hierarchy's sizes; EPT: 12 bytes a point, a LAZ
        point's usual size) before anything is fetched.
    overwrite : bool
        Fetch and write again; without it a rerun of the same source, area, resolution and tile size keeps the
        tiles (nothing is fetched), one of other settings is refused.
    client : RangeClient, optional
        The network client (its counts say what was fetched).
    progress : callable, optional
        ``progress(fraction, message)``, told after each node and tile; returning False cancels.

    Returns
    -------
    dict
        ``outputs`` (``tiles``: the paths written or kept), ``tiles`` (each tile's line), ``points``, ``nodes``,
        ``estimate`` (``points``, ``bytes``),
        ``fetched_bytes`` and ``kept_tiles``; also written to ``out/report.json``.

    Raises
    ------
    InputError
        The area is empty, or holds more than ``max_download``.
    DataFileError
        The service cannot give the dataset, or a node does not decode.

    Examples
    --------
    >>> report = fetch_area("https://host/ept.json", "tiles", aoi=(0, 0, 1000, 1000))  # doctest: +SKIP
    >>> len(report["tiles"])  # doctest: +SKIP
    4
    """
    started = time.time()
    if not tile_size or tile_size <= 0:
        raise InputError(f"tile_size={tile_size!r}: a tile's side is a positive length", hint="e.g. 500 (CRS units)")
    w, s, e, n = area_box(aoi)
    now = {"source": str(source), "aoi": aoi.wkt if hasattr(aoi, "wkt") else [w, s, e, n],
           "resolution": resolution, "tile_size": float(tile_size)}
    local = [] if is_url(str(source)) else [source]
    out = output_folder(out)
    kept_run = rerun_kept(out, "gistools fetch", now, local, overwrite, started)
    if kept_run is not None:  # the same area fetched before, its tiles as they were written: nothing is fetched
        return kept_run
    client = client or RangeClient()
    src = open_source(source, client)
    nodes = src.octree_nodes(aoi, resolution)
    plan = _checked_plan(src, aoi, resolution, max_download, source)
    lattice = [(i * tile_size, j * tile_size)
               for i in range(int(np.floor(w / tile_size)), int(np.floor(e / tile_size)) + 1)
               for j in range(int(np.floor(s / tile_size)), int(np.floor(n / tile_size)) + 1)]
    with claim_output(out, "gistools fetch"):
        tiles, kept, count = _write_tiles(src, nodes, lattice, aoi, tile_size, out, overwrite, progress)
        rep = {"tool": "gistools fetch", "source": str(source), "crs_wkt": src.crs_wkt, "settings": now,
               "outputs": {"tiles": tiles}, "tiles": [{"name": Path(t).stem, "status": "skipped" if t in kept else "ok"}
                                                      for t in tiles],
               "counts": {"ok": len(tiles) - len(kept), "skipped": len(kept), "failed": 0}, "kept_tiles": kept,
               "points": count, "nodes": len(nodes), "estimate": {"points": plan.points, "bytes": plan.bytes},
               "fetched_bytes": client.bytes_fetched, "seconds": round(time.time() - started, 3),
               "made": run_record(now, local, {"tiles": tiles})}
        return write_folder_report(out, rep)


def _checked_plan(src, aoi, resolution, max_download, source):
    """The area's plan (its bytes estimated at 12 a point where the hierarchy does not say them), refused past
    ``max_download`` before any point is fetched."""
    plan = src.plan(aoi, resolution)
    estimate = plan.bytes if plan.bytes is not None else 12 * plan.points
    if max_download is not None and estimate > max_download:
        raise InputError(f"the area holds {plan.points:,} points in {plan.nodes} nodes, about {estimate / 1e6:,.1f} MB, "
                         f"more than the {max_download / 1e6:,.1f} MB allowed", path=str(source),
                         hint="Give a smaller area, a coarser resolution, or a larger max_download")
    return type(plan)(plan.nodes, plan.points, estimate)


def _write_tiles(src, nodes, lattice, aoi, tile_size, out: Path, overwrite, progress) -> tuple[list, list, int]:
    """Every node fetched once into ``out/.nodes``, then the tiles of the lattice that hold points of the area
    written (kept where they are there, unless ``overwrite``): (tiles, kept tiles, points written)."""
    scales, offsets = src.scales_offsets()
    steps = len(nodes) + len(lattice)
    cache = out / NODES
    cache.mkdir(exist_ok=True)
    for k, node in enumerate(nodes):
        _cached_node(src, node, cache)
        report(progress, (k + 1) / steps, f"node {node.name}")
    tiles, kept, count = [], [], 0
    for k, (x0, y0) in enumerate(lattice):
        path = out / f"{x0:.0f}_{y0:.0f}.laz"
        if path.exists() and not overwrite:
            tiles.append(str(path))
            kept.append(str(path))
            continue
        parts = [_cached_node(src, nd, cache) for nd in nodes if nd.bounds[0] < x0 + tile_size
                 and nd.bounds[2] >= x0 and nd.bounds[1] < y0 + tile_size and nd.bounds[3] >= y0]
        points = _in_tile(parts, aoi, x0, y0, tile_size)
        if len(points["x"]):
            _write_points(path, points, src.crs_wkt, scales, offsets, (x0, y0, 0.0))
            tiles.append(str(path))
            count += len(points["x"])
        report(progress, (len(nodes) + k + 1) / steps, path.name)
    return tiles, kept, count


def _in_tile(parts: list, aoi, x0: float, y0: float, size: float) -> dict:
    """The points of ``parts`` in the tile [x0, x0 + size) x [y0, y0 + size) and inside the area."""
    from ..io.area import _cut

    joined = _cut(parts, aoi)
    keep = (joined["x"] >= x0) & (joined["x"] < x0 + size) & (joined["y"] >= y0) & (joined["y"] < y0 + size)
    return {name: values[keep] for name, values in joined.items()}
