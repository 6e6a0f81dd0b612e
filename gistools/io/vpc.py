"""Virtual point clouds (``.vpc``): a STAC ItemCollection of point cloud files, as pdal_wrench ``build_vpc``,
lasR ``write_vpc()`` and QGIS 3.32+ read and write them.

Each item holds the file's native bounds (``proj:bbox``, ``proj:geometry``), its CRS (``proj:wkt2``, and
``proj:epsg`` when it has one), a WGS84 ``bbox`` and geometry, the point count (``pc:count``) and the file as
a relative ``assets.data.href``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pyproj

from ..parameters import option
from ..errors import DataFileError
from .atomic import atomic_path

__all__ = ["write_vpc", "read_vpc", "VPC_SUFFIX"]

VPC_SUFFIX = ".vpc"
_EXTENSIONS = ["https://stac-extensions.github.io/pointcloud/v1.0.0/schema.json",
               "https://stac-extensions.github.io/projection/v1.1.0/schema.json"]


def _ring(w, s, e, n) -> list:
    return [[w, s], [e, s], [e, n], [w, n], [w, s]]


class _CrsFacts:
    """What each item needs of a CRS, worked out once per CRS (a transformer takes tens of milliseconds to make)."""

    def __init__(self):
        self._known = {}

    def __call__(self, crs: pyproj.CRS):
        key = crs.to_wkt()
        if key not in self._known:
            horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
            self._known[key] = (pyproj.Transformer.from_crs(horizontal, "EPSG:4326", always_xy=True), key, crs.to_epsg())
        return self._known[key]


def _item(vpc_dir: Path, path: Path, bounds, z_range, count: int, crs: pyproj.CRS, facts: _CrsFacts) -> dict:
    w, s, e, n = (float(v) for v in bounds)
    to_wgs84, wkt, epsg = facts(crs)
    lon0, lat0, lon1, lat1 = to_wgs84.transform_bounds(w, s, e, n, densify_pts=21)
    props = {
        "datetime": "0001-01-01T00:00:00Z",
        "pc:count": int(count),
        "pc:type": "lidar",
        "pc:encoding": "?",
        "pc:schemas": [],
        "proj:bbox": [w, s, float(z_range[0]), e, n, float(z_range[1])],
        "proj:geometry": {"type": "Polygon", "coordinates": [_ring(w, s, e, n)]},
        "proj:wkt2": wkt,
    }
    if epsg is not None:
        props["proj:epsg"] = epsg
    return {
        "type": "Feature",
        "stac_version": "1.0.0",
        "stac_extensions": _EXTENSIONS,
        "id": path.stem,
        "geometry": {"type": "Polygon", "coordinates": [_ring(lon0, lat0, lon1, lat1)]},
        "bbox": [lon0, lat0, float(z_range[0]), lon1, lat1, float(z_range[1])],
        "properties": props,
        "links": [],
        "assets": {"data": {"href": "./" + Path(os.path.relpath(path, vpc_dir)).as_posix(), "roles": ["data"]}},
    }


def write_vpc(path, tiles, *, overwrite: bool = True) -> Path:
    """Write the VPC of ``tiles`` [(file, (west, south, east, north), (zmin, zmax), point count, CRS)], atomically."""
    path = Path(path)
    facts = _CrsFacts()
    items = [_item(path.parent.resolve(), Path(f).resolve(), b, zr, c, crs, facts) for f, b, zr, c, crs in tiles]
    doc = {"type": "FeatureCollection", "features": items}
    with atomic_path(path, overwrite=overwrite) as tmp:
        tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    return path


MAX_VPC_BYTES = 512 * 2**20  # a VPC lists files: half a gigabyte of JSON is not one


def _local_href(path: Path, href: str) -> str:
    """An item's file as a local path; a served one (https://) is read by area (gistools.Area), not as a tile."""
    if "://" in href and not href.lower().startswith("file://"):
        raise DataFileError(f"lists a served file ({href}): read by area", path=path,
                            hint=f"Give the area of it to read ({option('aoi')})")
    return href[len("file://"):] if href.lower().startswith("file://") else href


def _item_wkt(path: Path, props: dict):
    """An item's CRS as WKT: its proj:wkt2, else its proj:epsg (an unknown code is refused), else None."""
    if props.get("proj:wkt2") or not props.get("proj:epsg"):
        return props.get("proj:wkt2")
    try:
        return pyproj.CRS.from_epsg(int(props["proj:epsg"])).to_wkt()
    except (pyproj.exceptions.CRSError, ValueError, TypeError):
        raise DataFileError(f"an item's proj:epsg {props['proj:epsg']!r} is not a known EPSG code", path=path,
                            hint="Fix the item's proj:epsg, or give its proj:wkt2") from None


def _vpc_item(path: Path, it) -> dict:
    """One item of a VPC as gistools reads it; DataFileError naming what is wrong."""
    if not isinstance(it, dict):
        raise ValueError(f"an item is a {type(it).__name__}, not an object")
    props = it.get("properties") or {}
    href = _local_href(path, str(it["assets"]["data"]["href"]))
    bbox = props.get("proj:bbox")
    bounds = (bbox[0], bbox[1], bbox[3], bbox[4]) if bbox and len(bbox) == 6 else (tuple(bbox) if bbox else None)
    return {"path": (path.parent / href).resolve() if not Path(href).is_absolute() else Path(href),
            "bounds": bounds, "count": props.get("pc:count"), "crs_wkt": _item_wkt(path, props)}


def read_vpc(path) -> list[dict]:
    """The files of a VPC: [{"path", "bounds" (native west, south, east, north), "count", "crs_wkt"}]."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_VPC_BYTES:
            raise ValueError(f"{path.stat().st_size / 2**20:,.0f} MB of JSON")
        doc = json.loads(path.read_text(encoding="utf-8-sig"))
        items = doc["features"] if isinstance(doc, dict) else None
        if not isinstance(items, list):
            raise ValueError(f"its features are a {type(items).__name__}, not a list")
        out = [_vpc_item(path, it) for it in items]
    except DataFileError:
        raise
    except (OSError, ValueError, KeyError, TypeError, IndexError, RecursionError) as err:
        why = "nested too deep" if isinstance(err, RecursionError) else f"{type(err).__name__}: {str(err)[:200]}"
        raise DataFileError(f"not a virtual point cloud (STAC ItemCollection) ({why})", path=path,
                            hint="Give a .vpc written by gistools, pdal_wrench build_vpc, lasR or QGIS") from None
    return out
