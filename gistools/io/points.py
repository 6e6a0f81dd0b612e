"""LAS / LAZ tiles: headers, CRS and linear units, and chunked point streams.

Uses laspy (LAZ through lazrs). Reads LAS 1.0-1.4; memory stays flat whatever
the tile size because points are read ``chunk_size`` at a time.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import laspy
import numpy as np
import pyproj

from ..errors import Cancelled, CRSMismatchError, DataFileError, EmptyTileError, InputError, MissingCRSError
from ..machine import address_space_left
from ..parameters import option
from ..progress import check_stop
from ..units import LinearUnit, horizontal_unit, vertical_unit

__all__ = [
    "scaled",
    "TileInfo",
    "PointChunk",
    "read_tile_info",
    "iter_chunks",
    "parse_crs_text",
    "common_crs",
    "crs_label",
    "DEFAULT_CHUNK_SIZE",
]

log = logging.getLogger(__name__)

DEFAULT_CHUNK_SIZE = 2_000_000


@dataclass(frozen=True)
class TileInfo:
    """What a LAS/LAZ header says about a tile. Bounds (west, south, east, north) in CRS units."""

    path: Path
    point_count: int
    bounds: tuple[float, float, float, float]
    z_range: tuple[float, float]
    crs: pyproj.CRS
    crs_from_file: bool
    version: str
    point_format: int
    scales: tuple[float, float, float]
    offsets: tuple[float, float, float]
    compressed: bool
    points_by_return: tuple[int, ...] = field(default=())
    geokey_z_unit: LinearUnit | None = None  # from the GeoTIFF vertical keys, when the CRS is not compound
    crs_note: str | None = None  # what was wrong with the file's CRS record, and what was used instead
    copc: bool = False  # a COPC file (its "copc" VLR): a box of it is read by a query of the nodes that reach it

    @property
    def name(self) -> str:
        """File name without its .las/.laz suffix."""
        return self.path.stem

    @property
    def unit(self) -> LinearUnit:
        return horizontal_unit(self.crs)

    @property
    def z_unit(self) -> LinearUnit:
        """Unit of z: the compound CRS's vertical unit, else the GeoTIFF vertical keys', else the horizontal unit."""
        if self.crs.is_compound or self.geokey_z_unit is None:
            return vertical_unit(self.crs)
        return self.geokey_z_unit


@dataclass
class PointChunk:
    """A chunk of points as plain arrays (x, y, z float64 in CRS units)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    classification: np.ndarray
    return_number: np.ndarray
    number_of_returns: np.ndarray
    withheld: np.ndarray
    intensity: np.ndarray | None = None
    raw: object = None  # the laspy point record, for fields not extracted (e.g. raw integer Z)

    def __len__(self) -> int:
        return len(self.raw) if self.raw is not None else len(self.x)


_LABELS: dict = {}  # id(crs) -> (crs, label): the tiles of a delivery share one CRS object (see _file_crs)


def crs_label(crs: pyproj.CRS | None) -> str:
    """Short human label for a CRS: 'EPSG:2882 (NAD83(HARN) / Florida West (ftUS))'."""
    if crs is None:
        return "no CRS"
    known = _LABELS.get(id(crs))
    if known is not None and known[0] is crs:
        return known[1]
    code = crs.to_epsg(min_confidence=70)
    label = f"EPSG:{code} ({crs.name})" if code else crs.name
    if len(_LABELS) >= 256:
        _LABELS.clear()
    _LABELS[id(crs)] = (crs, label)  # the CRS kept with it: its id is not reused while here
    return label


def parse_crs_text(text: str) -> pyproj.CRS:
    """A CRS from user text (EPSG:2882, WKT, PROJ string)."""
    try:
        return pyproj.CRS.from_user_input(text)
    except pyproj.exceptions.CRSError as err:
        raise InputError(f"{option('crs')} {text!r} is not a CRS ({err})", hint="Give e.g. EPSG:2882 or a WKT string") from None


