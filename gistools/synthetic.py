"""Synthetic LiDAR scenes with known answers, shaped like a Florida county delivery.

A scene is a block of ground (smooth, rolling), paved roads, a river, a pond with an
island, a narrow creek, wetland, open grass, shrub patches of light / medium / heavy
cover in the 0-1 m, 1-2 m and 2-6 m height bands, trees taller than 6 m and a few
buildings. :func:`scene_points` samples pulses on a jittered grid and gives each
pulse 1-4 returns classified 1 (unclassified), 2 (ground) or 9 (water), as the
Levy County LAS 1.1 tiles are. Coordinates and heights are in the CRS's units
(US survey feet for EPSG:2882). Everything is deterministic for a given seed.

The generator's truth (ground surface function, feature polygons) is what tests
check gistools' results against.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon, box

from .units import US_SURVEY_FOOT

__all__ = ["Scene", "ShrubPatch", "make_scene", "scene_points", "ground_z", "write_breaklines", "BANDS_M", "COVER", "Stand",
           "make_stand", "stand_points", "stand_truth", "stand_ground", "write_stand"]

M = 1.0 / US_SURVEY_FOOT  # ftUS per metre
BANDS_M = {"B1": (0.25, 0.9), "B2": (1.2, 1.85), "B3": (2.35, 5.6)}  # crown top heights per band (m)
CROWN_RADIUS_FT = (3.5, 6.5)
CROWN_SHAPE = 0.1  # a crown's top falls by this fraction from its centre to its rim
COVER = {"light": 0.15, "medium": 0.5, "heavy": 0.9}  # crown cover fraction, mid-class of 0-0.3-0.7-1


@dataclass
class ShrubPatch:
    """A patch of shrub: its outline, cover class, band, and its crowns (x, y, radius, top height in ft).

    Crowns are opaque discs placed at random (a Boolean model) so that they cover the
    patch's cover fraction of its area; what the patch looks like from above is the crowns.
    """

    geometry: Polygon
    cover: str  # light / medium / heavy
    band: str  # B1 / B2 / B3
    crowns: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))

    @property
    def crown_union(self):
        discs = shapely.buffer(shapely.points(self.crowns[:, :2]), self.crowns[:, 2], quad_segs=16)
        return shapely.intersection(shapely.union_all(discs), self.geometry)


@dataclass
class Scene:
    """Feature geometry of a block, in CRS coordinates (ftUS)."""

    origin: tuple[float, float]
    size: tuple[float, float]
    roads: list[Polygon] = field(default_factory=list)
    river: Polygon | None = None
    river_centre: LineString | None = None
    creek: LineString | None = None
    creek_width: float = 6.0
    pond: Polygon | None = None
    wetland: list[Polygon] = field(default_factory=list)
    shrubs: list[ShrubPatch] = field(default_factory=list)
    trees: list[tuple[float, float, float, float]] = field(default_factory=list)  # x, y, crown radius, height
    buildings: list[tuple[Polygon, float]] = field(default_factory=list)

    @property
    def bounds(self):
        x0, y0 = self.origin
        return (x0, y0, x0 + self.size[0], y0 + self.size[1])

    @property
    def road_union(self):
        return shapely.union_all(self.roads)

    @property
    def water_union(self):
        parts = [g for g in (self.river, self.pond) if g is not None]
        if self.creek is not None:
            parts.append(self.creek.buffer(self.creek_width / 2))
        return shapely.union_all(parts)


def ground_z(x, y, origin=(0.0, 0.0)):
    """True ground height (ftUS) of the synthetic scenes at (x, y): gently rolling, 25-45 ft."""
    u = np.asarray(x, np.float64) - origin[0]
    v = np.asarray(y, np.float64) - origin[1]
    return 35.0 + 4.0 * np.sin(u / 310.0) * np.cos(v / 270.0) + 0.0015 * u - 0.001 * v + 1.5 * np.sin((u + v) / 140.0)


def _ellipse(cx, cy, rx, ry, angle=0.0, wobble=0.0, rng=None, n=48):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1.0 + (wobble * np.sin(3 * t + (rng.uniform(0, 6) if rng is not None else 0.0)))
    px, py = rx * r * np.cos(t), ry * r * np.sin(t)
    ca, sa = np.cos(angle), np.sin(angle)
    return Polygon(np.column_stack([cx + ca * px - sa * py, cy + sa * px + ca * py]))


def make_scene(origin=(430000.0, 1810000.0), size=(2000.0, 2000.0), seed: int = 35712) -> Scene:
    """A deterministic scene of ``size`` ftUS with its south-west corner at ``origin``.

    Features are laid out relative to the block size, so larger blocks (benchmarks)
    get the same kinds of features, repeated.
    """
    rng = np.random.default_rng(seed)
    x0, y0 = origin
    W, H = size
    sc = Scene(origin=(x0, y0), size=(W, H))
    # Roads: east-west roads every ~1400 ft, a curving north-south road every ~1300 ft.
    for k, v in enumerate(np.arange(0.7, H / 2000.0 * 2, 1.4)[: max(1, int(H // 1400))]):
        yc = y0 + v * 1000.0
        sc.roads.append(LineString([(x0 - 50, yc), (x0 + W + 50, yc)]).buffer(12.0, cap_style="flat"))
    for k in range(max(1, int(W // 1300))):
        xc = x0 + 700.0 + 1300.0 * k
        vs = np.linspace(-50, H + 50, 80)
        line = LineString(np.column_stack([xc + 60 * np.sin(vs / 400.0), y0 + vs]))
        sc.roads.append(line.buffer(11.0, cap_style="flat"))
    # River: meander west-east near the south of the block; creek from pond to river.
    us = np.linspace(-50, W + 50, 200)
    sc.river_centre = LineString(np.column_stack([x0 + us, y0 + 0.25 * H + 120 * np.sin(us / 300.0)]))
    sc.river = sc.river_centre.buffer(22.5, cap_style="flat")  # runs past the block edges
    pond_c = (x0 + 0.78 * W, y0 + 0.86 * H)
    pond = _ellipse(*pond_c, 130, 85, angle=0.3)
    island = _ellipse(*pond_c, 26, 20)
    sc.pond = Polygon(pond.exterior.coords, [island.exterior.coords])
    sc.creek = LineString([(pond_c[0] - 40, pond_c[1] - 80), (x0 + 0.62 * W, y0 + 0.62 * H), (x0 + 0.55 * W, y0 + 0.3 * H)])
    sc.wetland = [_ellipse(x0 + 0.18 * W, y0 + 0.12 * H, 0.12 * W, 0.07 * H, angle=0.2, wobble=0.1, rng=rng)]
    # Buildings: a few houses near the roads.
    for bx, by in [(0.30, 0.76), (0.45, 0.76), (0.30, 0.63), (0.60, 0.50)]:
        cx, cy = x0 + bx * W, y0 + by * H
        # two-storey roofs, 22-30 ft (6.7-9.1 m): above the shrub bands (lower roofs would be "shrub", spec A17)
        sc.buildings.append((box(cx - 30, cy - 20, cx + 30, cy + 20), float(rng.uniform(22, 30))))
    blocked = shapely.union_all([sc.road_union.buffer(10), sc.water_union.buffer(10)] + [b.buffer(15) for b, _ in sc.buildings])
    placed = _place_patches(sc, blocked, rng)
    # One low shrub patch inside the wetland (vegetation inside wetlands).
    wet = sc.wetland[0]
    c = wet.centroid
    patch = _ellipse(c.x, c.y, 40, 30)
    if not patch.intersects(blocked):
        sc.shrubs.append(ShrubPatch(patch, "medium", "B1", _crowns(patch, "medium", "B1", rng)))
        placed.append(patch)
    # Trees taller than 6 m in small groves.
    taken = shapely.union_all([blocked] + [p.buffer(10) for p in placed])
    shapely.prepare(taken)
    n_groves = max(6, int(W * H / 0.5e6))
    for _ in range(n_groves * 8):
        gx, gy = x0 + rng.uniform(60, W - 60), y0 + rng.uniform(60, H - 60)
        for _ in range(int(rng.integers(6, 14))):
            tx, ty = gx + rng.normal(0, 35), gy + rng.normal(0, 35)
            r = float(rng.uniform(10, 18))
            if taken.intersects(Point(tx, ty).buffer(r)):
                continue
            sc.trees.append((tx, ty, r, float(rng.uniform(40, 75))))
        if len(sc.trees) >= n_groves * 10:
            break
    return sc


def _place_patches(sc: Scene, blocked, rng) -> list[Polygon]:
    """Shrub patches into ``sc.shrubs``: every cover x band combination at least once, on ground free of
    ``blocked``, 20 ft apart; the patches placed."""
    x0, y0 = sc.origin
    W, H = sc.size
    combos = [(c, b) for c in COVER for b in BANDS_M]
    n_patches = max(2 * len(combos), int(round(2 * len(combos) * W * H / 4.0e6)))
    placed: list[Polygon] = []
    boxes = []  # the placed patches' bounds: only those within 20 ft of a candidate's are measured
    shapely.prepare(blocked)  # prepared: the same answers, faster on a county-sized block
    tries = 0
    while len(sc.shrubs) < n_patches and tries < 5000:
        tries += 1
        cover, band = combos[len(sc.shrubs) % len(combos)]
        rx, ry = rng.uniform(60, 120), rng.uniform(45, 95)
        cx, cy = x0 + rng.uniform(rx + 20, W - rx - 20), y0 + rng.uniform(ry + 20, H - ry - 20)
        poly = _ellipse(cx, cy, rx, ry, angle=rng.uniform(0, np.pi), wobble=0.12, rng=rng)
        if poly.intersects(blocked):
            continue
        w_, s_, e_, n_ = poly.bounds
        near = [p for p, (a, b, c, d) in zip(placed, boxes) if a < e_ + 20 and c > w_ - 20 and b < n_ + 20 and d > s_ - 20]
        if any(poly.distance(p) < 20 for p in near):
            continue
        placed.append(poly)
        boxes.append(poly.bounds)
        sc.shrubs.append(ShrubPatch(poly, cover, band, _crowns(poly, cover, band, rng)))
    return placed


def _crowns(poly, cover: str, band: str, rng) -> np.ndarray:
    """Crowns (x, y, r, top ft) covering COVER[cover] of ``poly`` (within 2 %): discs on a jittered
    grid whose spacing is tuned to the cover (shrubs of one stand are spread fairly evenly; a pure
    Boolean model clumps too much to give one cover class over a 25 ft neighbourhood)."""
    lo_r, hi_r = CROWN_RADIUS_FT
    lo, hi = BANDS_M[band]
    mean_area = np.pi * (lo_r * lo_r + lo_r * hi_r + hi_r * hi_r) / 3
    f = COVER[cover]
    w, s, e, n = poly.bounds
    spacing = np.sqrt(mean_area / f)
    state = rng.bit_generator.state
    for _ in range(6):
        rng.bit_generator.state = state  # the same draws each try: only the spacing changes
        gx, gy = np.meshgrid(np.arange(w, e, spacing), np.arange(s, n, spacing))
        x = gx.ravel() + rng.uniform(-0.35, 0.35, gx.size) * spacing
        y = gy.ravel() + rng.uniform(-0.35, 0.35, gy.size) * spacing
        r = rng.uniform(lo_r, hi_r, gx.size)
        top = rng.uniform(lo * M, hi * M, gx.size)
        keep = shapely.contains_xy(poly, x, y)
        discs = shapely.buffer(shapely.points(x[keep], y[keep]), r[keep], quad_segs=16)
        got = shapely.intersection(shapely.union_all(discs), poly).area / poly.area
        if abs(got - f) < 0.01:
            break
        spacing *= np.sqrt(got / f)
    return np.column_stack([x[keep], y[keep], r[keep], top[keep]])


def _inside(poly, x, y):
    """Boolean mask of points inside ``poly`` (bounding box first, then exact test)."""
    w, s, e, n = poly.bounds
    cand = np.nonzero((x >= w) & (x <= e) & (y >= s) & (y <= n))[0]
    mask = np.zeros(len(x), bool)
    if len(cand):
        mask[cand] = shapely.contains_xy(poly, x[cand], y[cand])
    return mask


def scene_points(scene: Scene, bounds, *, spacing: float = 4.0, seed: int = 0) -> dict:
    """Returns of pulses on a jittered ``spacing`` grid inside ``bounds`` (west, south, east, north), half-open.

    Returns a dict of arrays: x, y, z (ftUS), classification, return_number,
    number_of_returns, intensity, gps_time.
    """
    rng = np.random.default_rng(seed)
    w, s, e, n = bounds
    gx = np.arange(w + spacing / 2, e, spacing)
    gy = np.arange(s + spacing / 2, n, spacing)
    px, py = np.meshgrid(gx, gy)
    px = (px + rng.uniform(-0.4, 0.4, px.shape) * spacing).ravel()
    py = (py + rng.uniform(-0.4, 0.4, py.shape) * spacing).ravel()
    keep = (px >= w) & (px < e) & (py >= s) & (py < n)
    px, py = px[keep], py[keep]
    npulse = len(px)
    gz = ground_z(px, py, scene.origin)
    # Surface type of each pulse, later features win: 0 ground, 1 road, 2 water, 3 shrub, 4 tree, 5 building.
    kind = np.zeros(npulse, np.int8)
    top = np.full(npulse, np.nan)  # height above ground of the first return (ft)
    cover = np.zeros(npulse)
    crowns = [(p.crowns, COVER[p.cover]) for p in scene.shrubs if len(p.crowns)]
    if crowns:
        from scipy.spatial import cKDTree

        c = np.concatenate([a for a, _ in crowns])
        c_cover = np.concatenate([np.full(len(a), f) for a, f in crowns])
        d, i = cKDTree(c[:, :2]).query(np.column_stack([px, py]), k=8, distance_upper_bound=CROWN_RADIUS_FT[1])
        ok = np.isfinite(d)
        i = np.where(ok, i, 0)
        inside = ok & (d <= c[i, 2])
        height = np.where(inside, c[i, 3] * (1 - CROWN_SHAPE * (d / c[i, 2]) ** 2), -np.inf)
        best = height.max(axis=1)
        hit = np.isfinite(best) & (rng.random(npulse) < 0.97)  # a few pulses slip through gaps in the foliage
        kind[hit] = 3
        top[hit] = best[hit]
        cover[hit] = c_cover[i[np.arange(npulse), height.argmax(axis=1)]][hit]
    if scene.trees:
        t = np.array(scene.trees)
        from scipy.spatial import cKDTree

        tree = cKDTree(t[:, :2])
        d, i = tree.query(np.column_stack([px, py]), distance_upper_bound=t[:, 2].max())
        ok = np.isfinite(d)
        ok[ok] = d[ok] <= t[i[ok], 2]
        hit = ok & (rng.random(npulse) < 0.92)
        r_rel = d[hit] / t[i[hit], 2]
        kind[hit] = 4
        top[hit] = t[i[hit], 3] * (1 - 0.35 * r_rel**2) - rng.uniform(0, 2, hit.sum())
    water = _inside(scene.water_union, px, py)
    kind[water] = 2
    road = _inside(scene.road_union, px, py)
    kind[road] = 1
    for poly, height in scene.buildings:
        m = _inside(poly, px, py)
        kind[m] = 5
        top[m] = height
    # Water surface: 3 ft under the banks' ground, smoothed along the river.
    wz = gz - 3.0
    # Returns per pulse.
    nret = np.ones(npulse, np.int64)
    veg = kind == 3
    ground_seen = rng.random(npulse) > 0.7 * cover  # denser shrub hides more ground
    nret[veg & ground_seen] = 2
    tall_shrub = veg & (top > 2.3 * M)
    nret[tall_shrub & ground_seen] = np.where(rng.random((tall_shrub & ground_seen).sum()) < 0.5, 3, 2)
    tree = kind == 4
    nret[tree] = rng.integers(1, 5, tree.sum())
    water_dropout = (kind == 2) & (rng.random(npulse) < 0.15)  # specular water gives no return sometimes
    keep_pulse = ~water_dropout
    total = int(nret[keep_pulse].sum())
    pulse = np.repeat(np.nonzero(keep_pulse)[0], nret[keep_pulse])
    rn = np.arange(total) - np.repeat(np.cumsum(nret[keep_pulse]) - nret[keep_pulse], nret[keep_pulse]) + 1
    nr = nret[pulse]
    k = kind[pulse]
    x = px[pulse] + rng.normal(0, 0.05, total)
    y = py[pulse] + rng.normal(0, 0.05, total)
    g = gz[pulse]
    z = g.copy()
    cls = np.full(total, 2, np.uint8)
    inten = rng.integers(120, 240, total)
    last = rn == nr
    # Ground noise: open terrain RMSEz about 0.1 ft here (the delivery tested 0.30 ft).
    z += rng.normal(0, 0.08, total)
    # Vegetation and buildings: returns above ground; the last of several returns is ground.
    above = (k >= 3) & ~(last & (nr > 1))
    frac = np.where(rn == 1, 1.0, rng.uniform(0.2, 0.8, total))
    z[above] = g[above] + top[pulse][above] * frac[above]
    cls[above] = 1
    inten[above] = rng.integers(60, 200, above.sum())
    # Trees with one return: canopy only, no ground.
    w_ = k == 2
    z[w_] = wz[pulse][w_] + rng.normal(0, 0.03, w_.sum())
    cls[w_] = 9
    inten[w_] = rng.integers(2, 25, w_.sum())
    r_ = k == 1
    inten[r_] = rng.integers(20, 70, r_.sum())
    return {
        "x": x, "y": y, "z": z, "classification": cls,
        "return_number": rn.astype(np.uint8), "number_of_returns": nr.astype(np.uint8),
        "intensity": inten.astype(np.uint16),
        "gps_time": 86400.0 * 190 + np.arange(total) * 1e-5,
    }


def _edges_within(geom, block):
    """Edge lines of a (multi)polygon inside ``block``, merged where they join (no block-edge segments)."""
    lines = shapely.line_merge(geom.boundary.intersection(block))
    return list(getattr(lines, "geoms", [lines]))


def write_breaklines(scene: Scene, footprints: list[dict], gpkg, crs) -> None:
    """The delivery's breakline layers for a scene, as a GeoPackage: FOOTPRINT (``footprints``: dicts
    with a geometry and fields), ROADBREAKLINE (edge of pavement, both sides), HYDROGRAPHICFEATURE
    (river banks and a single-line creek), WATERBODY (river and pond with its island) and WETLAND."""
    import geopandas as gpd

    block = box(*scene.bounds)
    gpd.GeoDataFrame(footprints, crs=crs).to_file(gpkg, layer="FOOTPRINT")
    road_edges = _edges_within(scene.road_union, block)
    gpd.GeoDataFrame({"TYPE": ["EDGE_OF_PAVEMENT"] * len(road_edges)}, geometry=road_edges, crs=crs).to_file(
        gpkg, layer="ROADBREAKLINE")
    hydro = [(ln, "DUAL_LINE_BANK") for ln in _edges_within(scene.river, block)] + [(scene.creek, "SINGLE_LINE")]
    gpd.GeoDataFrame({"TYPE": [t for _, t in hydro]}, geometry=[g for g, _ in hydro], crs=crs).to_file(
        gpkg, layer="HYDROGRAPHICFEATURE")
    gpd.GeoDataFrame({"NAME": ["river", "pond"]}, geometry=[scene.river.intersection(block), scene.pond], crs=crs).to_file(
        gpkg, layer="WATERBODY")
    gpd.GeoDataFrame({"NAME": ["wetland"] * len(scene.wetland)}, geometry=scene.wetland, crs=crs).to_file(
        gpkg, layer="WETLAND")


# --- a forest stand for canopy fuels (gistools fuels) --------------------------------------------------------------
@dataclass
class Stand:
    """Crowns on a lattice of ``cell``-metre cells (metres, a UTM CRS): cones (apex up, widest at the base) or
    half-ellipsoids (a dome on a flat base), one shape per cell.

    ``cells``: one row per cell: col, row, crown base (m above ground), top (m), radius (m), tree spacing (m),
    foliage bulk density inside the crowns (kg/m3) and shape (0 cone, 1 half-ellipsoid); spacing 0 is a cell
    without trees. ``trees``: x, y, radius, base, top, density, shape, one row per tree; every crown lies inside its
    cell and no two crowns overlap.
    """

    origin: tuple[float, float]
    cell: float
    shape: tuple[int, int]  # cells (cols, rows)
    cells: np.ndarray
    trees: np.ndarray
    margin: float = 30.0  # bare ground around the cells

    @property
    def bounds(self):
        x0, y0 = self.origin
        return (x0 - self.margin, y0 - self.margin, x0 + self.shape[0] * self.cell + self.margin,
                y0 + self.shape[1] * self.cell + self.margin)


def stand_ground(x, y, origin):
    """The stand's ground elevation (m): a plane rising 6 % to the north-east with a gentle swell."""
    dx, dy = np.asarray(x) - origin[0], np.asarray(y) - origin[1]
    return 120.0 + 0.04 * dx + 0.045 * dy + 1.5 * np.sin(dx / 23.0) * np.cos(dy / 31.0)


