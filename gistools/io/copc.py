"""Writing Cloud Optimized Point Clouds (COPC: LAZ 1.4 with an octree of its points), through copclib.

The octree is built here: the cube of the points' extent is split depth by depth; a voxel holding at most
``max_node_points`` points keeps them all, a fuller one keeps one point per 1/128 of its side (the COPC
spacing at its depth, points taken in a fixed pseudo-random order) and hands the rest to its 8 children.
Every node is compressed with copclib's LAZ compressor and the hierarchy written in one page. COPC holds
point formats 6-8 only: formats 0-5 are converted by laspy (1 -> 6, 3 -> 7 ...), and the points are
stored node by node, so their order is the octree's, not the input's.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..parameters import option

__all__ = ["write_copc", "copc_available"]

_SPACING_DIVISIONS = 128
_MAX_DEPTH = 16


def copc_available() -> bool:
    import importlib.util

    return importlib.util.find_spec("copclib") is not None


def _copc_format(las):
    import laspy

    pf = las.header.point_format.id
    if pf in (6, 7, 8):
        return las
    target = {0: 6, 1: 6, 2: 7, 3: 7, 4: 6, 5: 7}.get(pf)
    if target is None:
        raise InputError(f"point format {pf} has no COPC equivalent", hint=f"Use {option('format', 'laz')}")
    return laspy.convert(las, point_format_id=target, file_version="1.4")


def octree_nodes(x, y, z, mins, span: float, max_node_points: int = 100_000) -> dict:
    """{(depth, kx, ky, kz): point indices} of an octree over the cube (``mins``, side ``span``)."""
    n = len(x)
    order = np.random.default_rng(0).permutation(n)  # a fixed order: each level samples the cloud evenly
    xyz = np.column_stack([x, y, z])[order] - np.asarray(mins, np.float64)
    remaining = np.arange(n)
    nodes = {}
    for depth in range(_MAX_DEPTH + 1):
        if remaining.size == 0:
            break
        cells = 1 << depth
        step = span / cells
        k = np.clip(np.floor(xyz[remaining] / step).astype(np.int64), 0, cells - 1)
        key = (k[:, 0] * cells + k[:, 1]) * cells + k[:, 2]
        uniq, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
        inverse = inverse.ravel()
        leaf = (counts[inverse] <= max_node_points) | (depth == _MAX_DEPTH)
        fine = np.clip(np.floor(xyz[remaining] / (step / _SPACING_DIVISIONS)).astype(np.int64), 0,
                       cells * _SPACING_DIVISIONS - 1)
        side = cells * _SPACING_DIVISIONS
        fine_key = (fine[:, 0] * side + fine[:, 1]) * side + fine[:, 2]
        _, first = np.unique(fine_key, return_index=True)
        keep = leaf.copy()
        keep[first] = True
        for g in np.unique(inverse[keep]):
            members = remaining[keep & (inverse == g)]
            kk = uniq[g]
            nodes[(depth, int(kk // (cells * cells)), int((kk // cells) % cells), int(kk % cells))] = order[members]
        remaining = remaining[~keep]
    return nodes


def write_copc(las, path, *, crs_wkt: str | None, max_node_points: int = 100_000) -> None:
    """Write a LasData as a COPC file at ``path`` (not atomic: the caller writes to a partial name)."""
    import copclib

    if list(las.point_format.extra_dimension_names):
        raise InputError(f"{option('format', 'copc')} does not carry extra-bytes dimensions here",
                         hint=f"Use {option('format', 'laz')}")
    las = _copc_format(las)
    pf = las.header.point_format.id
    x, y, z = (np.asarray(a, np.float64) for a in (las.x, las.y, las.z))
    mins = np.array([x.min(), y.min(), z.min()])
    maxs = np.array([x.max(), y.max(), z.max()])
    span = float(max((maxs - mins).max(), 1e-6))
    scales, offsets = las.header.scales, las.header.offsets
    cfg = copclib.CopcConfigWriter(pf, copclib.Vector3(*map(float, scales)), copclib.Vector3(*map(float, offsets)),
                                   crs_wkt or "")
    cfg.las_header.min = copclib.Vector3(*map(float, mins))
    cfg.las_header.max = copclib.Vector3(*map(float, mins + span))
    cfg.copc_info.spacing = span / _SPACING_DIVISIONS
    # the octree's cube: [mins, mins + span] on every axis, as the nodes were cut (readers take it from here)
    cfg.copc_info.center_x, cfg.copc_info.center_y, cfg.copc_info.center_z = (float(v) for v in mins + span / 2)
    cfg.copc_info.halfsize = span / 2
    writer = copclib.FileWriter(str(path), cfg)
    try:
        records = las.points.array
        for (d, kx, ky, kz), idx in sorted(octree_nodes(x, y, z, mins, span, max_node_points).items()):
            raw = np.ascontiguousarray(records[np.sort(idx)]).view(np.int8).ravel()
            packed = copclib.CompressBytes(copclib.VectorChar(raw), pf, 0)
            writer.AddNodeCompressed(copclib.VoxelKey(d, kx, ky, kz), packed, len(idx))
        writer.copc_config.las_header.min = copclib.Vector3(*map(float, mins))
        writer.copc_config.las_header.max = copclib.Vector3(*map(float, maxs))
    finally:
        writer.Close()
    if crs_wkt:
        wkt_into_vlr(path)


_WKT_USER, _WKT_RECORD = b"LASF_Projection", 2112
_VLR_HEADER, _EVLR_HEADER = 54, 60


def _records(data, start: int, count: int, header: int):
    """(offset of each record's header, user id, record id, data offset, data length) of ``count`` (E)VLRs."""
    import struct

    out, at = [], start
    for _ in range(count):
        user = bytes(data[at + 2: at + 18]).rstrip(b"\0")
        record = struct.unpack_from("<H", data, at + 18)[0]
        length = struct.unpack_from("<Q" if header == _EVLR_HEADER else "<H", data, at + 20)[0]
        out.append((at, user, record, at + header, length))
        at += header + length
    return out


def wkt_into_vlr(path) -> None:
    """Move the CRS of a COPC file from an extended VLR (where copclib writes it) into a regular VLR after the COPC
    info and LAZ VLRs, where QGIS (``QgsLazInfo``), which reads regular VLRs only, finds it. The bytes after the
    VLRs shift by the new record's size, so every absolute offset is moved with them: the point data and EVLR
    starts in the header, the LAZ chunk table pointer, the COPC root hierarchy page and each hierarchy entry.
    The WKT global-encoding bit is set. Not atomic: the caller writes to a partial name."""
    import struct
    from pathlib import Path

    path = Path(path)
    data = bytearray(path.read_bytes())
    point_offset, vlr_count = struct.unpack_from("<II", data, 96)
    evlr_start, evlr_count = struct.unpack_from("<QI", data, 235)
    vlrs = _records(data, 375, vlr_count, _VLR_HEADER)
    evlrs = _records(data, evlr_start, evlr_count, _EVLR_HEADER)
    if any(u == _WKT_USER and r == _WKT_RECORD for _, u, r, _, _ in vlrs):
        return
    wkt = [e for e in evlrs if e[1] == _WKT_USER and e[2] == _WKT_RECORD]
    if not wkt:
        return
    _, _, _, wkt_at, wkt_len = wkt[0]
    payload = bytes(data[wkt_at: wkt_at + wkt_len])
    if len(payload) > 65535:
        return  # too long for a regular VLR: it stays an EVLR
    delta = _VLR_HEADER + len(payload)
    for _, user, record, at, length in vlrs:
        if user == b"copc" and record == 1:  # COPC info: root_hier_offset after five doubles
            struct.pack_into("<Q", data, at + 40, struct.unpack_from("<Q", data, at + 40)[0] + delta)
    for _, user, record, at, length in evlrs:
        if user == b"copc" and record == 1000:  # hierarchy pages: 32-byte entries, the offset at +16
            for e in range(at, at + length, 32):
                offset = struct.unpack_from("<Q", data, e + 16)[0]
                if offset:  # an empty node has offset 0
                    struct.pack_into("<Q", data, e + 16, offset + delta)
    chunk_table = struct.unpack_from("<q", data, point_offset)[0]
    if chunk_table > 0:
        struct.pack_into("<q", data, point_offset, chunk_table + delta)
    struct.pack_into("<II", data, 96, point_offset + delta, vlr_count + 1)
    struct.pack_into("<Q", data, 235, evlr_start + delta)
    struct.pack_into("<H", data, 6, struct.unpack_from("<H", data, 6)[0] | 0x10)
    vlr = bytearray(_VLR_HEADER)
    vlr[2:2 + len(_WKT_USER)] = _WKT_USER
    struct.pack_into("<HH", vlr, 18, _WKT_RECORD, len(payload))
    vlr[22:22 + 16] = b"OGC WKT (gistools)"[:16]
    end = vlrs[-1][3] + vlrs[-1][4] if vlrs else 375  # after the last VLR (bytes a writer left before the points stay)
    with open(path, "wb") as f:
        f.write(data[:end])
        f.write(vlr)
        f.write(payload)
        f.write(data[end:])