def chosen_crs(given, found, what: str, path, example: str) -> pyproj.CRS:
    """The CRS of an input: ``given`` (text or a pyproj CRS: the --crs option, which wins), else ``found`` (the
    file's own), else refused naming ``what`` carries none, with ``example`` of a --crs to give."""
    if given is not None:
        return parse_crs_text(given) if isinstance(given, str) else pyproj.CRS.from_user_input(given)
    if found is not None:
        return pyproj.CRS.from_user_input(found)
    raise InputError(f"{what} carr{'y' if what.endswith('s') else 'ies'} no CRS", path=path,
                     hint=f"Give one with {option('crs')} ({example})")


def _open_error(path: Path, err: Exception) -> DataFileError:
    return DataFileError(
        f"not a readable LAS/LAZ file ({type(err).__name__}: {err})",
        path=path,
        hint="Check the file is a complete LAS 1.0-1.4 or LAZ file (re-copy or re-export it)",
    )


_GEOKEY_UNITS = {9001: LinearUnit("metre", 1.0), 9002: LinearUnit("foot", 0.3048),
                 9003: LinearUnit("US survey foot", 1200.0 / 3937.0)}


def _geokey_z_unit(header) -> LinearUnit | None:
    """Vertical unit from GeoTIFF keys: VerticalCSTypeGeoKey (4096, an EPSG vertical CRS) or
    VerticalUnitsGeoKey (4099). laspy's CRS parser reads only the horizontal keys."""
    for vlr in header.vlrs:
        if type(vlr).__name__ != "GeoKeyDirectoryVlr":
            continue
        keys = {int(k.id): k for k in vlr.geo_keys}
        vcs = keys.get(4096)
        if vcs is not None and vcs.tiff_tag_location == 0 and 0 < vcs.value_offset < 32767:
            try:
                axis = pyproj.CRS.from_epsg(int(vcs.value_offset)).axis_info[0]
                return LinearUnit(axis.unit_name, float(axis.unit_conversion_factor))
            except pyproj.exceptions.CRSError:
                pass
        units = keys.get(4099)
        if units is not None and units.tiff_tag_location == 0:
            return _GEOKEY_UNITS.get(int(units.value_offset))
    return None


def _add_vertical_geokeys(header, epsg: int) -> None:
    from laspy.vlrs.known import GeoKeyEntryStruct

    unit = pyproj.CRS.from_epsg(epsg).axis_info[0].unit_conversion_factor
    unit_code = min(_GEOKEY_UNITS, key=lambda c: abs(_GEOKEY_UNITS[c].metres - unit))
    for vlr in header.vlrs:
        if type(vlr).__name__ == "GeoKeyDirectoryVlr":
            keys = [k for k in vlr.geo_keys if k.id not in (4096, 4099)]
            for key_id, value in ((4096, epsg), (4099, unit_code)):
                entry = GeoKeyEntryStruct()
                entry.id, entry.tiff_tag_location, entry.count, entry.value_offset = key_id, 0, 1, value
                keys.append(entry)
            vlr.geo_keys = keys
            vlr.geo_keys_header.number_of_keys = len(keys)
            return


def _balanced(text: str, start: int) -> str | None:
    """The bracketed element of WKT ``text`` that starts at ``start`` (its keyword), brackets balanced."""
    depth, i = 0, text.find("[", start)
    if i < 0:
        return None
    for j in range(i, len(text)):
        depth += {"[": 1, "]": -1}.get(text[j], 0)
        if depth == 0:
            return text[start: j + 1]
    return None


def _proj_reason(err: Exception) -> str:
    """PROJ's reason for refusing a CRS, without the whole WKT pyproj puts before it."""
    import re

    m = re.search(r"proj_create: ([^)]*)", str(err))
    return f"PROJ: {m.group(1)}" if m else str(err)[-160:]


def _horizontal_from_wkt(header):
    """The horizontal CRS inside a WKT record that does not parse as a whole (a broken compound CRS), or None."""
    for vlr in header.vlrs:
        text = getattr(vlr, "string", None)
        if not isinstance(text, str):
            continue
        for key in ("PROJCRS[", "PROJCS[", "PROJECTEDCRS["):
            at = text.upper().find(key)
            part = _balanced(text, at) if at >= 0 else None
            if part:
                try:
                    return pyproj.CRS.from_wkt(part)
                except pyproj.exceptions.CRSError:
                    continue
    return None


