"""The search plan of a lost person: ``gistools search-plan`` (``gistools:search_plan`` in QGIS).

From a DEM with the shrub chain's classes (a ``gistools shrub`` folder) and the point last seen:

* **barriers** (cliffs, water, thickets) and **handrails** (roads, trails, drainages, ridges, thicket edges);
* the **probability of area** (POA) of each cell, from the category's distance rings (Koester 2008), as the crow
  flies or walked on the travel graph, shared within each ring by the category's shares near linear features,
  downhill / level / uphill, and a weight of dense cover;
* **segments** of about the target area bounded by roads, trails, drainages, ridges and thicket edges, each with its
  POA, dominant vegetation, sweep width and the minutes to reach it from the staging points;
* the **probability of detection** (POD) of the searcher-hours given to each segment (Koopman's exponential
  detection function), the probability of success, and the segments ranked by POA x POD per hour;
* **routes**: the quickest walk from the nearest staging point to each segment and point asked for, on the graph of
  ``gistools travel``, and a litter carry from the point last seen to the nearest staging point.

The tables (distance rings, sweep widths) and each threshold are stated with their sources on the documentation's
"Search and rescue" page.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError
from ..grid import affine_apply
from ..terrain.search import RING_SHARES

log = logging.getLogger("gistools.products.search_plan")

__all__ = ["SearchSettings", "search_plan", "lost_person_table", "parse_area", "TABLE"]

TOOL = "gistools search-plan"
TABLE = Path(__file__).resolve().parent.parent / "datasets" / "lost_person.csv"
HECTARE, ACRE = 10_000.0, 4046.8564224
CLASS_NAMES = {0: "none", 1: "light", 2: "medium", 3: "heavy", 4: "road", 5: "water"}
BARRIER_CODES = {1: ("cliff", "#6a3d9a"), 2: ("water", "#1f78b4"), 3: ("thicket", "#1b5e20")}
OUTPUTS = {"poa": "poa.tif", "segments_raster": "segments.tif", "barriers_raster": "barriers.tif",
           "segments": "segments.gpkg", "barriers": "barriers.gpkg", "routes": "routes.gpkg"}
_AREA_WORDS = {"ha": HECTARE, "hectare": HECTARE, "hectares": HECTARE, "ac": ACRE, "acre": ACRE, "acres": ACRE,
               "km2": 1e6, "m2": 1.0, "ft2": 0.3048 ** 2, "sqft": 0.3048 ** 2, "sqm": 1.0}


def parse_area(text, xy_metres: float, *, name: str) -> float:
    """Square metres of an area written "10ha", "25ac", "0.5km2", "500m2", "1000ft2", or a bare number in CRS units
    squared (``xy_metres`` metres a unit).

    >>> parse_area("25ac", 1.0, name="segment_size")
    101171.41056
    >>> parse_area(100, 0.3048, name="segment_size")  # 100 square feet
    9.290304
    """
    import re

    from ..parameters import option

    hint = f"e.g. {option(name, '10ha')} or {option(name, '25ac')}"
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, scale = float(text), xy_metres ** 2
    else:
        m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([A-Za-z0-9]*)\s*", str(text))
        word = m.group(2).lower() if m else ""
        if not m or (word and word not in _AREA_WORDS):
            raise InputError(f"{option(name, str(text))} is not an area", hint=hint)
        try:
            value = float(m.group(1))
        except ValueError:
            raise InputError(f"{option(name, str(text))} is not an area", hint=hint) from None
        scale = _AREA_WORDS[word] if word else xy_metres ** 2
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{option(name, str(text))}: an area must be a finite number above 0", hint=hint)
    return value * scale


@dataclass(frozen=True)
class SearchSettings:
    """Parameters of ``gistools search-plan`` (declared in gistools.parameters.search). Speeds in km/h, slopes in
    degrees, ``detection_ranges`` in metres (open, light, medium, heavy); lengths and areas take a unit (None: the
    default in the data's unit); the walk's model as ``TravelSettings``."""

    ecoregion: str | None = None
    distance: str = "crow"
    search_speed: float = 1.0
    detection_ranges: tuple = (25.0, 15.0, 10.0, 5.0)
    visibility: str = "medium"
    feature_weights: tuple = (3.0, 5.0, 2.0, 1.5, 2.0)
    cover_weight: float = 1.0
    segment_size: str | float | None = None
    near_distance: str | float | None = None
    cliff_slope: float = 45.0
    cliff_height: str | float | None = None
    thicket_area: str | float | None = None
    channel_area: str | float | None = None
    litter_speed: float = 1.0
    litter_max_slope: float = 20.0
    litter_width: str | float | None = None
    road_speed: float | None = None
    wade_speed: float | None = None
    tobler: tuple = (6.0, 3.5, 0.05)
    shrub_factors: tuple = (0.92, 0.83, 0.75)
    neighbours: int | str = 16
    max_memory: float = 4.0
    reproject_vectors: bool = False

    def validate(self) -> None:
        from ..parameters import check, option

        for name in ("distance", "search_speed", "visibility", "cover_weight", "near_distance", "cliff_slope", "cliff_height", "litter_speed",
                     "litter_max_slope", "litter_width", "road_speed", "wade_speed", "max_memory"):
            check(name, getattr(self, name))
        check("neighbours", str(self.neighbours))
        for name, count, example in (("detection_ranges", 4, "25,15,10,5"), ("feature_weights", 5, "3,5,2,1.5,2")):
            values = tuple(getattr(self, name))
            if len(values) != count or not all(math.isfinite(float(v)) and float(v) >= 0 for v in values):
                raise InputError(f"{option(name, values)}: give {count} numbers, each at least 0",
                                 hint=f"e.g. {option(name, example)}")
        for name in ("segment_size", "thicket_area", "channel_area"):
            value = getattr(self, name)
            if value is not None:
                parse_area(value, 1.0, name=name)
        self.travel().validate()

    def travel(self):
        """The walk's settings (``gistools travel``'s) of this plan."""
        from .travel import TravelSettings

        return TravelSettings(tobler=tuple(self.tobler), shrub_factors=tuple(self.shrub_factors),
                              road_speed=self.road_speed, wade_speed=self.wade_speed, neighbours=self.neighbours,
                              max_memory=self.max_memory, reproject_vectors=self.reproject_vectors)


# --- the category's table -----------------------------------------------------------------------------------------

_NEEDED = ("category", "ecoregion", "p25_km", "p50_km", "p75_km", "p95_km")
_SHARES = ("near_linear_share", "downhill_share", "level_share", "uphill_share")


def lost_person_table(path=None) -> list[dict]:
    """The rows of a distance table (the shipped ``datasets/lost_person.csv`` when ``path`` is None): each with
    ``category``, ``ecoregion``, ``rings_m`` (25, 50, 75, 95 % in metres, increasing), the optional shares
    (``near_linear_share``: found near a linear feature; ``downhill_share``, ``level_share``, ``uphill_share``)
    None when blank, and ``source``."""
    from ..parameters import option

    path = Path(path) if path is not None else TABLE
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            rows = [{k: v for k, v in r.items() if isinstance(k, str) and isinstance(v, str)}
                    for r in csv.DictReader(f)]  # extra fields of a row (under the key None) left out
            rows = [r for r in rows if any(v.strip() for v in r.values())]
    except DataFileError:
        raise
    except OSError as err:
        raise DataFileError(f"cannot read the categories table ({err.strerror or err})", path=path) from None
    except (csv.Error, UnicodeDecodeError) as err:
        raise DataFileError(f"the categories table is not a UTF-8 CSV ({err})", path=path) from None
    if not rows or any(c not in rows[0] for c in _NEEDED):
        raise DataFileError(f"the categories table needs the columns {', '.join(_NEEDED)}", path=path,
                            hint=f"Start from the shipped table (gistools search-plan --list-categories) and give it "
                                 f"as {option('categories')}")
    return [_table_row(r, n, path) for n, r in enumerate(rows, start=2)]


def _table_row(r: dict, line: int, path: Path) -> dict:
    def number(key):
        text = (r.get(key) or "").strip()
        if not text:
            return None
        try:
            value = float(text)
        except ValueError:
            raise DataFileError(f"line {line}: {key} {text!r} is not a number", path=path) from None
        if not math.isfinite(value) or value < 0:
            raise DataFileError(f"line {line}: {key} {text!r} must be a finite number at least 0", path=path)
        return value

    rings = [number(k) for k in _NEEDED[2:]]
    if any(v is None or v <= 0 for v in rings) or any(b <= a for a, b in zip(rings, rings[1:])):
        raise DataFileError(f"line {line}: p25_km < p50_km < p75_km < p95_km, all above 0, are needed", path=path)
    row = {"category": category_key(r["category"]), "ecoregion": category_key(r.get("ecoregion") or ""),
           "rings_m": [v * 1000.0 for v in rings], "source": (r.get("source") or "").strip(),
           "n": (r.get("n") or "").strip()}
    row.update({k: number(k) for k in _SHARES})
    slope = [row[k] for k in ("downhill_share", "level_share", "uphill_share")]
    if any(v is not None for v in slope) and (None in slope or abs(sum(slope) - 1.0) > 0.02):
        raise DataFileError(f"line {line}: downhill_share, level_share and uphill_share are given together and sum "
                            "to 1", path=path)
    if row["near_linear_share"] is not None and row["near_linear_share"] > 1:
        raise DataFileError(f"line {line}: near_linear_share is a share, at most 1", path=path)
    return row


def category_key(name) -> str:
    """A category or terrain as the table keys it: lower case, words joined by "_" ("Child 1-3" -> "child_1_3")."""
    import re

    return re.sub(r"[^0-9a-z]+", "_", str(name).strip().lower()).strip("_")


def category_row(table: list[dict], category: str, ecoregion: str | None) -> dict:
    """The row of ``category`` (and ``ecoregion``, else its first row); InputError naming the ones there."""
    from ..parameters import option

    if not category:
        raise InputError(f"no lost person category: give {option('category')}",
                         hint=f"e.g. {option('category', 'dementia')}; the table's: "
                              + ", ".join(sorted({r['category'] for r in table})))
    rows = [r for r in table if r["category"] == category_key(category)]
    if not rows:
        raise InputError(f"{option('category', category)} is not in the categories table",
                         hint="Give one of " + ", ".join(sorted({r['category'] for r in table})))
    if ecoregion:
        pick = [r for r in rows if r["ecoregion"] == category_key(ecoregion)]
        if not pick:
            raise InputError(f"{option('ecoregion', ecoregion)}: the table has no such row for {category}",
                             hint="Give one of " + ", ".join(r["ecoregion"] or "''" for r in rows))
        return pick[0]
    return rows[0]


def _effort(path, segments: int) -> dict[int, float]:
    """{segment: searcher-hours} of the effort CSV (segment,hours); refused: an unknown segment, hours not a finite
    number at least 0, a segment twice."""
    from ..parameters import option

    hours: dict[int, float] = {}
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            reader = csv.DictReader(f)
            fields = [c.strip().lower() for c in (reader.fieldnames or [])]
            if "segment" not in fields or "hours" not in fields:
                raise DataFileError("the effort table needs the columns segment,hours", path=path,
                                    hint="One line a segment: segment,hours (searcher-hours)")
            for line, r in enumerate(reader, start=2):
                r = {k.strip().lower(): (v or "").strip() for k, v in r.items() if isinstance(k, str)
                     and isinstance(v, (str, type(None)))}
                if not r.get("segment"):
                    continue
                seg, h = _effort_row(r, line, path, segments)
                if seg in hours:
                    raise DataFileError(f"line {line}: segment {seg} is given twice", path=path)
                hours[seg] = h
    except DataFileError:
        raise
    except OSError as err:
        raise DataFileError(f"cannot read {option('effort')} ({err.strerror or err})", path=path) from None
    except (csv.Error, UnicodeDecodeError) as err:
        raise DataFileError(f"the effort table is not a UTF-8 CSV ({err})", path=path) from None
    return hours


def _effort_row(r: dict, line: int, path, segments: int) -> tuple[int, float]:
    """(segment, hours) of a line of the effort table, checked: a whole segment number of the plan, hours a finite
    number at least 0."""
    try:
        number, h = float(r["segment"]), float(r.get("hours") or 0)
        seg = int(number)
    except (ValueError, OverflowError):
        raise DataFileError(f"line {line}: segment {r['segment']!r}, hours {r.get('hours')!r}: a segment number "
                            "and hours are needed", path=path) from None
    if seg != number:
        raise DataFileError(f"line {line}: segment {r['segment']!r} is not a whole number", path=path)
    if not 1 <= seg <= segments:
        raise DataFileError(f"line {line}: there is no segment {seg} (the plan has 1-{segments})", path=path,
                            hint="Number the effort by the segments of segments.gpkg")
    if not math.isfinite(h) or h < 0:
        raise DataFileError(f"line {line}: hours {r['hours']!r} must be a finite number at least 0", path=path)
    return seg, h


def _points(values, crs, reproject: bool, name: str) -> list[tuple[float, float, str]]:
    """(x, y, where from) of "X,Y" texts, (x, y) pairs and point layers given as ``name``."""
    from ..io.vector import check_crs, read_layer, split_layer_spec
    from ..parameters import option
    from .travel import _finite_point, _point_text

    if values is None:
        return []
    items = [values] if isinstance(values, (str, Path)) else list(values)
    if len(items) == 2 and all(isinstance(v, (int, float)) for v in items):
        items = [tuple(items)]
    points = []
    for item in items:
        if isinstance(item, (tuple, list)) and len(item) == 2:
            xy = (float(item[0]), float(item[1]))
        else:
            xy = _point_text(item)
        if xy is not None:
            if not all(math.isfinite(v) for v in xy):
                raise InputError(f"{option(name, str(item))}: the coordinates must be finite numbers",
                                 hint="Give X,Y in the DEM's CRS")
            points.append((xy[0], xy[1], str(item) if not isinstance(item, (tuple, list)) else f"{xy[0]},{xy[1]}"))
            continue
        if not str(item).strip() or not split_layer_spec(item)[0].exists():
            raise InputError(f"{option(name, str(item))} is neither X,Y nor a point layer that exists",
                             hint="Give X,Y in the DEM's CRS or a point layer (file.gpkg:LAYER)")
        gdf = check_crs(read_layer(item, kinds=("point",), what=option(name)), crs, str(item), reproject=reproject,
                        against="the DEM's")
        points += [_finite_point(g.x, g.y, str(item)) for g in gdf.geometry.explode(index_parts=False)
                   if g is not None and not g.is_empty]
    return points


def _cells(points, grid, name: str, passable=None) -> list[tuple[int, int]]:
    """(row, column) of each point; refused: off the DEM, or (``passable`` given) on a cell no one can walk."""
    from ..parameters import option

    inv = ~grid.transform
    cells = []
    for x, y, where in points:
        col, row = affine_apply(inv, (x, y))
        r, c = int(math.floor(row)), int(math.floor(col))
        if not (0 <= r < grid.height and 0 <= c < grid.width):
            w, s, e, n = grid.bounds
            raise InputError(f"{option(name, where)}: {x:.3f},{y:.3f} is outside the DEM ({w:.3f},{s:.3f} - "
                             f"{e:.3f},{n:.3f})", hint="Give the point in the DEM's CRS, within it")
        if passable is not None and not passable[r, c]:
            raise InputError(f"{option(name, where)}: {x:.3f},{y:.3f} is on a cell no one walks (water, or no DEM)",
                             hint="Move it onto land nearby")
        cells.append((r, c))
    return cells


# --- the plan -----------------------------------------------------------------------------------------------------

@dataclass
class _Scene:
    """The DEM's cells and what is known of each: heights, classes, roads, water, trails."""

    grid: object
    xy: object
    z: object
    heights: np.ndarray
    classes: np.ndarray
    road: np.ndarray
    water: np.ndarray
    trail: np.ndarray

    @property
    def cell_m(self) -> float:
        return self.grid.cell_size * self.xy.metres


