"""The points of an area read from a point cloud service or a local copy of it: an Entwine Point Tiles dataset (EPT:
``.../ept.json``) or a Cloud Optimized Point Cloud (COPC: ``....copc.laz``), over HTTP(S) or from the disk.

Only the octree nodes that meet the area are read (and, with ``resolution``, only the depths whose point spacing is
not finer than it, as PDAL's ``resolution``); their points are then cut to the area exactly. What comes from a
library: COPC's header, hierarchy pages and LAZ chunks are laspy's ``CopcReader`` (reading through
``gistools.io.http.RangeFile`` for a URL), an EPT node's LAZ is read by laspy. What is written here: EPT's metadata
and hierarchy (JSON pages, a count of -1 naming a page of its own; the EPT specification, entwine.io), the
octree's node bounds and depths, the cut to a box or a polygon, and the estimate of what an area costs before
anything else is fetched.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError
from .http import RangeClient, RangeFile, is_url

__all__ = ["PointSource", "open_source", "open_sources", "area_box", "area_in_crs", "is_area_source", "is_index", "FIELDS"]

# the fields read for every point (the tile engine's), as numpy arrays
FIELDS = ("x", "y", "z", "classification", "return_number", "number_of_returns", "intensity")


def area_box(aoi) -> tuple[float, float, float, float]:
    """(minx, miny, maxx, maxy) of an area: a box of four numbers, or a shapely geometry."""
    if hasattr(aoi, "bounds") and hasattr(aoi, "geom_type"):
        return tuple(float(v) for v in aoi.bounds)
    w, s, e, n = (float(v) for v in aoi)
    if not (w < e and s < n):
        raise InputError(f"the area {w:g},{s:g},{e:g},{n:g} is empty (minx must be below maxx, miny below maxy)",
                         hint="Give minx,miny,maxx,maxy")
    return w, s, e, n


def _inside(x, y, aoi) -> np.ndarray:
    """Points in the area: a box closed on every side, or a polygon with its boundary."""
    if hasattr(aoi, "geom_type"):
        import shapely

        return shapely.intersects_xy(aoi, x, y)
    w, s, e, n = area_box(aoi)
    return (x >= w) & (x <= e) & (y >= s) & (y <= n)


def _fields(points) -> dict:
    """The FIELDS of a laspy point record as numpy arrays."""
    return {"x": np.asarray(points.x, np.float64), "y": np.asarray(points.y, np.float64),
            "z": np.asarray(points.z, np.float64), "classification": np.asarray(points.classification, np.uint8),
            "return_number": np.asarray(points.return_number, np.uint8),
            "number_of_returns": np.asarray(points.number_of_returns, np.uint8),
            "intensity": np.asarray(points.intensity, np.uint16)}


def _cut(parts: list, aoi) -> dict:
    """The points of ``parts`` (dicts of FIELDS) inside the area, joined."""
    if not parts:
        return {name: np.empty(0, np.float64 if name in ("x", "y", "z") else np.uint16) for name in FIELDS}
    joined = {name: np.concatenate([p[name] for p in parts]) for name in FIELDS}
    keep = _inside(joined["x"], joined["y"], aoi)
    return {name: values[keep] for name, values in joined.items()}


@dataclass(frozen=True)
class Node:
    """An octree node of a dataset: its name (``D-X-Y-Z``), its points, its 2D bounds, its bytes (COPC) and where
    they are (a COPC file's offset)."""

    name: str
    points: int
    bounds: tuple  # (minx, miny, maxx, maxy)
    bytes: int | None = None
    offset: int | None = None


@dataclass(frozen=True)
class Plan:
    """What reading an area costs, known from the hierarchy before any point is fetched."""

    nodes: int
    points: int
    bytes: int | None  # None where the hierarchy does not say (EPT)


class PointSource:
    """A point cloud dataset read by area (``open_source`` makes one)."""

    location: str
    crs_wkt: str | None

    @property
    def remote(self) -> bool:
        """Served over HTTP(S) (its nodes are kept in a cache once fetched), not read from the disk."""
        return any(is_url(part) for part in self.location.split(";"))

    def octree_nodes(self, aoi, resolution: float | None = None) -> list[Node]:  # pragma: no cover - overridden
        raise NotImplementedError

    def node_points(self, node: Node) -> dict:  # pragma: no cover - each kind overrides it
        raise NotImplementedError

    def plan(self, aoi, resolution: float | None = None) -> Plan:
        """What the area costs, from the hierarchy alone: nodes, points and (where the hierarchy says) bytes."""
        nodes = self.octree_nodes(aoi, resolution)
        sizes = [n.bytes for n in nodes]
        return Plan(nodes=len(nodes), points=sum(n.points for n in nodes),
                    bytes=None if None in sizes else sum(sizes))

    def read(self, aoi, resolution: float | None = None) -> dict:
        """The points inside the area (FIELDS as numpy arrays) of the nodes that meet it."""
        return _cut([self.node_points(node) for node in self.octree_nodes(aoi, resolution)], aoi)


def open_source(location, client: RangeClient | None = None) -> PointSource:
    """An EPT dataset (its ``ept.json``, or the folder or URL prefix holding it) or a COPC file, local or served.

    Parameters
    ----------
    location : str or path
        ``https://host/path/ept.json``, ``https://host/x.copc.laz``, or a local path of either.
    client : RangeClient, optional
        The network client (its counts tell what was fetched); None: a new one.

    Returns
    -------
    PointSource
        With ``plan(aoi, resolution)`` (nodes, points and bytes an area takes) and ``read(aoi, resolution)`` (the
        area's points as numpy arrays of FIELDS).

    Raises
    ------
    DataFileError
        The location is not an EPT dataset or a COPC file, or the server cannot give it.

    Examples
    --------
    >>> source = open_source("tests/data/pdal/lone-star-laszip/ept.json")  # doctest: +SKIP
    >>> len(source.read((515380, 4918350, 515390, 4918360))["x"])  # doctest: +SKIP
    """
    text = str(location)
    client = client or RangeClient()
    if text.lower().endswith(".laz") or text.lower().endswith(".las"):
        return CopcSource(text, client)
    if not text.lower().endswith(".json"):
        text = text.rstrip("/") + "/ept.json"
    return EptSource(text, client)


# --- EPT --------------------------------------------------------------------------------------------------------


class EptSource(PointSource):
    """An EPT dataset (laszip nodes, JSON hierarchy)."""

    def __init__(self, location: str, client: RangeClient):
        location = location if is_url(location) else str(Path(location).resolve())
        self.location, self.client = location, client
        self.base = location[: -len("ept.json")]
        meta = self._json(location, "the dataset's metadata (ept.json)")
        try:
            self.cube = [float(v) for v in meta["bounds"]]
            self.span = float(meta["span"])
            data_type, hierarchy_type = meta["dataType"], meta.get("hierarchyType", "json")
            self.points = int(meta["points"])
        except (KeyError, TypeError, ValueError):
            raise DataFileError("not EPT metadata (ept.json needs bounds, span, dataType, points)", path=location,
                                hint="Give the ept.json of an Entwine Point Tiles dataset") from None
        if data_type != "laszip" or hierarchy_type != "json":
            raise DataFileError(f"EPT nodes of dataType {data_type!r} and hierarchyType {hierarchy_type!r}: gistools "
                                "reads laszip nodes and JSON hierarchies", path=location,
                                hint="Ask for the dataset as laszip EPT or COPC (PDAL's writers.copc converts it)")
        srs = meta.get("srs") or {}
        self.crs_wkt = srs.get("wkt") or (f"{srs.get('authority', 'EPSG')}:{srs['horizontal']}"
                                          if srs.get("horizontal") else None)

    def _read(self, relative_or_url: str) -> bytes:
        target = relative_or_url if is_url(relative_or_url) or Path(relative_or_url).is_absolute() else \
            self.base + relative_or_url
        if is_url(target):
            return self.client.get(target)
        try:
            return Path(target).read_bytes()
        except OSError as err:
            raise DataFileError(f"cannot be read ({err.strerror or err})", path=target,
                                hint="Check the dataset's folder is complete") from None

    def _json(self, location: str, what: str) -> dict:
        try:
            value = json.loads(self._read(location))
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise DataFileError(f"{what} is not JSON", path=location, hint="Check the URL names an EPT dataset") \
                from None
        if not isinstance(value, dict):
            raise DataFileError(f"{what} is not a JSON object", path=location, hint="Check the URL")
        return value

    def node_bounds(self, key: tuple) -> tuple:
        """(minx, miny, minz, maxx, maxy, maxz) of the node ``key`` = (depth, x, y, z) of the cube."""
        d, x, y, z = key
        size = [(self.cube[i + 3] - self.cube[i]) / 2 ** d for i in range(3)]
        mins = [self.cube[i] + (x, y, z)[i] * size[i] for i in range(3)]
        return (*mins, *(mins[i] + size[i] for i in range(3)))

    def max_depth(self, resolution: float | None) -> int | None:
        """The deepest depth read for ``resolution`` (the first whose spacing is at least as fine), None: all."""
        if resolution is None:
            return None
        spacing = (self.cube[3] - self.cube[0]) / self.span
        return max(0, math.ceil(math.log2(spacing / float(resolution)))) if spacing > resolution else 0

    def nodes(self, aoi, resolution: float | None = None) -> list[tuple[tuple, int]]:
        """[(key, points)] of the nodes that meet the area's box, to the resolution's depth."""
        w, s, e, n = area_box(aoi)
        deepest = self.max_depth(resolution)
        found, pages = [], ["0-0-0-0"]
        while pages:
            page = pages.pop()
            entries = self._json(f"ept-hierarchy/{page}.json", f"the hierarchy page {page}")
            for name, count in entries.items():
                try:
                    key = tuple(int(v) for v in name.split("-"))
                    count = int(count)
                    assert len(key) == 4
                except (ValueError, TypeError, AssertionError):
                    raise DataFileError(f"the hierarchy page {page} holds {name!r}: {count!r}, not a node and a count",
                                        path=self.base + f"ept-hierarchy/{page}.json", hint="The dataset is damaged")
                if deepest is not None and key[0] > deepest:
                    continue
                bx0, by0, _z0, bx1, by1, _z1 = self.node_bounds(key)
                if bx0 > e or bx1 < w or by0 > n or by1 < s:
                    continue
                if count == -1 and name != page:
                    pages.append(name)
                elif count > 0:
                    found.append((key, count))
        return sorted(set(found))

    def octree_nodes(self, aoi, resolution: float | None = None) -> list[Node]:
        found = []
        for key, count in self.nodes(aoi, resolution):
            x0, y0, _z0, x1, y1, _z1 = self.node_bounds(key)
            found.append(Node("-".join(map(str, key)), count, (x0, y0, x1, y1)))
        return found

    def node_points(self, node: Node) -> dict:
        return self.read_node(tuple(int(v) for v in node.name.split("-")))

    def read_node(self, key: tuple) -> dict:
        """The points of one node (its LAZ file), as FIELDS."""
        import laspy

        name = "-".join(map(str, key))
        data = self._read(f"ept-data/{name}.laz")
        try:
            return _fields(laspy.read(io.BytesIO(data)).points)
        except Exception as err:  # noqa: BLE001 - laspy / lazrs raise several kinds for a damaged file
            raise DataFileError(f"the node {name} does not decode ({type(err).__name__}: {err})",
                                path=self.base + f"ept-data/{name}.laz", hint="The dataset is damaged") from None

    def scales_offsets(self) -> tuple:
        """(scales, offsets) of x, y, z: the dataset's schema."""
        schema = {d["name"]: d for d in self._json(self.location, "ept.json").get("schema", [])}
        return (tuple(float(schema.get(a, {}).get("scale", 0.01)) for a in "XYZ"),
                tuple(float(schema.get(a, {}).get("offset", 0.0)) for a in "XYZ"))


# --- COPC -------------------------------------------------------------------------------------------------------


class CopcSource(PointSource):
    """A COPC file, read through laspy's CopcReader (over the range client for a URL)."""

    def __init__(self, location: str, client: RangeClient):
        import laspy

        self.location, self.client = location, client
        try:
            stream = io.BufferedReader(RangeFile(client, location), buffer_size=64 * 1024) if is_url(location) \
                else open(location, "rb")  # noqa: SIM115 - the reader keeps it open
        except OSError as err:
            raise DataFileError(f"cannot be read ({err.strerror or err})", path=location,
                                hint="Check the path") from None
        try:
            self.reader = laspy.CopcReader(stream)
        except DataFileError:
            raise
        except Exception as err:  # noqa: BLE001 - laspy raises several kinds for a file that is not COPC
            stream.close()
            raise DataFileError(f"not a COPC file ({type(err).__name__}: {err})", path=location,
                                hint="Give a .copc.laz file (or an EPT dataset's ept.json)") from None
        try:
            self.crs_wkt = self.reader.header.parse_crs().to_wkt()
        except Exception:  # noqa: BLE001 - a file without a CRS, or one pyproj cannot parse
            self.crs_wkt = None

    def _query(self, aoi, resolution):
        import laspy

        w, s, e, n = area_box(aoi)
        pad = 2 * float(max(self.reader.header.scales[:2]))  # laspy cuts on integer coordinates: keep the edge
        return laspy.copc.Bounds(mins=np.array([w - pad, s - pad]), maxs=np.array([e + pad, n + pad])), resolution

    def octree_nodes(self, aoi, resolution: float | None = None) -> list[Node]:
        from laspy.copc import load_octree_for_query

        bounds, _ = self._query(aoi, resolution)
        level = None
        if resolution is not None:
            level = range(0, max(1, math.ceil(math.log2(self.reader.copc_info.spacing / resolution)) + 1))
        nodes = load_octree_for_query(self.reader.source, self.reader.copc_info, self.reader.root_page,
                                      query_bounds=bounds.ensure_3d(self.reader.header.mins, self.reader.header.maxs),
                                      level_range=level)
        return [Node(f"{n.key.level}-{n.key.x}-{n.key.y}-{n.key.z}", int(n.point_count),
                     tuple(float(v) for v in (*n.bounds.mins[:2], *n.bounds.maxs[:2])), int(n.byte_size),
                     int(n.offset)) for n in nodes if n.point_count > 0]

    def node_points(self, node: Node) -> dict:
        """One node's points: its LAZ chunk fetched (a range of the file) and decompressed with lazrs, as laspy does."""
        import lazrs
        from laspy.point.record import PackedPointRecord, ScaleAwarePointRecord

        if is_url(self.location):
            data = self.client.get(self.location, node.offset, node.bytes)
        else:
            with open(self.location, "rb") as fh:
                fh.seek(node.offset)
                data = fh.read(node.bytes)
        header = self.reader.header
        points = np.zeros(node.points * header.point_format.size, dtype=np.uint8)
        try:
            lazrs.decompress_points_with_chunk_table(data, self.reader.laszip_vlr.record_data, points,
                                                     [(node.points, node.bytes)], self.reader.decompression_selection)
        except Exception as err:  # noqa: BLE001 - lazrs raises its own kinds for a damaged chunk
            raise DataFileError(f"the node {node.name} does not decode ({type(err).__name__}: {err})",
                                path=self.location, hint="The file is damaged") from None
        record = PackedPointRecord.from_buffer(points, header.point_format)
        return _fields(ScaleAwarePointRecord(record.array, record.point_format, header.scales, header.offsets))

    def scales_offsets(self) -> tuple:
        """(scales, offsets) of x, y, z: the file's header."""
        return tuple(map(float, self.reader.header.scales)), tuple(map(float, self.reader.header.offsets))


# --- local LAS / LAZ tiles, and several sources as one ------------------------------------------------------------


class LasFileSource(PointSource):
    """A local LAS/LAZ file that is not COPC: one node, its header's bounds (the whole file is read)."""

    def __init__(self, path):
        import laspy

        self.location = str(Path(path).resolve())
        try:
            with laspy.open(self.location) as reader:
                self.header = reader.header
        except Exception as err:  # noqa: BLE001 - laspy raises several kinds for a file that is not LAS
            raise DataFileError(f"not a LAS/LAZ file ({type(err).__name__}: {err})", path=self.location,
                                hint="Give LAS/LAZ tiles, an EPT dataset or a COPC file") from None
        try:
            crs = self.header.parse_crs()
            self.crs_wkt = crs.to_wkt() if crs is not None else None
        except Exception:  # noqa: BLE001 - a CRS pyproj cannot parse: the tile engine says so per tile
            self.crs_wkt = None

    def octree_nodes(self, aoi, resolution: float | None = None) -> list[Node]:
        w, s, e, n = area_box(aoi)
        x0, y0, x1, y1 = (float(v) for v in (*self.header.mins[:2], *self.header.maxs[:2]))
        if x0 > e or x1 < w or y0 > n or y1 < s or not self.header.point_count:
            return []
        return [Node(Path(self.location).stem, int(self.header.point_count), (x0, y0, x1, y1),
                     Path(self.location).stat().st_size)]

    def node_points(self, node: Node) -> dict:
        import laspy

        try:
            return _fields(laspy.read(self.location).points)
        except Exception as err:  # noqa: BLE001 - laspy / lazrs raise several kinds for a damaged file
            raise DataFileError(f"does not decode ({type(err).__name__}: {err})", path=self.location,
                                hint="Check the file is complete") from None

    def scales_offsets(self) -> tuple:
        return tuple(map(float, self.header.scales)), tuple(map(float, self.header.offsets))


class SourceSet(PointSource):
    """Several sources read as one (a folder of tiles, a VPC's items): their nodes named ``<source>~<node>``."""

    def __init__(self, sources: list):
        import pyproj

        self.sources = sources
        self.location = ";".join(s.location for s in sources)
        known = [s for s in sources if s.crs_wkt]
        self.crs_wkt = known[0].crs_wkt if known else None
        first = pyproj.CRS.from_user_input(self.crs_wkt) if known else None
        for other in known[1:]:
            if not pyproj.CRS.from_user_input(other.crs_wkt).equals(first, ignore_axis_order=True):
                raise InputError(f"{other.location} and {known[0].location} are in different CRSs",
                                 hint="Read one CRS at a time (reproject one of them first)")

    def octree_nodes(self, aoi, resolution: float | None = None) -> list[Node]:
        return [Node(f"{i}~{n.name}", n.points, n.bounds, n.bytes, n.offset)
                for i, source in enumerate(self.sources) for n in source.octree_nodes(aoi, resolution)]

    def node_points(self, node: Node) -> dict:
        i, _, name = node.name.partition("~")
        own = Node(name, node.points, node.bounds, node.bytes, node.offset)
        return self.sources[int(i)].node_points(own)

    def scales_offsets(self) -> tuple:
        return self.sources[0].scales_offsets()


def is_area_source(item) -> bool:
    """An input that only an area can read: a URL, an EPT dataset (its ept.json or folder), an index of datasets
    (a local COPC file is a tile too)."""
    text = str(item)
    if is_url(text):
        return True
    path = Path(text)
    return path.name.lower() == "ept.json" or (path.is_dir() and (path / "ept.json").is_file()) or is_index(text)


def _vpc_sources(location: str, client: RangeClient) -> list:
    """The sources of a VPC's items (STAC items of a FeatureCollection), local or served, relative hrefs resolved."""
    from urllib.parse import urljoin

    if is_url(location):
        data = client.get(location)
    else:
        try:
            data = Path(location).read_bytes()
        except OSError as err:
            raise DataFileError(f"cannot be read ({err.strerror or err})", path=location,
                                hint="Check the path") from None
    try:
        items = json.loads(data)["features"]
        hrefs = [next(iter(item["assets"].values()))["href"] for item in items]
    except (ValueError, KeyError, TypeError, StopIteration):
        raise DataFileError("not a virtual point cloud (a STAC FeatureCollection with an asset per item)",
                            path=location, hint="Give a .vpc made by QGIS, PDAL or gistools") from None
    base = location if is_url(location) else Path(location).resolve().parent.as_uri() + "/"
    found = []
    for href in hrefs:
        target = urljoin(base, href)
        if target.startswith("file://"):
            from urllib.request import url2pathname

            target = url2pathname(target[len("file://"):])
        found.append(target)
    return [_one_source(target, client) for target in found]


INDEX_SUFFIXES = (".geojson", ".gpkg", ".fgb")
URL_FIELDS = ("url", "ept", "href", "location", "source", "path")  # the column of an index that holds the URLs


def is_index(item) -> bool:
    """An index of datasets: a GeoJSON (or GeoPackage, FlatGeobuf) of their boundaries with their URLs (as USGS
    publishes for 3DEP)."""
    return str(item).lower().endswith(INDEX_SUFFIXES)


def _index_sources(location: str, aoi, client: RangeClient) -> PointSource:
    """The datasets of an index whose boundaries meet the area, read together (they must share a CRS). A box of
    no CRS is in the index's; the area, reprojected, is kept as the source's ``area`` (in the data's CRS)."""
    import geopandas as gpd
    import pyproj
    import shapely
    from urllib.parse import urljoin

    if aoi is None:
        raise InputError(f"{location}: an index of datasets is read by area", hint="Give the area (aoi)")
    try:
        gdf = gpd.read_file(io.BytesIO(client.get(location)) if is_url(location) else location)
    except DataFileError:
        raise
    except Exception as err:  # noqa: BLE001 - pyogrio raises its own kinds for a file that is not a layer
        raise DataFileError(f"not an index of datasets ({type(err).__name__}: {err})", path=location,
                            hint="Give a GeoJSON of dataset boundaries with their URLs") from None
    field = next((c for c in gdf.columns if c.lower() in URL_FIELDS), None)
    if field is None:
        raise DataFileError(f"the index has no column of URLs (one of {', '.join(URL_FIELDS)})", path=location,
                            hint="Name the datasets' URL column url")
    index_wkt = gdf.crs.to_wkt() if gdf.crs is not None else None
    area = area_in_crs(aoi, index_wkt)
    shape = area if hasattr(area, "geom_type") else shapely.box(*area)
    picked = gdf[gdf.geometry.intersects(shape)]
    if picked.empty:
        raise InputError(f"{location}: no dataset of the index meets the area", hint="Check the area and its CRS")
    base = location if is_url(location) else Path(location).resolve().parent.as_uri() + "/"
    sources = []
    for href in picked[field].astype(str):
        target = urljoin(base, href)
        if target.startswith("file://"):
            from urllib.request import url2pathname

            target = url2pathname(target[len("file://"):])
        sources.append(_one_source(target, client))
    found = sources[0] if len(sources) == 1 else SourceSet(sources)
    if index_wkt and found.crs_wkt and pyproj.CRS.from_user_input(index_wkt) != pyproj.CRS.from_user_input(found.crs_wkt):
        to_data = pyproj.Transformer.from_crs(gdf.crs, pyproj.CRS.from_user_input(found.crs_wkt), always_xy=True)
        shape = shapely.transform(shapely.segmentize(shape, max(shape.length / 400, 1e-9)),
                                  lambda xy: np.column_stack(to_data.transform(xy[:, 0], xy[:, 1])))
    found.area = shape
    return found


def _one_source(text: str, client: RangeClient) -> PointSource:
    lower = text.lower()
    if lower.endswith(".vpc"):
        return SourceSet(_vpc_sources(text, client))
    if is_url(text) or is_area_source(text) or lower.endswith(".copc.laz"):
        return open_source(text, client)
    return LasFileSource(text)


def open_sources(inputs, client: RangeClient | None = None, aoi=None) -> PointSource:
    """Every input as one source read by area: URLs and local copies of EPT datasets and COPC files, VPCs (their
    items local or served), indexes of datasets (GeoJSON: the datasets whose boundaries meet ``aoi``) and LAS/LAZ
    tiles (files, folders, globs). Mixed CRSs are refused; the datasets of one area are read together.

    Parameters
    ----------
    inputs : str, path or sequence of them
    client : RangeClient, optional
        The network client.
    aoi : optional
        The area (as ``area_in_crs`` takes it): an index's datasets are picked by it.

    Returns
    -------
    PointSource

    Examples
    --------
    >>> source = open_sources(["tests/data/pdal/lone-star.copc.laz"])  # doctest: +SKIP
    """
    from .tiles import find_tiles

    client = client or RangeClient()
    items = [inputs] if isinstance(inputs, (str, Path)) else list(inputs)
    sources = []
    for item in items:
        text = str(item)
        if is_index(text):
            sources.append(_index_sources(text, aoi, client))
        elif is_url(text) or is_area_source(text) or text.lower().endswith((".vpc", ".copc.laz")):
            sources.append(_one_source(text, client))
        else:
            sources += [_one_source(str(path), client) for path in find_tiles([item])]
    return sources[0] if len(sources) == 1 else SourceSet(sources)


def area_in_crs(aoi, crs_wkt):
    """The area in the data's CRS: ``aoi`` is a box (four numbers, or text ``minx,miny,maxx,maxy`` with an optional
    ``,EPSG:code`` or CRS after it), a shapely geometry in the data's CRS, or a polygon layer (``file.gpkg``,
    ``file.gpkg|layername=NAME``), reprojected when its CRS is another. Returns a box tuple or a shapely polygon."""
    import pyproj

    if hasattr(aoi, "geom_type"):
        return aoi
    if not isinstance(aoi, (str, Path)):
        return area_box(aoi)
    text = str(aoi).strip()
    parts = [p.strip() for p in text.split(",")]
    try:
        box = tuple(float(v) for v in parts[:4])
        is_box = len(box) == 4
    except ValueError:
        is_box = False
    if not is_box:
        return _layer_area(text, crs_wkt)
    box = area_box(box)
    if len(parts) == 4:
        return box
    given = _crs_of(",".join(parts[4:]), text)  # EPSG:code, or a WKT (its commas kept)
    if crs_wkt is None or given == pyproj.CRS.from_user_input(crs_wkt):
        return box
    t = pyproj.Transformer.from_crs(given, pyproj.CRS.from_user_input(crs_wkt), always_xy=True)
    return area_box(t.transform_bounds(*box, densify_pts=21))


def _crs_of(text: str, aoi: str):
    import pyproj

    try:
        return pyproj.CRS.from_user_input(text)
    except pyproj.exceptions.CRSError:
        raise InputError(f"the area {aoi!r}: {text!r} is not a CRS", hint="Write the box's CRS as EPSG:code") from None


def _layer_area(spec: str, crs_wkt):
    """The union of a polygon layer's features, in the data's CRS."""
    import pyproj
    import shapely

    from .vector import read_layer

    gdf = read_layer(spec, ("polygon",), what="the area of interest")
    if crs_wkt is not None and gdf.crs is not None:
        gdf = gdf.to_crs(pyproj.CRS.from_user_input(crs_wkt))
    area = shapely.union_all(gdf.geometry.values)
    if area.is_empty:
        raise InputError(f"{spec}: the area's layer holds no polygon", hint="Give a layer of polygons")
    return area