_CRS_CACHE: dict = {}  # the CRS records' bytes -> CRS: a delivery's tiles share one CRS, which PROJ builds once
_CRS_CACHE_SIZE = 64


def _crs_key(header):
    """The bytes of the header's CRS records (GeoTIFF keys, OGC WKT), or None where they cannot be had."""
    try:
        records = [v for v in [*header.vlrs, *(getattr(header, "evlrs", None) or [])]
                   if getattr(v, "user_id", "") == "LASF_Projection"]
        return tuple((v.record_id, bytes(v.record_data) if hasattr(v, "record_data") else v.record_data_bytes())
                     for v in records)
    except Exception:  # a record laspy cannot write back: no cache
        return None


def _file_crs(header, path):
    """(the file's CRS or None, a note on a CRS record that does not parse)."""
    key = _crs_key(header)
    cached = _CRS_CACHE.get(key) if key is not None else None  # one lookup: tiles on threads share the cache
    if cached is not None:
        return cached, None
    try:
        crs = header.parse_crs()
        if key is not None:
            if len(_CRS_CACHE) >= _CRS_CACHE_SIZE:
                _CRS_CACHE.clear()
            _CRS_CACHE[key] = crs
        return crs, None
    except Exception as err:  # malformed CRS VLRs
        file_crs = _horizontal_from_wkt(header)
        note = f"the CRS record cannot be parsed ({_proj_reason(err)})" + (
            f"; its horizontal part ({file_crs.name}) is used" if file_crs is not None else "")
        log.warning("%s: %s", path, note)
        return file_crs, note


def _check_record_count(path: Path, header, count: int) -> None:
    """Refuse an uncompressed file shorter than its header promises, or holding more records than it counts."""
    record = header.point_format.size
    needed = header.offset_to_point_data + count * record
    size = os.path.getsize(path)
    if size < needed:
        raise DataFileError(
            f"truncated: the header promises {count:,} points ({needed:,} bytes) but the file has {size:,} bytes",
            path=path,
            hint="Re-copy or re-export the tile",
        )
    # what follows the point records: extended VLRs (LAS 1.4) or waveform packets kept in the file (LAS 1.3)
    after = [o for o in (_evlr_start(header), _internal_waveform_start(header)) if o and o >= needed]
    end = min(after) if after else size
    held = (end - header.offset_to_point_data) // record
    if held > count and _only_zeros(path, needed, end):
        log.warning("%s: %s bytes of zeros after the %s point records (padding), left out", path, f"{end - needed:,}",
                    f"{count:,}")
        return
    if held > count:  # a header that counts fewer points than the file holds: laspy would read only those
        raise DataFileError(
            f"the header counts {count:,} points but the file holds {held:,} point records",
            path=path,
            hint="Repair the header's point count (e.g. lasinfo -repair, or pdal translate) and run again",
        )


def _is_compressed(path: Path, header) -> bool:
    """Whether the points are LAZ, whatever the file's name says (a LAZ file named .las is read as LAZ)."""
    return (path.suffix.lower() == ".laz" or header.point_format.id >= 128
            or bool(getattr(header, "are_points_compressed", False))
            or any(getattr(v, "user_id", "") == "laszip encoded" for v in header.vlrs))