def _scene(dem_path, classes_path, layers: dict, settings: SearchSettings, meta) -> _Scene:
    from ..units import length_to_crs_units
    from .travel import _burn, _classes_on, _lines_of, _read_heights, _roads_and_water

    grid = meta.grid
    heights = _read_heights(meta)
    classes = _classes_on(classes_path, grid) if classes_path is not None else np.zeros(grid.shape, np.uint8)
    from ..parameters import in_data_units

    travel = in_data_units(settings.travel(), meta.xy.is_foot)
    lengths = {name: length_to_crs_units(getattr(travel, name), meta.xy, name=name)
               for name in ("snap", "max_road_width", "max_hydro_width", "single_line_width")}
    road, water = _roads_and_water(grid, layers["roads"], layers["hydro"], layers["waterbodies"], travel, lengths)
    trail = np.zeros(grid.shape, dtype=bool)
    if layers["trails"]:
        from rasterio.features import rasterize

        from ..parameters import option

        lines = _lines_of(layers["trails"], grid.crs, option("trails"), settings.reproject_vectors, ("line",))
        if lines:
            trail = rasterize(lines, out_shape=grid.shape, transform=grid.transform, fill=0, default_value=1,
                              all_touched=True, dtype="uint8").astype(bool)
    road = road | (classes == 4)
    water = (water | (classes == 5)) & ~road
    del _burn
    return _Scene(grid, meta.xy, meta.z, heights, classes, road, water, trail)