def make_stand(origin=(500010.0, 4100010.0), shape=(4, 3), cell: float = 30.0, seed: int = 7) -> Stand:
    """A stand of ``shape`` cells of varied crowns, one cell bare. Bases 2.5-12 m, crown lengths 4-12 m, radii
    1.5-3 m, foliage 0.08-0.3 kg/m3 (leaf area density 0.6-2 m2/m3 at 0.141 kg/m2), crown cover 30-75 %."""
    rng = np.random.default_rng(seed)
    cells, trees = [], []
    for row in range(shape[1]):
        for col in range(shape[0]):
            if (col, row) == (0, 0):
                cells.append((col, row, 0, 0, 0, 0, 0, 0))
                continue
            base = rng.uniform(2.5, 12.0)
            top = base + rng.uniform(4.0, 12.0)
            radius = rng.uniform(1.5, 3.0)
            spacing = 2 * radius * rng.uniform(1.02, 1.6)
            rho = rng.uniform(0.08, 0.3)
            shape_ = (col + row) % 2
            cells.append((col, row, base, top, radius, spacing, rho, shape_))
            n = int(cell // spacing)
            off = (cell - n * spacing) / 2 + spacing / 2
            gx = origin[0] + col * cell + off + spacing * np.arange(n)
            gy = origin[1] + row * cell + off + spacing * np.arange(n)
            tx, ty = np.meshgrid(gx, gy)
            for x, y in zip(tx.ravel(), ty.ravel()):
                trees.append((x, y, radius, base, top, rho, shape_))
    return Stand(origin, cell, shape, np.asarray(cells, float), np.asarray(trees, float))


def stand_points(stand: Stand, *, density: float = 20.0, extinction: float = 0.5, leaf_mass_area: float = 0.141,
                 seed: int = 0) -> dict:
    """Returns of vertical pulses at ``density`` per square metre, uniformly placed (metres).

    Through a crown the pulse meets foliage as a Beer-Lambert medium: interceptions are a Poisson process of rate
    ``extinction`` x leaf area density (= foliage density / ``leaf_mass_area``) per metre of path; each interception
    is a return (up to 4), and a pulse that leaves the crown with fewer than 4 returns ends on the ground (class 2;
    vegetation returns are class 1)."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    w, s, e, n = stand.bounds
    count = rng.poisson(density * (e - w) * (n - s))
    px, py = rng.uniform(w, e, count), rng.uniform(s, n, count)
    gz = stand_ground(px, py, stand.origin)
    t = stand.trees
    entry = np.zeros(count)  # height above ground where the pulse enters a crown, and the path through it
    path = np.zeros(count)
    rate = np.zeros(count)
    if len(t):
        d, i = cKDTree(t[:, :2]).query(np.column_stack([px, py]))
        r, base, top = t[i, 2], t[i, 3], t[i, 4]
        hit = d < r
        u = np.minimum(d / r, 1.0)
        depth_ = np.where(t[i, 6] > 0, np.sqrt(1 - u ** 2), 1 - u) * (top - base)  # the crown's height above its base
        entry[hit] = (base + depth_)[hit]
        path[hit] = entry[hit] - base[hit]
        rate[hit] = extinction * t[i, 5][hit] / leaf_mass_area
    xs, ys, zs, ret, cls = [], [], [], [], []
    depth = np.zeros(count)
    alive = np.ones(count, bool)  # still inside its crown
    nret = np.zeros(count, np.int64)
    for k in range(4):
        with np.errstate(divide="ignore"):
            depth = depth + np.where(rate > 0, rng.exponential(1.0, count) / np.where(rate > 0, rate, 1.0), np.inf)
        stop = alive & (depth < path)
        alive &= stop
        nret[stop] += 1
        xs.append(px[stop]), ys.append(py[stop]), zs.append((gz + entry - depth)[stop])
        ret.append(np.full(int(stop.sum()), k + 1)), cls.append(np.full(int(stop.sum()), 1))
        idx = np.flatnonzero(stop)
        if k == 0:
            pulse_of = [idx]
        else:
            pulse_of.append(idx)
    ground = nret < 4
    nret[ground] += 1
    xs.append(px[ground]), ys.append(py[ground]), zs.append(gz[ground])
    ret.append(nret[ground]), cls.append(np.full(int(ground.sum()), 2))
    pulse_of.append(np.flatnonzero(ground))
    pulse = np.concatenate(pulse_of)
    out = {"x": np.concatenate(xs), "y": np.concatenate(ys), "z": np.concatenate(zs),
           "return_number": np.concatenate(ret).astype(np.uint8), "classification": np.concatenate(cls).astype(np.uint8)}
    out["number_of_returns"] = nret[pulse].astype(np.uint8)
    out["intensity"] = np.full(len(pulse), 100, np.uint16)
    out["gps_time"] = pulse.astype(np.float64)
    return out


def stand_truth(stand: Stand, *, floor: float = 2.0, layer: float = 1.0, window: int = 3, threshold: float = 0.012,
                extinction: float = 0.5, leaf_mass_area: float = 0.141, step: float = 0.05) -> dict:
    """Per cell (arrays over stand.cells' rows) the answers, computed from the crowns' geometry: ``base`` the crown
    base (0 without trees), ``height`` the crown top, ``cbd`` the largest centred ``window``-layer running mean of
    the layers' bulk density (foliage mass of the crowns' slices over the cell's layer volume; layers under
    ``floor`` left out), ``cbh`` the middle of the lowest layer whose running mean exceeds ``threshold`` (FVS's
    rule on the exact profile; 0 where none does), ``cover`` the expected share (percent) of first returns above ``floor``, integrated over
    the cell on a ``step`` raster (1 - exp(-k LAD path) per position)."""
    c = stand.cells
    ncell = len(c)
    out = {k: np.zeros(ncell) for k in ("cbh", "base", "height", "cbd", "cover")}
    area = stand.cell ** 2
    for j, (col, row, base, top, radius, spacing, rho, shape) in enumerate(c):
        if spacing == 0:
            continue
        ntree = int(stand.cell // spacing) ** 2
        out["base"][j], out["height"][j] = base, top
        layers = int(np.ceil(top / layer)) + window
        profile = np.zeros(layers)
        for i in range(layers):
            lo, hi = max(i * layer, base), min((i + 1) * layer, top)
            if hi <= lo or i * layer < floor - 1e-9:
                continue
            # volume of a crown's slice between lo and hi: the integral of its cross-section, pi (R (top - z) / L)^2
            # for a cone, pi R^2 (1 - ((z - base) / L)^2) for a half-ellipsoid
            length = top - base
            if shape:
                a, b = (lo - base) / length, (hi - base) / length
                vol = np.pi * radius ** 2 * length * ((b - b ** 3 / 3) - (a - a ** 3 / 3))
            else:
                vol = np.pi * radius ** 2 / length ** 2 * ((top - lo) ** 3 - (top - hi) ** 3) / 3
            profile[i] = rho * ntree * vol / (area * layer)
        half = window // 2
        padded = np.concatenate([np.zeros(half), profile, np.zeros(half)])
        means = np.array([padded[i:i + window].mean() for i in range(layers)])
        means[np.arange(layers) * layer < floor - 1e-9] = 0
        out["cbd"][j] = means.max()
        over = np.flatnonzero(means > threshold)
        out["cbh"][j] = (over[0] + 0.5) * layer if len(over) else 0.0
        # cover: one tree's disc, the share of pulses stopped, times the trees' share of the cell
        r = np.arange(step / 2, radius, step)
        u = r / radius
        path = (top - base) * (np.sqrt(1 - u ** 2) if shape else 1 - u)
        p = 1 - np.exp(-extinction * rho / leaf_mass_area * path)
        stopped = np.sum(p * 2 * np.pi * r * step)  # m2 of a tree's disc, ring by ring
        out["cover"][j] = 100 * ntree * stopped / area
    return out


def write_stand(stand: Stand, points: dict, folder, *, tiles=(2, 2), epsg: int = 32610) -> list:
    """The stand's points as ``tiles`` LAS tiles (split at the middle of cells, not on their edges) and as one file
    ``stand.las`` in ``folder``; returns the tiles' paths (``folder/tiles/``)."""
    import pyproj
    from pathlib import Path

    from .io.points import write_tile

    folder = Path(folder)
    crs = pyproj.CRS.from_epsg(epsg)
    write_tile(folder / "stand.las", points, crs, version="1.2", point_format=1, overwrite=True)
    w, s, e, n = stand.bounds
    xs = np.linspace(w, e, tiles[0] + 1)
    ys = np.linspace(s, n, tiles[1] + 1)
    paths = []
    for a in range(tiles[0]):
        for b in range(tiles[1]):
            keep = (points["x"] >= xs[a]) & (points["x"] < xs[a + 1]) & (points["y"] >= ys[b]) & (points["y"] < ys[b + 1])
            part = {k: v[keep] for k, v in points.items()}
            paths.append(write_tile(folder / "tiles" / f"stand_{a}_{b}.las", part, crs, version="1.2", point_format=1,
                                    overwrite=True))
    return paths