def read_tile_info(path, crs: pyproj.CRS | str | None = None, *, require_crs: bool = True) -> TileInfo:
    """Header facts of one tile, reading no points.

    ``crs`` overrides the file's CRS and is required when the file has none (unless not ``require_crs``: the
    info then has ``crs`` None). A CRS record that does not parse is named as such; when its horizontal part
    parses, that is used (``crs_note`` says so). Raises DataFileError (unreadable, truncated),
    MissingCRSError, EmptyTileError.
    """
    path = Path(path)
    if isinstance(crs, str):
        crs = parse_crs_text(crs)
    if not path.is_file():
        raise DataFileError("file not found", path=path, hint="Check the path")
    try:
        with laspy.open(path) as reader:
            header = reader.header
            file_crs, crs_note = _file_crs(header, path)
            geokey_z = _geokey_z_unit(header)
    except Exception as err:
        raise _open_error(path, err) from None
    count = int(header.point_count)
    compressed = _is_compressed(path, header)
    if count == 0:
        raise EmptyTileError("the tile holds no points", path=path, hint="Remove it from the input or re-export it")
    if not compressed:
        _check_record_count(path, header, count)
    _check_header_numbers(path, header)
    if crs is None and file_crs is None and require_crs:
        raise MissingCRSError(
            crs_note or "header has no CRS",
            path=path,
            hint=f"Pass the tiles' CRS with {option('crs')}, e.g. {option('crs', 'EPSG:2882')}",
        )
    used = crs if crs is not None else file_crs
    if require_crs:
        try:
            horizontal_unit(used)  # refuses geographic CRSs early, naming the CRS
        except InputError as err:
            raise InputError(str(err), path=path) from None
    return TileInfo(
        path=path,
        point_count=count,
        bounds=(float(header.mins[0]), float(header.mins[1]), float(header.maxs[0]), float(header.maxs[1])),
        z_range=(float(header.mins[2]), float(header.maxs[2])),
        crs=used,
        crs_from_file=crs is None,
        version=str(header.version),
        point_format=int(header.point_format.id),
        scales=tuple(float(s) for s in header.scales),
        offsets=tuple(float(o) for o in header.offsets),
        compressed=compressed,
        points_by_return=tuple(int(n) for n in header.number_of_points_by_return),
        geokey_z_unit=geokey_z,
        crs_note=None if crs is not None else crs_note,
        copc=any(getattr(v, "user_id", "") == "copc" for v in header.vlrs),
    )


def _internal_waveform_start(header) -> int | None:
    """Offset of the waveform data packets a LAS 1.3 / 1.4 file holds after its points (global encoding bit 1), or
    None."""
    start = getattr(header, "start_of_waveform_data_packet_record", None)
    encoding = getattr(header, "global_encoding", None)
    internal = getattr(encoding, "waveform_data_packets_internal", None)
    if internal is None:
        try:
            internal = bool(int(getattr(encoding, "value", encoding) or 0) & 2)
        except (TypeError, ValueError):
            internal = False
    return int(start) if start and internal else None


def _only_zeros(path: Path, start: int, end: int, limit: int = 64 * 2**20) -> bool:
    """Whether bytes ``start`` to ``end`` of a file are all zero (read by blocks, up to ``limit`` bytes)."""
    if end - start > limit:
        return False
    with open(path, "rb") as f:
        f.seek(start)
        left = end - start
        while left > 0:
            block = f.read(min(left, 1 << 20))
            if not block or block.count(0) != len(block):
                return bool(not block and left)  # a file shorter than said is not padding
            left -= len(block)
    return True


def _evlr_start(header) -> int | None:
    """Offset of the first extended VLR (LAS 1.4), or None."""
    start = getattr(header, "start_of_first_evlr", None)
    n = getattr(header, "number_of_evlrs", 0)
    return int(start) if start and n else None


def _check_header_numbers(path: Path, header) -> None:
    """Refuse scales, offsets and bounds that cannot give coordinates (0, NaN, inf, far beyond any CRS)."""
    scales, offsets = np.asarray(header.scales, float), np.asarray(header.offsets, float)
    if not np.all(np.isfinite(scales)) or np.any(scales == 0):
        raise DataFileError(f"the header's scale factors {scales.tolist()} are not usable (zero or not finite)",
                            path=path, hint="Repair the header (scales such as 0.01) or re-export the tile")
    if not np.all(np.isfinite(offsets)):
        raise DataFileError(f"the header's offsets {offsets.tolist()} are not finite", path=path,
                            hint="Repair the header or re-export the tile")
    mins, maxs = np.asarray(header.mins, float), np.asarray(header.maxs, float)
    if not (np.all(np.isfinite(mins)) and np.all(np.isfinite(maxs))) or np.any(maxs < mins):
        raise DataFileError(f"the header's bounds (min {mins.tolist()}, max {maxs.tolist()}) are not usable",
                            path=path, hint="Repair the header's bounds (lasinfo -repair_bb, or pdal translate)")
    if np.any(np.abs(np.concatenate([mins, maxs])) > 1e12):
        raise DataFileError(f"the header's bounds (min {mins.tolist()}, max {maxs.tolist()}) lie beyond any map",
                            path=path, hint="Repair the header's bounds (lasinfo -repair_bb, or pdal translate)")


