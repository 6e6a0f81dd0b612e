"""Road and hydro breaklines to polygons (the dissertation's Split and Feature To Polygon, S6-S7).

Edge-of-pavement lines are split by each tile footprint, noded together with the
footprint's boundary (so road strips cut at tile edges close), and polygonised.
Polygonising also closes the blocks *between* roads (spec A9), so a face is kept as
road only when it is narrow (mean width 2A/P <= ``max_width``) and mostly bounded
by breaklines (not a sliver between a road edge and the tile edge).
Lengths are in CRS units.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.ops import polygonize

__all__ = ["faces_from_lines", "road_polygons", "water_polygons"]


def _lines(geoms) -> list:
    out = []
    for g in geoms:
        if g is None or g.is_empty:
            continue
        if g.geom_type in ("LineString", "LinearRing"):
            out.append(g)
        elif g.geom_type == "MultiLineString":
            out.extend(g.geoms)
        elif g.geom_type in ("Polygon", "MultiPolygon"):
            out.extend(_lines([g.boundary]))
    return out


def faces_from_lines(lines, frame: Polygon, *, snap: float = 0.2, max_width: float = 60.0,
                     min_line_share: float = 0.6) -> list[Polygon]:
    """Narrow faces formed by ``lines`` inside ``frame`` (a tile footprint).

    ``snap``: vertices are snapped to a grid of this size before noding (the
    dissertation's 0.2 ft cluster tolerance). A face is kept when its mean width
    2 * area / perimeter <= ``max_width`` and at least ``min_line_share`` of its
    boundary lies on the lines (not on the frame).
    """
    with np.errstate(invalid="ignore"):  # GEOS 3.11 reports empty pieces with NaN coordinates
        clipped = [g for g in (shapely.intersection(ln, frame) for ln in _lines(lines)) if not g.is_empty]
    if not clipped:
        return []
    lines_union = shapely.set_precision(shapely.union_all(_lines(clipped)), snap)
    noded = shapely.union_all([lines_union, shapely.set_precision(frame.boundary, snap)])
    faces = list(polygonize(_lines([noded])))
    keep = []
    on_lines = lines_union.buffer(snap * 2)
    for face in faces:
        if face.area <= 0:
            continue
        width = 2 * face.area / face.length
        if width > max_width:
            continue
        share = face.exterior.intersection(on_lines).length / face.exterior.length
        if share >= min_line_share:
            keep.append(face)
    return keep


def road_polygons(road_lines, frame: Polygon, *, snap: float = 0.2, max_width: float = 60.0) -> MultiPolygon:
    """Road surface of one tile from edge-of-pavement lines (CRS units)."""
    faces = faces_from_lines(road_lines, frame, snap=snap, max_width=max_width)
    return shapely.union_all(faces) if faces else MultiPolygon()


def water_polygons(hydro_lines, waterbodies, frame: Polygon, *, snap: float = 0.2, max_width: float = 500.0,
                   single_line_width: float = 8.0):
    """Water of one tile: WATERBODY polygons (islands stay holes), faces between dual-line
    banks, and single-line features (lines bounding no face) buffered to ``single_line_width``."""
    with np.errstate(invalid="ignore"):
        parts = [shapely.intersection(g, frame) for g in waterbodies if g is not None and not g.is_empty]
    lines = _lines(hydro_lines)
    faces = faces_from_lines(lines, frame, snap=snap, max_width=max_width)
    parts += faces
    face_edges = shapely.union_all([f.boundary for f in faces]).buffer(snap * 4) if faces else None
    for ln in lines:
        with np.errstate(invalid="ignore"):
            piece = shapely.intersection(ln, frame)
        if piece.is_empty:
            continue
        if face_edges is not None and piece.difference(face_edges).length < 0.5 * piece.length:
            continue  # a bank of a dual-line feature
        parts.append(piece.buffer(single_line_width / 2, cap_style="flat"))
    parts = [p for p in parts if not p.is_empty and p.area > 0]
    return shapely.union_all(parts) if parts else MultiPolygon()