def _barriers(scene: _Scene, s: SearchSettings) -> dict:
    """The barrier and handrail cells: cliffs, water, thickets, drainages, ridges (D8 both ways)."""
    from ..terrain.search import cliff_cells, contributing_cells, flow_receivers, thicket_cells
    from ..units import length_to_crs_units

    cell_m = scene.cell_m
    height_m = length_to_crs_units(s.cliff_height, scene.xy, name="cliff_height") * scene.xy.metres
    cliff = cliff_cells(scene.heights, cell_m, scene.z.metres, min_slope=s.cliff_slope, min_height=height_m)
    cliff &= ~scene.road
    thicket = thicket_cells(scene.classes, cell_m ** 2, min_area=parse_area(s.thicket_area, scene.xy.metres,
                                                                            name="thicket_area"))
    channel = max(CHANNEL_CELLS, parse_area(s.channel_area, scene.xy.metres, name="channel_area") / cell_m ** 2)
    has = np.isfinite(scene.heights)
    down = flow_receivers(scene.heights)
    up = flow_receivers(np.where(has, -scene.heights, np.nan))
    drainage = (contributing_cells(down) >= channel) & has & ~scene.water
    ridge = (contributing_cells(up) >= channel) & has & ~scene.water
    return {"cliff": cliff, "water": scene.water, "thicket": thicket, "drainage": drainage, "ridge": ridge,
            "receivers": (down, up)}


CHANNEL_CELLS = 4  # a drainage or a ridge drains at least 4 cells, whatever --channel-area (else every cell is one)


def _edge(mask: np.ndarray) -> np.ndarray:
    """Cells of ``mask`` beside (8-connected) a cell outside it."""
    from scipy import ndimage

    return mask & ~ndimage.binary_erosion(mask, structure=np.ones((3, 3), bool), border_value=1)