def common_crs(infos: list[TileInfo]) -> pyproj.CRS:
    """The one CRS of a run's tiles; CRSMismatchError naming both files otherwise."""
    first = infos[0]
    for info in infos[1:]:
        if not info.crs.equals(first.crs, ignore_axis_order=True):
            raise CRSMismatchError(
                f"CRS {crs_label(info.crs)} differs from {crs_label(first.crs)} of {first.path}",
                path=info.path,
                hint=f"Reproject the tiles to one CRS, or run them separately; {option('crs')} overrides the CRS of every tile",
            )
        if abs(info.z_unit.metres - first.z_unit.metres) > 1e-9:
            raise CRSMismatchError(
                f"z is in {info.z_unit.name} but in {first.z_unit.name} in {first.path}",
                path=info.path,
                hint=f"Convert the tiles to one vertical unit, or run them separately; {option('crs')} with a compound CRS "
                     "overrides both",
            )
    return first.crs


ALL_FIELDS = ("x", "y", "z", "classification", "return_number", "number_of_returns", "withheld")


def iter_chunks(
    info: TileInfo, chunk_size: int = DEFAULT_CHUNK_SIZE, *, intensity: bool = False, fields=ALL_FIELDS,
    only_fields: bool = False,
) -> Iterator[PointChunk]:
    """Points of a tile, ``chunk_size`` at a time, as :class:`PointChunk` arrays.

    ``fields`` limits what is extracted (the others are None), which saves time on
    big tiles. ``only_fields``: a LAS 1.4 LAZ of point format 6 to 10 (compressed in layers) decodes only the
    layers of ``fields``, X, Y, Z (and intensity when asked): GPS time, scan angle, point source, user data, RGB,
    NIR and extra bytes are skipped, and hold no values in ``raw`` (the caller must not use them). Other files decode
    whole either way. Raises DataFileError naming the file when decoding fails (e.g. a truncated LAZ).
    """
    path = info.path
    selection = decoded_layers(fields, intensity) if only_fields else laspy.DecompressionSelection.all()
    try:
        with laspy.open(path, decompression_selection=selection) as reader:
            need = min(chunk_size, reader.header.point_count) * reader.header.point_format.size
            room_to_decode(reader, need)
            for points in reader.chunk_iterator(chunk_size):
                check_stop()  # a tile on a pool's thread stops here once the run has stopped
                if len(points) == 0:
                    continue
                yield _chunk_from(points, intensity, fields)
                room_to_decode(reader, need)
    except (DataFileError, MemoryError, GeneratorExit, KeyboardInterrupt, Cancelled):
        raise
    except BaseException as err:  # laspy / lazrs raise many types for damaged files; lazrs panics are BaseExceptions
        raise _decoder_error(path, err) from None


# What a decoder needs beyond its arrays (LAZ chunk buffers, a thread's stack and heap arena), in bytes
DECODER_MARGIN = 32 * 2**20


def room_to_decode(reader, need: int) -> None:
    """Under an address-space limit (``ulimit -v``), raise MemoryError before a LAZ decoder fills ``need`` bytes
    of points where it would then be left without room: lazrs (Rust) aborts the whole process on a failed
    allocation, which no handler can catch (numpy's failures are MemoryErrors, and LAS files need no decoder)."""
    if not reader.header.are_points_compressed:
        return
    left = address_space_left()
    if left is not None and left < need + DECODER_MARGIN:
        raise MemoryError(f"{(need + DECODER_MARGIN) / 2**20:.0f} MiB needed to decode, "
                          f"{left / 2**20:.0f} MiB left under the address-space limit")


def _decoder_error(path: Path, err: BaseException) -> Exception:
    """A decoder's failure as MemoryError (lazrs panics when it cannot start its threads) or DataFileError."""
    if not isinstance(err, Exception):
        text = str(err)
        if "thread" in text.lower() or "memory" in text.lower():
            return MemoryError(f"{path.name}: the LAZ decoder could not get memory or threads ({text[:120]})")
        err = RuntimeError(text)
    return _open_error(path, err)


