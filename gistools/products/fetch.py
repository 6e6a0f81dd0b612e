"""The points of an area from a point cloud service (EPT, COPC; over HTTP(S) or a local copy) as LAS/LAZ tiles on
an absolute lattice: the tiles every command of gistools takes, each node of the service fetched once.

The area's octree nodes (gistools.io.area) are fetched once each into ``out/.nodes/`` (numpy archives, written
whole or not at all), then cut into tiles of ``tile_size`` on the lattice of its multiples (a point on a tile's
west or south edge belongs to it, one on its east or north edge to the next), each tile keeping only the points
inside the area. A rerun keeps the nodes and the tiles it finds, so it fetches nothing.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engine.record import write_folder_report
from ..engine.resume import rerun_kept, run_record
from ..errors import InputError
from ..io.area import FIELDS, PointSource, area_box, open_sources
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
    """A node's points, from the cache when fetched before, else fetched and kept there (a local file's are read
    where they are)."""
    if not getattr(source, "remote", True):
        return source.node_points(node)
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
               max_download: float | None = None, margin: float = 0.0, nodes=None, overwrite: bool = False,
               client: RangeClient | None = None, progress: ProgressCallback | None = None) -> dict:
    """The points of an area of a point cloud service as LAZ tiles on an absolute lattice.

    Parameters
    ----------
    source : str, path, sequence of them, or PointSource
        EPT datasets (``https://host/path/ept.json``), COPC files (``https://host/x.copc.laz``), VPCs, local copies
        of either, or LAS/LAZ tiles (files, folders, globs).
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
    margin : float
        The points within this distance outside the area (CRS units) are kept too, in the tiles that meet the
        area (what a product's cells at the area's edge see beyond it); no tile is made of the margin alone.
    nodes : str or path, optional
        Where the fetched nodes are kept (default ``out/.nodes``); a folder shared by the areas of one source.
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
        ``fetched_bytes`` (``kept`` where a rerun of the same settings kept them); also written to
        ``out/report.json``.

    Raises
    ------
    InputError
        The area is empty, or holds more than ``max_download``.
    DataFileError
        The service cannot give the dataset, or a node does not decode.

    Examples
    --------
    >>> report = fetch_area("sample_tiles", "out/area_tiles", aoi=(430400, 1810400, 431600, 1811600))
    >>> len(report["outputs"]["tiles"]), report["points"] > 0
    (16, True)
    """
    started = time.time()
    if not tile_size or tile_size <= 0:
        raise InputError(f"tile_size={tile_size!r}: a tile's side is a positive length", hint="e.g. 500 (CRS units)")
    w, s, e, n = area_box(aoi)
    client = client if client is not None else getattr(source, "client", None) or RangeClient()
    items = [source] if isinstance(source, (str, Path)) else source
    served = isinstance(source, PointSource) or all(is_url(str(i)) for i in items)
    src = source if isinstance(source, PointSource) else None
    if src is None and not served:  # local inputs: opened now (cheap), their files stamped for the rerun
        src = open_sources(source, client, aoi=aoi)
    location = src.location if src is not None else ";".join(map(str, items))
    now = {"source": location, "aoi": aoi.wkt if hasattr(aoi, "wkt") else [w, s, e, n],
           "resolution": resolution, "tile_size": float(tile_size), "margin": float(margin)}
    local = [p for p in location.split(";") if not is_url(p)]
    out = output_folder(out)
    kept_run = rerun_kept(out, "gistools fetch", now, local, overwrite, started)
    if kept_run is not None:  # the same area fetched before, its tiles as they were written: nothing is fetched
        return kept_run
    src = src if src is not None else open_sources(source, client, aoi=aoi)
    grown = _grown(aoi, margin)
    found = src.octree_nodes(grown, resolution)
    plan = _checked_plan(src, grown, resolution, max_download, location)
    report(progress, 0.0, f"{plan.points:,} points in {plan.nodes} nodes, about {plan.bytes / 1e6:,.1f} MB")
    cells = _lattice(aoi, tile_size)
    with claim_output(out, "gistools fetch"):  # tiles not kept whole (above) are written again: inputs may differ
        cache = Path(nodes) if nodes is not None else out / NODES
        tiles, count = _write_tiles(src, found, cells, grown, tile_size, out, cache, progress)
        rep = {"tool": "gistools fetch", "source": location, "crs_wkt": src.crs_wkt, "settings": now,
               "outputs": {"tiles": tiles}, "tiles": [{"name": Path(t).stem, "status": "ok"} for t in tiles],
               "counts": {"ok": len(tiles), "skipped": 0, "failed": 0},
               "points": count, "nodes": len(found), "estimate": {"points": plan.points, "bytes": plan.bytes},
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


def _grown(aoi, margin: float):
    """The area grown by ``margin`` (a box stays a box; a polygon is buffered)."""
    if not margin:
        return aoi
    if hasattr(aoi, "buffer"):
        return aoi.buffer(margin)
    w, s, e, n = area_box(aoi)
    return (w - margin, s - margin, e + margin, n + margin)


def _lattice(aoi, tile_size: float) -> tuple[list, tuple]:
    """The lattice's cells (i, j) that meet the area, and the area's range of them (i0, i1, j0, j1): the cell
    [i, i + 1) x [j, j + 1) times ``tile_size``; a point past the range (the margin, the area's east or north edge)
    belongs to the range's edge cell, so no cell is made of the margin alone."""
    w, s, e, n = area_box(aoi)
    i0, j0 = math.floor(w / tile_size), math.floor(s / tile_size)
    i1, j1 = max(i0, math.ceil(e / tile_size) - 1), max(j0, math.ceil(n / tile_size) - 1)
    cells = [(i, j) for i in range(i0, i1 + 1) for j in range(j0, j1 + 1)]
    if hasattr(aoi, "geom_type"):
        import shapely

        cells = [(i, j) for i, j in cells if aoi.intersects(shapely.box(i * tile_size, j * tile_size,
                                                                        (i + 1) * tile_size, (j + 1) * tile_size))]
    return cells, (i0, i1, j0, j1)


def _tile_name(i: int, j: int, size: float) -> str:
    """A tile's name: its south-west corner (whole units where the lattice has them)."""
    def corner(v):
        return f"{v:.0f}" if float(size).is_integer() else f"{v:.3f}"
    return f"{corner(i * size)}_{corner(j * size)}"


def _write_tiles(src, nodes, cells, grown, tile_size, out: Path, cache: Path, progress) -> tuple[list, int]:
    """Every node fetched once into ``cache``, then the tiles of the lattice's ``cells`` (their range's edge cells
    taking the margin) that hold points of the grown area written: (tiles, points written)."""
    cells, (i0, i1, j0, j1) = cells
    scales, offsets = src.scales_offsets()
    steps = len(nodes) + len(cells)
    cache.mkdir(parents=True, exist_ok=True)
    client = getattr(src, "client", None)
    points_read = 0
    for k, node in enumerate(nodes):
        _cached_node(src, node, cache)
        points_read += node.points
        fetched = f", {client.bytes_fetched / 1e6:,.1f} MB fetched" if client is not None else ""
        report(progress, (k + 1) / steps, f"{points_read:,} points{fetched}")
    tiles, count = [], 0
    for k, (i, j) in enumerate(cells):
        path = out / f"{_tile_name(i, j, tile_size)}.laz"
        x_lo, x_hi = (i * tile_size if i > i0 else -math.inf), ((i + 1) * tile_size if i < i1 else math.inf)
        y_lo, y_hi = (j * tile_size if j > j0 else -math.inf), ((j + 1) * tile_size if j < j1 else math.inf)
        parts = [_cached_node(src, nd, cache) for nd in nodes if nd.bounds[0] <= x_hi and nd.bounds[2] >= x_lo
                 and nd.bounds[1] <= y_hi and nd.bounds[3] >= y_lo]
        points = _in_tile(parts, grown, (i, j), (i0, i1, j0, j1), tile_size)
        if len(points["x"]):
            _write_points(path, points, src.crs_wkt, scales, offsets, (i * tile_size, j * tile_size, 0.0))
            tiles.append(str(path))
            count += len(points["x"])
        report(progress, (len(nodes) + k + 1) / steps, path.name)
    return tiles, count


def _in_tile(parts: list, grown, cell: tuple, span: tuple, size: float) -> dict:
    """The points of ``parts`` inside the grown area whose lattice cell (clamped to the area's ``span``) is
    ``cell``: each point in exactly one tile, by the lattice's own formula."""
    from ..io.area import _cut

    joined = _cut(parts, grown)
    i0, i1, j0, j1 = span
    ci = np.clip(np.floor(joined["x"] / size), i0, i1)
    cj = np.clip(np.floor(joined["y"] / size), j0, j1)
    keep = (ci == cell[0]) & (cj == cell[1])
    return {name: values[keep] for name, values in joined.items()}


AREA_FOLDER = "fetched"  # the cache's default place, inside the output folder


@dataclass(frozen=True)
class Area:
    """The points of an area of point cloud services or local data, given where a command takes tiles.

    A command given an Area fetches its points (once: the cache keeps them) into LAZ tiles on an absolute lattice
    and runs on those as on files, with every option checked first.

    Parameters
    ----------
    inputs : str, path or sequence of them
        EPT datasets (``https://host/path/ept.json``), COPC files (``https://host/x.copc.laz``), VPCs (their items
        local or served), local copies of either, or LAS/LAZ tiles (files, folders, globs).
    aoi : str, sequence of 4 floats or shapely geometry
        The area: ``minx,miny,maxx,maxy`` (the data's CRS, or ``minx,miny,maxx,maxy,EPSG:code``), a polygon layer
        (``file.gpkg``, ``file.gpkg|layername=NAME``), a box of 4 numbers or a shapely polygon in the data's CRS.
    cache : str or path
        Where the fetched nodes and tiles are kept (a rerun, or another product of the same area, fetches nothing).
    resolution : str or float, optional
        Read only the octree depths whose point spacing is at least this fine (a length: "2m", "5ft"); None: every
        point.
    tile_size : str or float, optional
        The tiles' side (a length); None: 500 m (1500 ft in feet).
    margin : str or float
        The points within this length outside the area are read too (what the cells at the area's edge see).
    max_download : str or float, optional
        Refuse an area larger than this ("2GB"; bytes) before any point is fetched.
    progress : callable, optional
        ``progress(fraction, message)`` while points are fetched.

    Examples
    --------
    >>> import gistools
    >>> area = gistools.Area("sample_tiles", aoi="430400,1810400,431600,1811600", cache="out/area_cache")
    >>> settings = gistools.RasterSettings(products=("dsm",))
    >>> gistools.rasters_from_tiles(area, "out/area_dsm", settings, overwrite=True)["counts"]
    {'ok': 4, 'failed': 0, 'skipped': 0}
    """

    inputs: object
    aoi: object
    cache: object
    resolution: object = None
    tile_size: object = None
    margin: object = "30m"
    max_download: object = None
    progress: object = field(default=None, compare=False)
    client: object = field(default=None, compare=False)
    _found: dict = field(default_factory=dict, compare=False, repr=False)

    def __str__(self) -> str:
        items = [self.inputs] if isinstance(self.inputs, (str, Path)) else list(self.inputs)
        return f"{', '.join(map(str, items))} (area {self.aoi})"

    def check(self) -> None:
        """The area's options, checked before anything is read or written."""
        from ..units import parse_length, parse_size

        for name in ("resolution", "tile_size", "margin"):
            value = getattr(self, name)
            if value is not None and parse_length(value, name=name)[0] < (0 if name == "margin" else 1e-9):
                raise InputError(f"{name} {value!r} must be {'0 or more' if name == 'margin' else 'positive'}",
                                 hint=f"e.g. {name}='2m'")
        if self.max_download is not None:
            parse_size(self.max_download, name="max_download")
        if self.aoi is None or (isinstance(self.aoi, str) and not self.aoi.strip()):
            raise InputError("a service, or points by area, needs an area", hint="Give aoi='minx,miny,maxx,maxy'")

    def _items(self) -> list[str]:
        items = [self.inputs] if isinstance(self.inputs, (str, Path)) else list(self.inputs)
        return [str(i) if is_url(str(i)) else str(Path(i).resolve()) for i in items]

    def local_tiles(self) -> list[Path]:
        """The area's tiles, fetched into the cache where they are not there yet (a served area fetched before is
        taken from the cache without a request)."""
        if "tiles" not in self._found:
            self._found["tiles"] = self._served_before() or self._fetched()
        return list(self._found["tiles"])

    def _given(self) -> str:
        """The area as given (its inputs, area and lengths), the cache's key of a served area."""
        import hashlib
        import json

        aoi = self.aoi.wkt if hasattr(self.aoi, "wkt") else str(self.aoi) if isinstance(self.aoi, (str, Path)) \
            else [float(v) for v in self.aoi]
        given = json.dumps([self._items(), aoi, *(str(v) for v in (self.resolution, self.tile_size, self.margin))])
        return hashlib.sha256(given.encode()).hexdigest()[:12]

    def _served_before(self) -> list | None:
        """The tiles of this same area of services fetched whole before (no local file can have changed)."""
        import json

        if not all(is_url(i) for i in self._items()) or _is_file_area(self.aoi):
            return None  # local files, or an area's layer, may have changed since: opened and stamped again
        record = Path(self.cache) / f"given-{self._given()}.json"
        try:
            tiles = [Path(t) for t in json.loads(record.read_text(encoding="utf-8"))["tiles"]]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return tiles if tiles and all(t.is_file() for t in tiles) else None

    def _fetched(self) -> list[Path]:
        import hashlib
        import json

        from ..io.area import area_in_crs, open_sources
        from ..units import length_to_crs_units, parse_size

        self.check()
        client = self.client or RangeClient()
        src = open_sources(self.inputs, client, aoi=self.aoi)
        unit = _unit_of(src.crs_wkt)
        aoi = getattr(src, "area", None) or area_in_crs(self.aoi, src.crs_wkt)  # an index's: in its CRS
        resolution = None if self.resolution is None else length_to_crs_units(self.resolution, unit, name="resolution")
        tile = self.tile_size if self.tile_size is not None else ("1500ft" if unit.is_foot else "500m")
        tile_size = length_to_crs_units(tile, unit, name="tile_size")
        margin = length_to_crs_units(self.margin or 0, unit, name="margin")
        key = json.dumps([src.location, aoi.wkt if hasattr(aoi, "wkt") else list(area_box(aoi)), resolution,
                          tile_size, margin])
        cache = Path(self.cache)
        folder = cache / f"area-{hashlib.sha256(key.encode()).hexdigest()[:12]}"
        nodes = cache / f"nodes-{hashlib.sha256(src.location.encode()).hexdigest()[:12]}"
        report_ = fetch_area(src, folder, aoi=aoi, resolution=resolution, tile_size=tile_size, margin=margin,
                             max_download=None if self.max_download is None else parse_size(self.max_download),
                             nodes=nodes, client=client, progress=self.progress)
        tiles = [Path(t) for t in report_["outputs"]["tiles"]]
        if not tiles:
            raise InputError(f"{self}: the area holds no points", hint="Check the area and its CRS")
        with atomic_path(cache / f"given-{self._given()}.json", overwrite=True) as tmp:
            tmp.write_text(json.dumps({"tiles": [str(t) for t in tiles]}), encoding="utf-8")
        return tiles


def _is_file_area(aoi) -> bool:
    """An area given as a layer file (not numbers nor a geometry)."""
    if not isinstance(aoi, (str, Path)):
        return False
    try:
        [float(v) for v in str(aoi).split(",")[:4]]
    except ValueError:
        return True
    return False


def _unit_of(crs_wkt):
    """The data's horizontal unit (metres where it has no CRS)."""
    import pyproj

    from ..units import LinearUnit, horizontal_unit

    if not crs_wkt:
        return LinearUnit("metre", 1.0)
    return horizontal_unit(pyproj.CRS.from_user_input(crs_wkt))
