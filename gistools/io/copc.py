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
        raise InputError(f"point format {pf} has no COPC equivalent", hint="Use --format laz")
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
        raise InputError("--format copc does not carry extra-bytes dimensions here", hint="Use --format laz")
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