def decoded_layers(fields, intensity: bool = False) -> "laspy.DecompressionSelection":
    """The LAZ layers (laspy.DecompressionSelection) that hold X, Y, Z and ``fields``: in point formats 6 to 10 the
    return numbers share the X, Y layer, the withheld flag is in the flags layer."""
    layers = laspy.DecompressionSelection
    selection = layers.XY_RETURNS_CHANNEL | layers.Z
    if "classification" in fields:
        selection |= layers.CLASSIFICATION
    if "withheld" in fields:
        selection |= layers.FLAGS
    if intensity or "intensity" in fields:
        selection |= layers.INTENSITY
    return selection


_DTYPES = {"x": np.float64, "y": np.float64, "z": np.float64, "classification": np.uint8, "return_number": np.uint8,
           "number_of_returns": np.uint8, "withheld": bool}


def _chunk_from(points, intensity: bool, fields=ALL_FIELDS) -> PointChunk:
    values = {name: (np.asarray(getattr(points, name), _DTYPES[name]) if name in fields else None) for name in ALL_FIELDS}
    return PointChunk(**values, intensity=np.asarray(points.intensity, np.uint16) if intensity else None, raw=points)


def scaled(chunk: PointChunk, axis: str, mask: np.ndarray) -> np.ndarray:
    """x, y or z of the points under ``mask`` (float64), scaled from the raw integers only for them.

    Gives the same values as laspy's scaled arrays (raw * scale + offset).
    """
    full = getattr(chunk, axis)
    if full is not None:
        return full[mask]
    i = "xyz".index(axis)
    raw = np.asarray(getattr(chunk.raw, axis.upper()))[mask]
    return raw * chunk.raw.scales[i] + chunk.raw.offsets[i]


def write_tile(path, points: dict, crs: pyproj.CRS, *, version: str = "1.4", point_format: int = 6,
               scale: float = 0.01, offsets=None, overwrite: bool = False, vertical_epsg: int | None = None) -> Path:
    """Write point arrays (x, y, z, classification, return_number, number_of_returns, optional
    intensity, gps_time) as LAS or LAZ (by suffix), atomically, with the CRS in the header
    (GeoTIFF keys below LAS 1.4, WKT from 1.4). ``vertical_epsg`` adds the vertical CRS as
    GeoTIFF VerticalCSTypeGeoKey / VerticalUnitsGeoKey (e.g. 6360, NAVD88 height in ftUS)."""
    from .raster import atomic_path

    path = Path(path)
    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales = np.array([scale, scale, scale])
    x, y, z = points["x"], points["y"], points["z"]
    header.offsets = np.array(offsets if offsets is not None else [np.floor(x.min()), np.floor(y.min()), 0.0])
    try:
        header.add_crs(crs, keep_compatibility=True)
    except RuntimeError:  # GeoTIFF keys need an EPSG code; a custom CRS goes as a WKT record
        header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(crs.to_wkt()))
    if vertical_epsg is not None:
        _add_vertical_geokeys(header, vertical_epsg)
    las = laspy.LasData(header)
    las.x, las.y, las.z = x, y, z
    for name in ("classification", "return_number", "number_of_returns", "intensity", "gps_time"):
        if name in points and name in las.point_format.dimension_names:
            setattr(las, name, points[name])
    with atomic_path(path, overwrite=overwrite, keep_suffix=True) as tmp:  # laspy picks LAZ by the suffix
        las.write(tmp)
    return path


def read_all_points(path):
    """The whole tile as a laspy LasData (every dimension, extra bytes and VLR kept), or DataFileError."""
    path = Path(path)
    try:
        with laspy.open(path) as reader:
            room_to_decode(reader, reader.header.point_count * reader.header.point_format.size)
            return reader.read()
    except (DataFileError, MemoryError, KeyboardInterrupt):
        raise
    except BaseException as err:  # laspy / lazrs raise many types for damaged files
        err = _decoder_error(path, err)
        if isinstance(err, MemoryError):
            raise err from None
        raise DataFileError(f"cannot read the points ({type(err).__name__}: {err})", path=path,
                            hint="Check the file (a truncated copy?), or leave it out") from None


POINT_FIELDS = ("x", "y", "z", "return_number", "number_of_returns", "classification")