def _speeds(scene: _Scene, s: SearchSettings, walls=None, litter: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(factor, fixed speed) of a walker (``travel``'s model, trails walked as roads), or of a litter carry: its
    speed on flat ground, no cell steeper than its limit, no gap narrower than its team, no heavy shrub, cliff or
    water."""
    from ..terrain.search import corridor_open
    from ..terrain.travel import tobler_speed
    from ..units import length_to_crs_units
    from .travel import speed_model

    travel = s.travel()
    classes = scene.classes
    factor, fixed = speed_model(classes, scene.road | scene.trail, scene.water, travel)
    if not litter:
        return factor, fixed
    blocked = walls | (classes == 3) | scene.water | ~np.isfinite(scene.heights)
    width = length_to_crs_units(s.litter_width, scene.xy, name="litter_width") * scene.xy.metres
    steep = _steeper(scene, s.litter_max_slope)
    ok = corridor_open(blocked, scene.cell_m, width) & ~steep & ~blocked
    scale = s.litter_speed / float(tobler_speed(0.0, *travel.tobler))
    factor = np.where(ok, np.where(np.isfinite(fixed), 1.0, factor) * scale, 0.0)
    return factor, np.full(factor.shape, np.nan)


def _steeper(scene: _Scene, limit: float) -> np.ndarray:
    """Cells steeper than ``limit`` degrees by the central differences of the walk's slope or by gdaldem's (Horn's
    3 x 3 window, where the window has heights): a litter is kept off both."""
    from ..terrain.derivatives import terrain_arrays
    from ..terrain.search import slope_degrees

    z = scene.heights * scene.z.metres
    horn = terrain_arrays(np.pad(z, 1, constant_values=np.nan), scene.cell_m, scene.cell_m, products=("slope",))
    with np.errstate(invalid="ignore"):
        return (slope_degrees(scene.heights, scene.cell_m, scene.z.metres) > limit) | (horn["slope"] > limit)


def _solve(scene: _Scene, s: SearchSettings, speeds, sources) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(minutes, predecessors, source of each cell) of the quickest walks from ``sources`` on the travel graph."""
    from scipy.sparse.csgraph import dijkstra

    from ..terrain.travel import walk_graph

    factor, fixed = speeds
    travel = s.travel()
    graph = walk_graph(scene.heights, scene.grid.cell_size, factor=factor, fixed_speed=fixed,
                       xy_metres=scene.xy.metres, z_metres=scene.z.metres, neighbours=int(travel.neighbours),
                       tobler=tuple(travel.tobler))
    cols = scene.grid.width
    index = sorted({r * cols + c for r, c in sources})
    minutes, pred, src = dijkstra(graph, directed=True, indices=index, min_only=True, return_predecessors=True)
    return minutes.reshape(scene.grid.shape), pred, src


def _rings_distance(scene: _Scene, s: SearchSettings, seen_cells, seen_xy, speeds) -> np.ndarray:
    """Each cell's distance from the nearest point last seen in metres: as the crow flies (between cell centres and
    the points), or walked (the minutes on the travel graph times Tobler's speed on flat open ground)."""
    from ..terrain.travel import tobler_speed

    grid = scene.grid
    has = np.isfinite(scene.heights)
    if s.distance == "walk":
        minutes, _pred, _src = _solve(scene, s, speeds, seen_cells)
        flat = float(tobler_speed(0.0, *s.travel().tobler)) * 1000.0 / 60.0  # metres a minute
        d = minutes * flat
    else:
        rows, cols = np.indices(grid.shape)
        x, y = affine_apply(grid.transform, (cols + 0.5, rows + 0.5))
        d = np.min([np.hypot(x - px, y - py) for px, py in seen_xy], axis=0) * scene.xy.metres
    return np.where(has, d, np.nan)


VISIBILITY = {"high": 1.8, "medium": 1.6, "low": 1.1}  # W / Rd, Koester et al. 2014


def _features(scene: _Scene, barriers: dict) -> dict:
    """The cells of each kind of linear feature: roads, trails, water's edge, drainages, ridges, thicket edges."""
    return {"road": scene.road, "trail": scene.trail, "water": _edge(scene.water), "drainage": barriers["drainage"],
            "ridge": barriers["ridge"], "thicket_edge": _edge(barriers["thicket"])}


def _weights(scene: _Scene, s: SearchSettings, barriers: dict, features: dict, near_m: float) -> np.ndarray:
    """Each cell's weight within its ring: 0 on water, cliffs and cells without a DEM; else the largest weight of the
    linear features within ``near_m`` above 1 times the least below 1 (1 away from all), times ``cover_weight`` in
    medium and heavy shrub."""
    from ..terrain.search import near_cells

    has = np.isfinite(scene.heights)
    up, down = np.ones(scene.grid.shape), np.ones(scene.grid.shape)  # the largest weight above 1, the least below
    for kind, w in zip(("road", "trail", "water", "drainage", "ridge"), s.feature_weights):
        w = float(w)
        if w != 1.0 and features[kind].any():
            near = near_cells(features[kind], scene.cell_m, near_m)
            if w > 1:
                up = np.where(near, np.maximum(up, w), up)
            else:
                down = np.where(near, np.minimum(down, w), down)
    weight = up * down
    weight = np.where(np.isin(scene.classes, (2, 3)), weight * float(s.cover_weight), weight)
    return np.where(scene.water | barriers["cliff"] | ~has, 0.0, weight)


def _poa(scene: _Scene, row: dict, distance, weight, near, seen) -> tuple[np.ndarray, list, list]:
    """(POA of each cell, the share each ring holds, the share of each ring's area on the DEM's data), rings around
    the first point last seen ``seen`` (x, y, z)."""
    from ..terrain.search import annulus_inside_fraction, probability_of_area

    grid = scene.grid
    has = np.isfinite(scene.heights)
    inside, low = [], 0.0
    for high in [r / scene.xy.metres for r in row["rings_m"]]:
        inside.append(annulus_inside_fraction(seen[:2], low, high, has, grid.transform))
        low = high
    splits = []
    if row.get("near_linear_share") is not None:
        p = row["near_linear_share"]
        splits.append(([near, ~near], [p, 1.0 - p]))
    if row.get("downhill_share") is not None:
        z0 = seen[2]
        tol = LEVEL_M / scene.z.metres
        z = np.where(has, scene.heights, z0)
        splits.append(([z < z0 - tol, np.abs(z - z0) <= tol, z > z0 + tol],
                       [row["downhill_share"], row["level_share"], row["uphill_share"]]))
    poa, held = probability_of_area(distance, row["rings_m"], inside, weight=weight, splits=splits)
    return poa, held, inside


LEVEL_M = 10.0  # a cell within 10 m of the height of the point last seen is level with it


def _segments_table(scene: _Scene, s: SearchSettings, labels, poa, reach, hours: dict) -> list[dict]:
    """One row a segment: area, POA, dominant class, sweep width, minutes to reach it, hours, coverage, POD, POS and
    the rank by POA x POD per hour (its limit POA x W v / A where no hours are given)."""
    from ..terrain.search import coverage, detection_probability

    n = int(labels.max())
    flat = labels.ravel()
    cell_m2 = scene.cell_m ** 2
    area = np.bincount(flat, minlength=n + 1)[1:] * cell_m2
    poa_sum = np.bincount(flat, weights=poa.ravel(), minlength=n + 1)[1:]
    veg = np.clip(np.where(np.isin(scene.classes, (1, 2, 3)), scene.classes, 0), 0, 3).ravel()
    counts = np.zeros((n + 1, 4))
    np.add.at(counts, (flat, veg), 1)
    counts = counts[1:]
    widths = np.asarray(s.detection_ranges, dtype=np.float64) * VISIBILITY[s.visibility]
    width = counts @ widths / np.maximum(counts.sum(axis=1), 1)
    rows = []
    for k in range(n):
        seg = k + 1
        h = float(hours.get(seg, 0.0))
        cov = float(coverage(width[k], s.search_speed, h, area[k]))
        pod = float(detection_probability(cov))
        rate = float(poa_sum[k] * pod / h) if h > 0 else float(poa_sum[k] * width[k] * s.search_speed * 1000.0
                                                                / area[k])
        inside = reach[labels == seg] if reach is not None else np.array([np.nan])
        minutes = float(np.nanmin(np.where(np.isfinite(inside), inside, np.nan))) if np.isfinite(inside).any() \
            else None
        rows.append({"segment": seg, "area_ha": float(area[k] / HECTARE), "acres": float(area[k] / ACRE),
                     "poa": float(poa_sum[k]), "density": float(poa_sum[k] / (area[k] / HECTARE)),
                     "vegetation": CLASS_NAMES[int(np.argmax(counts[k]))],
                     "sweep_width_m": float(width[k]), "minutes_from_staging": minutes, "hours": h,
                     "coverage": cov, "pod": pod, "pos": float(poa_sum[k] * pod), "pos_per_hour": rate})
    order = sorted(range(n), key=lambda i: -rows[i]["pos_per_hour"])
    for rank, i in enumerate(order, start=1):
        rows[i]["rank"] = rank
    return rows


# --- outputs ------------------------------------------------------------------------------------------------------

def _polygons(labels: np.ndarray, grid, mask=None) -> dict:
    """{label: (Multi)Polygon} of the cells of each label above 0."""
    import shapely
    from rasterio.features import shapes

    mask = labels > 0 if mask is None else mask
    parts: dict[int, list] = {}
    for geom, value in shapes(labels.astype(np.int32), mask=mask, transform=grid.transform, connectivity=4):
        parts.setdefault(int(value), []).append(shapely.geometry.shape(geom))
    return {k: shapely.union_all(v) for k, v in sorted(parts.items())}


def _centres(cells, grid) -> np.ndarray:
    cols = grid.width
    cells = np.asarray(cells, dtype=np.int64)
    x, y = affine_apply(grid.transform, ((cells % cols) + 0.5, (cells // cols) + 0.5))
    return np.stack([x, y], axis=1)


def _route(pred, minutes, target: int, grid, xy_metres: float):
    """(LineString of cell centres, minutes, length in metres) of the path to ``target``; None where none reaches
    it or it is the start itself."""
    import shapely

    from ..terrain.search import cell_path

    if not np.isfinite(minutes.ravel()[target]):
        return None
    path = cell_path(pred, target)
    if len(path) < 2:
        return None
    line = shapely.LineString(_centres(path, grid))
    return line, float(minutes.ravel()[target]), float(line.length * xy_metres)


def _frame(rows: list[dict], geoms: list, crs, columns: dict):
    """A GeoDataFrame of ``rows`` (its ``columns``: {name: dtype}, even when it has no row)."""
    import geopandas as gpd
    import pandas as pd

    data = pd.DataFrame(rows, columns=list(columns)).astype(columns) if rows else \
        pd.DataFrame({k: pd.Series(dtype=v) for k, v in columns.items()})
    return gpd.GeoDataFrame(data, geometry=gpd.GeoSeries(geoms, crs=crs.to_wkt()), crs=crs.to_wkt())


_SEGMENT_COLUMNS = {"segment": "int64", "rank": "int64", "area_ha": "float64", "acres": "float64", "poa": "float64",
                    "density": "float64", "vegetation": "object", "sweep_width_m": "float64",
                    "minutes_from_staging": "float64", "hours": "float64", "coverage": "float64", "pod": "float64",
                    "pos": "float64", "pos_per_hour": "float64"}
_ROUTE_COLUMNS = {"route": "int64", "kind": "object", "target": "object", "start": "object", "minutes": "float64",
                  "length_m": "float64"}


def _route_rows(plan: dict) -> tuple[list, list, list, list]:
    """(rows, lines) of the teams' routes (to each segment, to each point asked for) and of the litter carry."""
    walk, litter = plan["walk"], plan["litter"]
    grid, xy = plan["grid"], plan["xy_metres"]
    rows, lines = [], []
    for seg in plan["segments"]:
        entry = plan["entries"].get(seg["segment"])
        got = _route(walk["pred"], walk["minutes"], entry, grid, xy) if entry is not None else None
        if got:
            rows.append({"route": len(rows) + 1, "kind": "segment", "target": str(seg["segment"]),
                         "start": plan["staging"][int(walk["source"][entry])], "minutes": got[1], "length_m": got[2]})
            lines.append(got[0])
    for (x, y, where), cell in zip(plan["route_to"], plan["route_cells"]):
        got = _route(walk["pred"], walk["minutes"], cell, grid, xy)
        if got:
            rows.append({"route": len(rows) + 1, "kind": "point", "target": where,
                         "start": plan["staging"][int(walk["source"][cell])], "minutes": got[1], "length_m": got[2]})
            lines.append(got[0])
    litter_rows, litter_lines = [], []
    if litter is not None and litter["target"] is not None:
        got = _route(litter["pred"], litter["minutes"], litter["target"], grid, xy)
        if got:
            litter_rows.append({"route": 1, "kind": "litter", "target": plan["staging"][litter["target"]],
                                "start": "point last seen", "minutes": got[1], "length_m": got[2]})
            litter_lines.append(got[0])
    return rows, lines, litter_rows, litter_lines


def _write(out: Path, plan: dict) -> dict:
    """The rasters and GeoPackages of a plan, each written atomically; {key: path}."""
    import shapely

    from ..io.raster import write_raster
    from ..io.styles import categorized_qml, line_qml
    from ..io.vector import write_layers

    grid, crs = plan["grid"], plan["grid"].crs
    files = {k: out / name for k, name in OUTPUTS.items()}
    has = plan["has"]
    write_raster(files["poa"], plan["poa"], grid, dtype="float64", overwrite=True,
                 tags={"GISTOOLS_PRODUCT": "poa"}, description="probability of area (per cell)")
    write_raster(files["segments_raster"], plan["labels"], grid, nodata=0, dtype="int32", overwrite=True,
                 tags={"GISTOOLS_PRODUCT": "segments"}, description="search segment")
    write_raster(files["barriers_raster"], np.where(has | plan["barrier_codes"] > 0, plan["barrier_codes"], 255),
                 grid, nodata=255, dtype="uint8", overwrite=True, tags={"GISTOOLS_PRODUCT": "barriers"},
                 description="barrier", categories={0: ("none", "#ffffff"), **BARRIER_CODES})
    polys = _polygons(plan["labels"], grid)
    seg_rows = [{k: r[k] for k in _SEGMENT_COLUMNS} for r in plan["segments"]]
    segments = _frame(seg_rows, [polys[r["segment"]] for r in seg_rows], crs, _SEGMENT_COLUMNS)
    rings = _frame(plan["ring_rows"], plan["ring_geoms"], crs, {"percent": "int64", "distance_m": "float64",
                                                                  "share": "float64", "held": "float64"})
    points = _frame([{"kind": k, "where": w} for k, (_x, _y, w) in plan["points"]],
                    [shapely.Point(x, y) for _k, (x, y, _w) in plan["points"]], crs,
                    {"kind": "object", "where": "object"})
    write_layers({"segments": segments, "rings": rings, "points": points}, files["segments"], overwrite=True,
                 styles=_segment_styles(segments))
    kinds = _polygons(plan["barrier_codes"], grid)
    barrier_rows, barrier_geoms = [], []
    for code, geom in kinds.items():
        for part in getattr(geom, "geoms", [geom]):
            barrier_rows.append({"kind": BARRIER_CODES[code][0],
                                 "area_ha": part.area * plan["xy_metres"] ** 2 / HECTARE})
            barrier_geoms.append(part)
    barriers = _frame(barrier_rows, barrier_geoms, crs, {"kind": "object", "area_ha": "float64"})
    handrails = _frame([{"kind": k, "length_m": g.length * plan["xy_metres"]} for k, g in plan["handrails"]],
                       [g for _k, g in plan["handrails"]], crs, {"kind": "object", "length_m": "float64"})
    write_layers({"barriers": barriers, "handrails": handrails}, files["barriers"], overwrite=True,
                 styles={"barriers": categorized_qml("kind", {k: (k, c) for k, c in BARRIER_CODES.values()}),
                         "handrails": categorized_qml("kind", HANDRAIL_STYLE, kind="line")})
    rows, lines, litter_rows, litter_lines = _route_rows(plan)
    write_layers({"routes": _frame(rows, lines, crs, _ROUTE_COLUMNS),
                  "litter": _frame(litter_rows, litter_lines, crs, _ROUTE_COLUMNS)}, files["routes"], overwrite=True,
                 styles={"routes": line_qml(ROUTE_COLOUR, 0.6), "litter": line_qml(LITTER_COLOUR, 0.9, dash=True)})
    _poa_style(out, plan)
    plan["route_count"] = (len(rows), len(litter_rows))
    plan["litter_route"] = litter_rows[0] if litter_rows else None
    return {k: str(p) for k, p in files.items()}


ROUTE_COLOUR, LITTER_COLOUR = "#e08214", "#b2182b"  # as the web map and the map book draw them
HANDRAIL_STYLE = {"road": ("road", "#4d4d4d"), "trail": ("trail", "#8c510a"), "drainage": ("drainage", "#2171b5"),
                  "ridge": ("ridge", "#7a0177"), "water_edge": ("water's edge", "#08519c"),
                  "thicket_edge": ("thicket edge", "#1b5e20")}
POA_RAMP = ("#fff5eb", "#fdd0a2", "#fd8d3c", "#d94801", "#7f2704")


def _segment_styles(segments) -> dict:
    """The segments filled by POA in five classes of equal count (labelled with their number), the rings as blue
    outlines, the points as QGIS draws them."""
    from ..io.styles import graduated_fill_qml, outline_qml

    values = np.sort(segments["poa"].to_numpy(dtype=np.float64)) if len(segments) else np.zeros(1)
    breaks = sorted({float(np.quantile(values, q)) for q in np.linspace(0, 1, 6)})
    if len(breaks) < 2:
        breaks = [breaks[0], breaks[0] + 1e-12]
    return {"segments": graduated_fill_qml("poa", breaks, POA_RAMP, label_field="segment"),
            "rings": outline_qml("#2166ac", 0.6)}


def _poa_style(out: Path, plan: dict) -> None:
    """poa.qml beside poa.tif: five classes of the cells' probability (a user's own style there is kept)."""
    from ..io.atomic import atomic_path
    from ..io.styles import pseudocolour_qml, style_is_ours

    target = out / "poa.qml"
    if not style_is_ours(target):
        return
    cells = plan["poa"][plan["poa"] > 0]
    top = float(cells.max()) if cells.size else 1.0
    breaks = sorted({float(v) for v in np.quantile(cells, (0.2, 0.4, 0.6, 0.8))}) if cells.size else [top]
    with atomic_path(target, overwrite=True) as tmp:
        tmp.write_text(pseudocolour_qml(breaks, top, POA_RAMP, ""), encoding="utf-8")


def _handrails(scene: _Scene, barriers: dict, features: dict) -> list:
    """(kind, line) of the handrails: drainages and ridges along their flow lines, the edges of roads, trails, water
    and thickets as the outlines of their cells."""
    import shapely

    from ..terrain.search import receiver_lines

    down, up = barriers["receivers"]
    lines = [("drainage", g) for g in receiver_lines(barriers["drainage"], down, scene.grid.transform)]
    lines += [("ridge", g) for g in receiver_lines(barriers["ridge"], up, scene.grid.transform)]
    for kind, mask in (("road", scene.road), ("trail", scene.trail), ("water_edge", scene.water),
                       ("thicket_edge", barriers["thicket"])):
        if mask.any():
            for geom in _polygons(mask.astype(np.int32), scene.grid).values():
                edge = shapely.line_merge(geom.boundary)
                lines += [(kind, g) for g in getattr(edge, "geoms", [edge])]
    del features
    return lines


def _ring_layer(scene: _Scene, s: SearchSettings, row: dict, seen, distance, held) -> tuple[list, list]:
    """The rings as polygons: annuli around the point last seen (as the crow flies), or the cells of each ring of
    the walked distance."""
    import shapely

    rows, geoms, low = [], [], 0.0
    for k, (high, share) in enumerate(zip(row["rings_m"], RING_SHARES)):
        if s.distance == "crow":
            outer = shapely.Point(seen[:2]).buffer(high / scene.xy.metres, quad_segs=64)
            geom = outer.difference(shapely.Point(seen[:2]).buffer(low / scene.xy.metres, quad_segs=64)) \
                if low > 0 else outer
        else:
            cells = np.isfinite(distance) & (distance >= low) & (distance < high)
            found = _polygons(cells.astype(np.int32), scene.grid)
            geom = found.get(1, shapely.Polygon())
        rows.append({"percent": (25, 50, 75, 95)[k], "distance_m": high, "share": share, "held": held[k]})
        geoms.append(geom)
        low = high
    return rows, geoms


@dataclass(frozen=True)
class _Request:
    """A plan's inputs, checked before any cell is read."""

    meta: object
    settings: SearchSettings
    row: dict
    seen: list
    staging: list
    route_to: list
    inputs: dict


def _request(dem, last_seen, category, settings, staging, route_to, effort, classes, layers, categories):
    """The checked inputs: the DEM's header, the settings in its unit, the category's row, the points on the DEM,
    the effort table's form."""
    from ..parameters import in_data_units, option
    from ..terrain.travel import plan_memory
    from .travel import _dem_inputs, _dem_meta, _last_seen_points

    settings = settings or SearchSettings()
    settings.validate()
    table = lost_person_table(categories)
    row = category_row(table, category, settings.ecoregion)
    dem_path, classes_path = _dem_inputs(dem, classes)
    meta = _dem_meta(dem_path)
    settings = in_data_units(settings, meta.xy.is_foot)
    plan = plan_memory(meta.grid.shape, int(settings.neighbours), settings.max_memory * 1e9)
    if plan["method"] != "whole":
        raise InputError(f"routes need the whole grid's walk graph: {meta.grid.width:,} x {meta.grid.height:,} "
                         f"cells need about {plan['graph_bytes'] / 1e9:.1f} GB, more than "
                         f"{option('max_memory', settings.max_memory)} GB", path=dem_path,
                         hint=f"Raise {option('max_memory')}, or clip the DEM to the search area or use coarser cells")
    seen = _last_seen_points(last_seen, meta.grid.crs, settings.reproject_vectors)
    staging_points = _points(staging, meta.grid.crs, settings.reproject_vectors, "staging") or [seen[0]]
    targets = _points(route_to, meta.grid.crs, settings.reproject_vectors, "route_to")
    for points, name in ((seen, "last_seen"), (staging_points, "staging"), (targets, "route_to")):
        _cells(points, meta.grid, name)
    if effort is not None:
        _effort(effort, 10 ** 9)  # its form now; its segments once they are made
    inputs = {"dem": dem_path, "classes": classes_path, **layers, "effort": effort, "categories": categories}
    return _Request(meta, settings, row, seen, staging_points, targets, inputs)


def _plan(req: _Request, progress) -> dict:
    """Everything of a plan but its files: barriers, POA, segments, the walks from the staging points, the litter."""
    from ..progress import report
    from ..terrain.search import segment_cells
    from ..units import length_to_crs_units

    s, meta = req.settings, req.meta
    grid = meta.grid
    layers = {k: req.inputs[k] for k in ("roads", "trails", "hydro", "waterbodies")}
    report(progress, 0.05, "reading the DEM and the shrub classes")
    scene = _scene(req.inputs["dem"], req.inputs["classes"], layers, s, meta)
    has = np.isfinite(scene.heights)
    report(progress, 0.2, "barriers and handrails")
    barriers = _barriers(scene, s)
    features = _features(scene, barriers)
    near_m = length_to_crs_units(s.near_distance, scene.xy, name="near_distance") * scene.xy.metres
    any_feature = np.logical_or.reduce(list(features.values()))
    from ..terrain.search import near_cells

    near = near_cells(any_feature, scene.cell_m, near_m)
    walls = barriers["cliff"] | barriers["thicket"] | scene.water
    speeds = _speeds(scene, s)
    walkable = (has & (speeds[0] > 0)) | np.isfinite(speeds[1])  # the travel graph's own rule
    seen_cells = _cells(req.seen, grid, "last_seen", passable=walkable)
    staging_cells = _cells(req.staging, grid, "staging", passable=walkable)
    route_cells = _cells(req.route_to, grid, "route_to", passable=walkable)
    report(progress, 0.35, "probability of area")
    distance = _rings_distance(scene, s, seen_cells, [(x, y) for x, y, _w in req.seen], speeds)
    r0, c0 = seen_cells[0]
    seen = (req.seen[0][0], req.seen[0][1], float(scene.heights[r0, c0]))
    weight = _weights(scene, s, barriers, features, near_m)
    poa, held, inside = _poa(scene, req.row, distance, weight, near, seen)
    report(progress, 0.5, "segments")
    searchable = has & ~scene.water & np.isfinite(distance) & (distance < req.row["rings_m"][-1])
    target = parse_area(s.segment_size, scene.xy.metres, name="segment_size")
    labels = segment_cells(searchable, scene.road | scene.trail | barriers["drainage"] | barriers["ridge"],
                           scene.cell_m, target, zones=barriers["thicket"].astype(np.int64))
    segments = int(labels.max())
    hours = _effort(req.inputs["effort"], segments) if req.inputs["effort"] is not None else {}
    report(progress, 0.6, "walks from the staging points")
    cols = grid.width
    minutes, pred, src = _solve(scene, s, speeds, staging_cells)
    names = {}
    for (_x, _y, where), (r, c) in zip(req.staging, staging_cells):
        names.setdefault(r * cols + c, where)
    rows = _segments_table(scene, s, labels, poa, minutes, hours)
    flat_minutes = np.where(np.isfinite(minutes), minutes, np.inf).ravel()
    entries = {}
    for seg in range(1, segments + 1):
        cells = np.flatnonzero(labels.ravel() == seg)
        best = cells[np.argmin(flat_minutes[cells])]
        if np.isfinite(flat_minutes[best]):
            entries[seg] = int(best)
    report(progress, 0.8, "the litter carry")
    litter = _litter(scene, s, barriers, seen_cells[0], sorted(names))
    codes = np.zeros(grid.shape, dtype=np.uint8)
    codes[barriers["thicket"]] = 3
    codes[barriers["cliff"]] = 1
    codes[scene.water] = 2
    ring_rows, ring_geoms = _ring_layer(scene, s, req.row, seen, distance, held)
    points = [("last_seen", p) for p in req.seen] + [("staging", p) for p in req.staging] + \
             [("route_to", p) for p in req.route_to]
    return {"grid": grid, "xy_metres": scene.xy.metres, "has": has, "poa": poa, "held": held, "inside": inside,
            "labels": labels, "segments": rows, "entries": entries, "barrier_codes": codes,
            "walk": {"minutes": minutes, "pred": pred, "source": src}, "litter": litter,
            "staging": names, "route_to": req.route_to, "route_cells": [r * cols + c for r, c in route_cells],
            "ring_rows": ring_rows, "ring_geoms": ring_geoms, "points": points,
            "handrails": _handrails(scene, barriers, features), "near_share": float(near[has].mean()) if has.any()
            else 0.0, "cells": {k: int(v.sum()) for k, v in (("cliff", barriers["cliff"]), ("water", scene.water),
                                                                 ("thicket", barriers["thicket"]),
                                                                 ("drainage", barriers["drainage"]),
                                                                 ("ridge", barriers["ridge"]))},
            "walls": int(walls.sum()), "cell_m2": scene.cell_m ** 2}


def _litter(scene: _Scene, s: SearchSettings, barriers: dict, start: tuple, staging_order: list) -> dict | None:
    """The litter carry's quickest way from the point last seen to the nearest staging point (None: no staging point
    but the point last seen itself)."""
    r, c = start
    cols = scene.grid.width
    begin = r * cols + c
    targets = [v for v in staging_order if v != begin]
    from ..terrain.travel import tobler_speed

    speeds = _speeds(scene, s, walls=barriers["cliff"] | barriers["thicket"], litter=True)
    # the person is carried from where they are, and to the staging point, whatever the shrub or slope there; out
    # of the heavy shrub they are in (its cells open at the heavy shrub's factor), never into another
    from scipy import ndimage

    scale = s.litter_speed / float(tobler_speed(0.0, *s.travel().tobler))
    heavy, _n = ndimage.label(scene.classes == 3, structure=np.ones((3, 3), bool))
    for v in (begin, *targets):
        cell = divmod(v, cols)
        if heavy[cell] > 0:
            way_out = (heavy == heavy[cell]) & np.isfinite(scene.heights) & (speeds[0] <= 0)
            speeds[0][way_out] = scale * float(s.shrub_factors[2])
        if np.isfinite(scene.heights[cell]) and speeds[0][cell] <= 0:
            speeds[0][cell] = scale
    minutes, pred, _src = _solve(scene, s, speeds, [start])
    if not targets:
        return None
    flat = minutes.ravel()
    best = min(targets, key=lambda v: flat[v])
    return {"minutes": minutes, "pred": pred, "target": int(best) if np.isfinite(flat[best]) else None,
            "names": staging_order}


def _refuse_foreign(out: Path) -> None:
    """OutputExistsError for a file at an output's name that no earlier run of the plan wrote (never replaced)."""
    from ..engine.record import read_folder_report
    from ..errors import OutputExistsError

    there = [out / name for name in (*OUTPUTS.values(), "report.json") if (out / name).exists()]
    previous = read_folder_report(out) if (out / "report.json").exists() else None
    if there and (previous or {}).get("tool") != TOOL:
        raise OutputExistsError("a file gistools search-plan did not write is in the way", path=there[0],
                                hint="Move or rename it, or choose another output folder")


def _report(req: _Request, plan: dict, files: dict, started: float) -> dict:
    """report.json of a plan (but ``made``)."""
    s, row = req.settings, req.row
    segs = plan["segments"]
    poa_total = float(plan["poa"][plan["has"]].sum())
    litter = plan.get("litter_route")
    return {
        "tool": TOOL, "crs_wkt": plan["grid"].crs.to_wkt(), "dem": str(req.inputs["dem"]),
        "classes": str(req.inputs["classes"]) if req.inputs["classes"] else None,
        "category": row["category"], "ecoregion": row["ecoregion"], "table_source": row["source"],
        "distance": s.distance, "rings_m": list(row["rings_m"]), "ring_shares": list(RING_SHARES),
        "ring_held": [float(v) for v in plan["held"]], "ring_on_data": [float(v) for v in plan["inside"]],
        "poa_total": poa_total, "rest_of_world": 1.0 - poa_total,
        "last_seen": [{"x": x, "y": y, "from": w} for x, y, w in req.seen],
        "staging": [{"x": x, "y": y, "from": w} for x, y, w in req.staging],
        "segments": len(segs), "segment_area_ha": sum(r["area_ha"] for r in segs),
        "pos_cumulative": float(sum(r["pos"] for r in segs)), "effort_hours": float(sum(r["hours"] for r in segs)),
        "ranked": [r["segment"] for r in sorted(segs, key=lambda r: r["rank"])],
        "sweep_widths_m": dict(zip(("open", "light", "medium", "heavy"),
                                   [float(v) * VISIBILITY[s.visibility] for v in s.detection_ranges])),
        "barrier_cells": plan["cells"], "near_feature_share": plan["near_share"],
        "routes": plan["route_count"][0],
        "litter": ({k: litter[k] for k in ("minutes", "length_m", "target")} if litter else None),
        "warnings": ([] if litter or plan["litter"] is None else
                     ["no litter carry from the point last seen to a staging point: heavy shrub, cliffs, water or "
                      f"slopes past {s.litter_max_slope:g} degrees close every way (or gaps narrower than the team)"]),
        "cell_size": plan["grid"].cell_size, "unit": req.meta.xy.short,
        "outputs": files, "kept": [],
        "settings": {k: (list(v) if isinstance(v, tuple) else v) for k, v in s.__dict__.items()},
        "seconds": round(time.time() - started, 3),
    }


def search_plan(dem, out, last_seen, category, settings: SearchSettings | None = None, *, staging=None,
                route_to=None, effort=None, classes=None, roads=None, trails=None, hydro=None, waterbodies=None,
                categories=None, overwrite: bool = False, progress=None) -> dict:
    """The search plan of a lost person from the point last seen: ``gistools search-plan``.

    Writes under ``out``: ``poa.tif`` (float64 probability of each cell, 0 off the rings and the DEM's data; the
    cells sum to 1 less the rest of the world), ``segments.tif`` (int32 segment numbers), ``barriers.tif`` (uint8: 1 cliff, 2 water,
    3 thicket), ``segments.gpkg`` (layers ``segments``: ``segment``, ``rank``, ``area_ha``, ``acres``, ``poa``,
    ``density`` per ha, ``vegetation``, ``sweep_width_m``, ``minutes_from_staging``, ``hours``, ``coverage``,
    ``pod``, ``pos``, ``pos_per_hour``; ``rings``; ``points``), ``barriers.gpkg`` (``barriers`` polygons and
    ``handrails`` lines, with their ``kind``), ``routes.gpkg`` (``routes`` to each segment and point asked for,
    ``litter``: the carry out; each with ``minutes`` and ``length_m``) and ``report.json``.

    Parameters
    ----------
    dem : str or path
        A ``gistools shrub`` output folder (its ``dem.vrt`` and ``classes.vrt``), or a DEM raster (with
        ``classes``).
    out : str or path
        Output folder, made when missing.
    last_seen : str, tuple or list
        The point last seen (the initial planning point): ``"X,Y"`` in the DEM's CRS, an (x, y) pair, a point
        layer, or a list of them; the rings are around the first, the walked distance from the nearest.
    category : str
        The lost person's category, a row of the table (``lost_person_table()``): hiker, hunter, dementia, ...
    settings : SearchSettings, optional
        ``ecoregion`` (the table's row), ``distance`` ("crow" or "walk"), ``search_speed`` (km/h),
        ``detection_ranges`` (m) and ``visibility``, ``feature_weights``, ``cover_weight``, ``segment_size`` (an
        area, "10ha"), thresholds of cliffs, thickets and drainages, the litter carry's speed, slope and width,
        the walk's model (as ``TravelSettings``). None: the defaults, in the data's unit.
    staging : str, tuple or list, optional
        Staging points (as ``last_seen``). None: the point last seen.
    route_to : str, tuple or list, optional
        Points to route to from the nearest staging point (where a dog alerted).
    effort : str or path, optional
        A CSV of ``segment,hours``: searcher-hours a segment.
    classes, roads, trails, hydro, waterbodies : str, optional
        The shrub classes raster (None: the folder's ``classes.vrt``); road edges, trails (lines), water lines and
        polygons (``file.gpkg:LAYER``), as ``gistools travel`` reads them.
    categories : str or path, optional
        A CSV of your own distance statistics (the columns of ``datasets/lost_person.csv``).
    overwrite : bool
        Make the outputs again whatever an earlier run left. Without it, the outputs of an earlier run with the
        same settings from unchanged inputs are kept; other settings are refused.
    progress : callable, optional
        ``progress(fraction, message)``; returning False cancels the run.

    Returns
    -------
    dict
        The report, also written to ``out/report.json``: ``rings_m`` (the category's distances, metres),
        ``ring_held`` (the probability each ring holds on the DEM), ``rest_of_world``, ``segments`` (how many),
        ``ranked`` (segments by POA x POD per hour), ``pos_cumulative``, ``sweep_widths_m``, ``litter``
        (``minutes``, ``length_m``), ``outputs``, ``settings``, ``seconds``, ``kept``.

    Raises
    ------
    InputError
        An option, category or point is not valid (outside the DEM, in water); the DEM's walk graph passes
        ``max_memory``; ``out`` holds a plan of other settings.
    DataFileError
        The DEM, the categories table or the effort table cannot be read, or the effort names a segment the plan
        does not have.
    OutputExistsError
        A file gistools did not write is at an output's name.
    Cancelled
        ``progress`` returned False.

    Examples
    --------
    >>> from gistools import search_plan, shrub_from_tiles
    >>> B = "sample_tiles/breaklines.gpkg"
    >>> chain = shrub_from_tiles("sample_tiles", "chain", roads=f"{B}:ROADBREAKLINE", waterbodies=f"{B}:WATERBODY",
    ...                          make_map=False)  # doctest: +SKIP
    >>> rep = search_plan("chain", "plan", "431000,1811000", "dementia", staging="431200,1810600")  # doctest: +SKIP
    >>> [round(r) for r in rep["rings_m"]], rep["segments"], round(rep["rest_of_world"], 3)  # doctest: +SKIP
    ([322, 805, 1931, 8208], 7, 0.757)
    """
    from ..engine.record import write_folder_report
    from ..engine.resume import rerun_kept, run_record
    from ..io.outdir import claim_output, output_folder
    from ..progress import report

    started = time.time()
    layers = {"roads": roads, "trails": trails, "hydro": hydro, "waterbodies": waterbodies}
    req = _request(dem, last_seen, category, settings, staging, route_to, effort, classes, layers, categories)
    out = output_folder(out)
    _refuse_foreign(out)
    now = {**{k: (list(v) if isinstance(v, tuple) else v) for k, v in req.settings.__dict__.items()},
           "category": req.row["category"], "ecoregion": req.row["ecoregion"], "rings_m": req.row["rings_m"],
           "last_seen": [list(p[:2]) for p in req.seen], "staging": [list(p[:2]) for p in req.staging],
           "route_to": [list(p[:2]) for p in req.route_to], "layers": {k: str(v) if v else None
                                                                      for k, v in layers.items()}}
    inputs = [v for v in req.inputs.values() if v is not None]
    kept = rerun_kept(out, TOOL, now, inputs, overwrite, started)
    if kept is not None:
        return kept
    plan = _plan(req, progress)
    report(progress, 0.9, "writing the plan")
    with claim_output(out, TOOL):
        files = _write(out, plan)
        rep = _report(req, plan, files, started)
        rep["made"] = run_record(now, inputs, files)
        rep = write_folder_report(out, rep)
    report(progress, 1.0, "done")
    return rep