def _empty_points(fields) -> dict:
    return {k: np.zeros(0, np.uint16 if k == "intensity" else np.float64) for k in fields}


def points_in_box(info: TileInfo, box, chunk_size: int = DEFAULT_CHUNK_SIZE, *, fields=POINT_FIELDS,
                  decoded=None) -> dict:
    """``fields`` (x, y, z, return_number, number_of_returns, classification; "intensity" too when asked) of a tile's
    points inside ``box`` (west, south, east, north; CRS units), withheld ones left out: a neighbour's buffer strip.
    COPC files are queried by bounds (only the nodes that reach the box are decoded); others are streamed in chunks.
    ``decoded``: the tile already decoded (a laspy LasData of all its points), read instead of the file."""
    w, s, e, n = box
    parts = []
    if decoded is None and info.copc:
        parts = [_copc_box(info.path, box, fields)]
    else:
        chunks = (iter_chunks(info, chunk_size, intensity="intensity" in fields, only_fields=True) if decoded is None
                  else [_chunk_from(decoded.points, "intensity" in fields)])
        for chunk in chunks:
            keep = (chunk.x >= w) & (chunk.x <= e) & (chunk.y >= s) & (chunk.y <= n) & ~chunk.withheld
            if keep.any():
                parts.append({k: getattr(chunk, k)[keep] for k in fields})
    if not parts:
        return _empty_points(fields)
    if len(parts) == 1:  # a tile in one chunk: its arrays as they are (a concatenation would copy each)
        return parts[0]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _copc_box(path, box, fields=POINT_FIELDS) -> dict:
    w, s, e, n = box
    try:
        with laspy.CopcReader.open(path) as reader:
            lo, hi = reader.header.mins, reader.header.maxs  # a query box beyond the file overflows laspy's int32 keys
            qw, qs, qe, qn = max(w, lo[0]), max(s, lo[1]), min(e, hi[0]), min(n, hi[1])
            if qw > qe or qs > qn:
                return _empty_points(fields)
            pts = reader.query(laspy.copc.Bounds(np.array([qw, qs]), np.array([qe, qn])))
    except Exception as err:
        raise DataFileError(f"cannot query the COPC file ({type(err).__name__}: {err})", path=path,
                            hint="Check the file, or convert it to LAZ") from None
    x, y = np.asarray(pts.x, np.float64), np.asarray(pts.y, np.float64)
    keep = (x >= w) & (x <= e) & (y >= s) & (y <= n) & ~np.asarray(pts.withheld, bool)
    types = {**_DTYPES, "intensity": np.uint16}
    return {k: np.asarray(getattr(pts, k), types[k])[keep] for k in fields}


def write_all_points(las, path, *, overwrite: bool = False, copc_wkt: str | None = None) -> Path:
    """Write a LasData (LAS or LAZ by the suffix; COPC when ``copc_wkt`` is given, the CRS as WKT) atomically;
    the file is read back (header and point count; COPC: its octree) before it takes its name."""
    from .atomic import atomic_path

    def verify(tmp):
        if copc_wkt is not None:
            with laspy.CopcReader.open(tmp) as reader:
                got = len(reader.query())
        else:
            with laspy.open(tmp) as reader:
                got = reader.header.point_count
        if got != len(las.points):
            raise DataFileError(f"wrote {got} of {len(las.points)} points", path=path)

    path = Path(path)
    with atomic_path(path, overwrite=overwrite, keep_suffix=True, verify=verify) as tmp:
        if copc_wkt is not None:
            from .copc import write_copc

            write_copc(las, tmp, crs_wkt=copc_wkt)
        else:
            _drop_copc_records(las)  # a tile read from a COPC file is written as a plain LAS / LAZ
            las.write(tmp)
    return path


def _drop_copc_records(las) -> None:
    """Remove the COPC info VLR and hierarchy EVLR (laspy reads but does not write them): without its octree the
    file is a plain LAZ, which every reader takes."""
    for records in (las.header.vlrs, getattr(las, "evlrs", None), getattr(las.header, "evlrs", None)):
        if records is None:
            continue
        for record in list(records):
            if getattr(record, "user_id", "") == "copc":
                records.remove(record)
