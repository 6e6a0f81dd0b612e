"""The offline web map in a real headless Chromium (Debian's ``chromium``, which the test command installs): each
class colour is drawn where its polygons are, the page asks the network for nothing (Chromium's network log, and a
run with the network blocked draws the same), and the polygons inlined in the page have the GeoPackage's areas."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import rasterio.features
import shapely
from shapely.geometry import box

from conftest import BLOCKED, SAMPLE, SIZE, chromium, need_chromium
from gistools.errors import InputError, OutputExistsError
from gistools.lidar.shrub import CLASS_STYLE
from gistools.deliver.webmap import web_map

need_chromium("web map")


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    from gistools.products.shrub import shrub_from_tiles

    out = tmp_path_factory.mktemp("chain")
    b = SAMPLE / "breaklines.gpkg"
    shrub_from_tiles(SAMPLE, out, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                     waterbodies=f"{b}:WATERBODY", wetlands=f"{b}:WETLAND", tile_index=f"{b}:FOOTPRINT", make_map=False)
    result = web_map(out)
    return out, result


def leaflet_pixels(geojson: dict, size, lonlats, padding: int = 8, snap: float = 0.25) -> list:
    """Where Leaflet 1.9 draws each (lon, lat) once the page has fitted the map to its polygons
    (``map.fitBounds(bounds, {padding: [8, 8]})`` with zoomSnap 0.25, in a map of ``size`` pixels): Leaflet's own
    arithmetic (getBoundsZoom, _getBoundsCenterZoom, the pixel origin) over spherical Mercator, written here from
    its documented steps."""
    r = 6378137.0
    xs, ys = [], []

    def walk(c):
        if isinstance(c[0], (int, float)):
            xs.append(c[0])
            ys.append(c[1])
        else:
            for k in c:
                walk(k)

    for f in geojson["features"]:
        walk(f["geometry"]["coordinates"])

    def project(lon, lat, zoom):
        scale = 256 * 2 ** zoom
        x, y = r * np.radians(lon), r * np.log(np.tan(np.pi / 4 + np.radians(lat) / 2))
        return np.array([scale * (0.5 / (np.pi * r) * x + 0.5), scale * (-0.5 / (np.pi * r) * y + 0.5)])

    west, south, east, north = min(xs), min(ys), max(xs), max(ys)
    inner = np.array(size, float) - 2 * padding
    span = project(east, south, 0) - project(west, north, 0)
    zoom = np.log2(min(inner[0] / span[0], inner[1] / span[1]))
    zoom = round(zoom / (snap / 100)) * (snap / 100)
    zoom = np.floor(zoom / snap) * snap
    centre = (project(west, south, zoom) + project(east, north, zoom)) / 2
    origin = np.round(centre - np.array(size, float) / 2)
    return [tuple(project(lon, lat, zoom) - origin) for lon, lat in lonlats]


def inlined(html: str) -> dict:
    return json.loads(re.search(r"var data = (\{.*?\}), classes = ", html, re.S).group(1).replace("<\\/", "</"))


def test_each_class_is_drawn_in_its_colour_where_its_polygons_are(chain, tmp_path):
    from PIL import Image

    out, result = chain
    gdf = gpd.read_file(out / "shrub_classes.gpkg")
    probes = []
    for code in sorted(set(gdf.class_code)):
        geom = shapely.union_all(list(gdf.geometry[gdf.class_code == code]))
        # a point well inside the class (3 cells from its edges; roads are narrower: 1 cell), in WGS84
        inner = next((g for g in (geom.buffer(-d) for d in (15, 5)) if not g.is_empty), None)
        if inner is None:
            continue
        p = gpd.GeoSeries([inner.representative_point()], crs=gdf.crs).to_crs(4326).iloc[0]
        probes.append((code, p.x, p.y))
    assert {c for c, _, _ in probes} >= {1, 2, 3, 4, 5}
    page = Path(result["html"]).resolve().as_uri()
    data = inlined(Path(result["html"]).read_text())
    pixels = leaflet_pixels(data, SIZE, [(x, y) for _, x, y in probes])
    size = SIZE
    for blocked, name in ((False, "open.png"), (True, "blocked.png")):
        chromium(f"--screenshot={tmp_path / name}", *(BLOCKED if blocked else ()), page, home=tmp_path, size=size)
        img = np.asarray(Image.open(tmp_path / name).convert("RGB")).astype(int)
        assert img.shape[:2] == (size[1], size[0])
        for (code, _, _), (px, py) in zip(probes, pixels):
            colour = np.array([int(CLASS_STYLE[code][1][i:i + 2], 16) for i in (1, 3, 5)])
            want = 0.75 * colour + 0.25 * np.array([0xDD, 0xDD, 0xDD])  # fill opacity 0.75 over Leaflet's grey
            got = img[int(round(py)), int(round(px))]
            assert np.abs(got - want).max() <= 12, (name, code, got, want)


def page_requests(log: Path) -> list[str]:
    """The URLs the page asked for, from Chromium's network log: requests with an initiator (the page's origin;
    the browser's own, such as its component updater, have "not an origin"), other than file: and data: ones."""
    log = json.loads(log.read_text())
    start = log["constants"]["logEventTypes"]["URL_REQUEST_START_JOB"]
    urls = []
    for e in log.get("events", []):
        p = e.get("params") or {}
        if e.get("type") == start and p.get("initiator") != "not an origin" and "url" in p:
            urls.append(p["url"])
    return sorted(u for u in urls if not u.startswith(("file:", "data:", "blob:")))


def test_the_page_makes_no_network_request(chain, tmp_path):
    out, result = chain
    chromium(f"--log-net-log={tmp_path / 'net.json'}", f"--screenshot={tmp_path / 'shot.png'}",
             Path(result["html"]).resolve().as_uri(), home=tmp_path)
    assert page_requests(tmp_path / "net.json") == []
    html = Path(result["html"]).read_text()
    assert "<script src" not in html and "<link" not in html  # Leaflet is inlined, not linked
    # the check sees a page's requests: with a basemap (off by default) the tiles are asked for
    copy = tmp_path / "online"
    shutil.copytree(out, copy)
    online = web_map(copy, basemap="http://127.0.0.1:9/{z}/{x}/{y}.png")
    chromium(f"--log-net-log={tmp_path / 'net2.json'}", f"--screenshot={tmp_path / 'shot2.png'}",
             Path(online["html"]).resolve().as_uri(), home=tmp_path)
    asked = page_requests(tmp_path / "net2.json")
    assert asked and all(u.startswith("http://127.0.0.1:9/") for u in asked)


def test_the_inlined_polygons_have_the_geopackages_areas(chain):
    out, result = chain
    gdf = gpd.read_file(out / "shrub_classes.gpkg")
    data = inlined(Path(result["html"]).read_text())
    assert len(data["features"]) == len(gdf) == result["features"]
    page = gpd.GeoDataFrame.from_features(data["features"], crs=4326).to_crs(gdf.crs)
    for (_, a), (_, b) in zip(gdf.iterrows(), page.iterrows()):
        assert (b["tile"], b["class_code"]) == (str(a["tile"]), a["class_code"])
        assert b["area"] == a["area"] and b["area_acres"] == pytest.approx(a["area_acres"])
        assert b.geometry.area == pytest.approx(a.geometry.area, rel=0.01)  # simplified within half a cell
    assert result["bytes"] < 2e6 and not result["parts"]


def test_a_big_county_is_split_by_tile_and_foreign_pages_are_kept(chain, tmp_path):
    out, _ = chain
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    result = web_map(copy, split_mb=0.02)  # a "county" past 20 kB of polygons
    assert len(result["parts"]) >= 2
    every = []
    for part in result["parts"]:
        every += [f["properties"]["tile"] for f in inlined(Path(part).read_text())["features"]]
    assert sorted(every) == sorted(str(t) for t in gpd.read_file(copy / "shrub_classes.gpkg").tile)
    assert "shrub_map_01.html" in Path(result["html"]).read_text()
    (copy / "shrub_map.html").write_text("<html>my own page</html>")
    with pytest.raises(OutputExistsError):
        web_map(copy)
    assert (copy / "shrub_map.html").read_text() == "<html>my own page</html>"
    with pytest.raises(InputError, match="^basemap 'tiles.invalid'"):  # a Python call names the argument
        web_map(copy, basemap="tiles.invalid")


PAYLOADS = ["<img src=x onerror=\"document.documentElement.dataset.pwned='img'\">",
            "<script>document.documentElement.dataset.pwned='script'</script>",
            "'\"><svg onload=\"document.documentElement.dataset.pwned='svg'\"></svg>",
            "</script><script>document.documentElement.dataset.pwned='close'</script>"]


def injected_folder(out, dest) -> Path:
    """A copy of a chain's folder whose every field that reaches the page carries markup that would run script:
    tile names and class names of the polygons, the title, CRS, units and settings of report.json."""
    shutil.copytree(out, dest)
    gdf = gpd.read_file(dest / "shrub_classes.gpkg")
    gdf["tile"] = [f"{PAYLOADS[i % 4]}{t}.las" for i, t in enumerate(gdf.tile)]
    gdf["class"] = [PAYLOADS[(i + 1) % 4] + str(c) for i, c in enumerate(gdf["class"])]
    (dest / "shrub_classes.gpkg").unlink()
    gdf.to_file(dest / "shrub_classes.gpkg")
    report = json.loads((dest / "report.json").read_text())
    report.update(map_title=PAYLOADS[0] + "title", crs=PAYLOADS[1] + "EPSG", horizontal_unit=PAYLOADS[2],
                  class_method=PAYLOADS[3], settings={**report.get("settings", {}), "bands": PAYLOADS[0]})
    (dest / "report.json").write_text(json.dumps(report))
    return dest


def ran_script(page: Path, tmp_path) -> tuple[bool, str]:
    """Open ``page`` with every popup open (#popups); whether any injected handler or script ran."""
    dom = chromium("--dump-dom", page.resolve().as_uri() + "#popups", home=tmp_path).stdout
    assert "<div class=\"leaflet-popup-content\"" in dom and "<details class=\"gt-box" in dom  # popups, panels drawn
    return re.search(r"<html[^>]*data-pwned", dom) is not None, dom


def test_no_markup_from_the_data_runs_in_the_page(chain, tmp_path):
    from gistools.web.page import content_security_policy

    out, _ = chain
    folder = injected_folder(out, tmp_path / "hostile")
    result = web_map(folder, basemap_attribution=PAYLOADS[2])
    page = Path(result["html"])
    ran, dom = ran_script(page, tmp_path)
    assert not ran
    assert re.search(r"<br>tile (&lt;|'\"&gt;)", dom)  # the tile name is shown, as text
    assert re.search(r"<b>(&lt;|'\"&gt;)", dom)  # the class name too
    assert "&lt;script&gt;document.documentElement.dataset.pwned='script'&lt;/script&gt;EPSG" in dom  # the CRS
    # the same page with the popup built from markup and no policy: the check sees the handler run
    text = page.read_text()
    unsafe = text.replace("return popup(f.properties);", "var d = document.createElement('div'); d.innerHTML = "
                          "'<b>' + f.properties['class'] + '</b> tile ' + f.properties.tile; return d;")
    assert unsafe != text
    control = tmp_path / "control.html"
    control.write_text(re.sub(r"<meta http-equiv='Content-Security-Policy'[^\n]*\n", "", unsafe))
    assert ran_script(control, tmp_path)[0]
    # and the policy alone, with that unsafe popup, still stops it (defence in depth)
    scripts = re.findall(r"<script>(.*?)</script>", unsafe, re.S)
    policy = content_security_policy(scripts)
    guarded = tmp_path / "guarded.html"
    guarded.write_text(re.sub(r"content=\"[^\"]*\"", lambda m: f'content="{policy}"', unsafe, count=1))
    assert not ran_script(guarded, tmp_path)[0]


# search and rescue and fire layers: gistools travel, viewshed and fuels folders drawn on the page

START = (430500.0, 1811500.0)  # the point last seen, on land in tile 35712 (US survey feet, EPSG:2882)
SAFE = (230, 60, 680, 740)  # page pixels clear of the controls (layer switcher, legends, readout, panel)


@pytest.fixture(scope="module")
def sar(chain, tmp_path_factory):
    """The chain's travel time from a point last seen (isochrones 2, 4, 6 min), its viewshed from there and the
    fuels of the same tiles."""
    from gistools.products.fuels import fuels_from_tiles
    from gistools.products.travel import TravelSettings, travel_from_dem
    from gistools.products.viewshed import viewshed_from_surface

    out, _ = chain
    root = tmp_path_factory.mktemp("sar")
    b = SAMPLE / "breaklines.gpkg"
    travel_from_dem(out, root / "travel", [f"{START[0]},{START[1]}"], TravelSettings(isochrones=(2, 4, 6)),
                    roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE", waterbodies=f"{b}:WATERBODY")
    viewshed_from_surface(out / "dsm.vrt", root / "viewshed", observers=[f"{START[0]},{START[1]}"],
                          observer_height="6ft")
    fuels_from_tiles(SAMPLE, root / "fuels")
    return root


def shot(folder, tmp_path, name, **layers) -> tuple[np.ndarray, dict, Path]:
    """A copy of the chain folder's web map with ``layers``, its screenshot and its inlined polygons."""
    from PIL import Image

    result = web_map(folder, **layers)
    page = Path(result["html"])
    chromium(f"--screenshot={tmp_path / name}", page.resolve().as_uri(), home=tmp_path)
    return np.asarray(Image.open(tmp_path / name).convert("RGB")).astype(int), inlined(page.read_text()), page


def probes_in(region, crs, data, count=6, step=4.0) -> list:
    """Up to ``count`` points of ``region`` (a shapely geometry in ``crs``) drawn on the page within SAFE, as
    (x, y in crs, pixel)."""
    if region.is_empty:
        return []
    w, s, e, n = region.bounds
    xs, ys = np.meshgrid(np.arange(w, e, step), np.arange(s, n, step))
    xs, ys = xs.ravel(), ys.ravel()
    keep = shapely.contains_xy(region, xs, ys)
    xs, ys = xs[keep], ys[keep]
    if not len(xs):
        return []
    lonlat = gpd.GeoSeries(gpd.points_from_xy(xs, ys), crs=crs).to_crs(4326)
    pixels = leaflet_pixels(data, SIZE, [(p.x, p.y) for p in lonlat])
    ok = [i for i, (px, py) in enumerate(pixels) if SAFE[0] <= px <= SAFE[2] and SAFE[1] <= py <= SAFE[3]]
    pick = [ok[int(k)] for k in np.linspace(0, len(ok) - 1, min(count, len(ok)))] if ok else []
    return [(xs[i], ys[i], pixels[i]) for i in pick]


def rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])


def test_the_isochrones_are_drawn_in_their_colours_over_the_map(chain, sar, tmp_path):
    """Each isochrone band (0-2, 2-4, 4-6 min), well inside its polygon, is its colour at 35 % over what the map
    without the travel layers shows there (the same fit: the page fits the shrub polygons)."""
    from gistools.deliver.layers import travel_frames

    out, _ = chain
    under, data, _ = shot(out, tmp_path, "under.png")
    copy = tmp_path / "with_travel"
    shutil.copytree(out, copy)
    img, data2, page = shot(copy, tmp_path, "travel.png", travel=sar / "travel")
    assert data2 == data  # the same polygons, the same fit
    bands, seen = travel_frames(sar / "travel")
    with rasterio.open(sar / "travel" / "travel_minutes.tif") as src:
        cell = src.res[0]
    shrub = gpd.read_file(out / "shrub_classes.gpkg")
    edges = shapely.union_all([g.boundary for g in shrub.geometry]).buffer(3 * cell)
    spot = shapely.union_all(list(seen.geometry)).buffer(40.0)
    assert list(bands["name"]) == ["0-2 min", "2-4 min", "4-6 min"]
    drawn = 0
    for geom, colour in zip(bands.geometry, bands["colour"]):
        inner = geom.buffer(-3 * cell).difference(edges).difference(spot)
        probes = probes_in(inner, bands.crs, data)
        assert probes, colour
        for _, _, (px, py) in probes:
            r, c = int(round(py)), int(round(px))
            want = 0.35 * rgb(colour) + 0.65 * under[r, c]
            assert np.abs(img[r, c] - want).max() <= 12, (colour, img[r, c], want)
            drawn += 1
    assert drawn >= 12
    # and outside every isochrone (beyond 6 min, or not reached) the map is unchanged
    outside = box(*shrub.total_bounds).buffer(-3 * cell).difference(shapely.union_all(list(bands.geometry)).buffer(
        3 * cell)).difference(edges)
    for _, _, (px, py) in probes_in(outside, bands.crs, data):
        r, c = int(round(py)), int(round(px))
        assert np.abs(img[r, c] - under[r, c]).max() <= 3
    # the point last seen is a magenta dot
    p = gpd.GeoSeries(list(seen.geometry), crs=seen.crs).to_crs(4326).iloc[0]
    px, py = leaflet_pixels(data, SIZE, [(p.x, p.y)])[0]
    assert np.abs(img[int(round(py)), int(round(px))] - rgb("#ff00ff")).max() <= 12
    legend = chromium("--dump-dom", page.resolve().as_uri(), home=tmp_path).stdout
    for name in ("0-2 min", "2-4 min", "4-6 min", "point last seen", "Isochrones", "Points last seen"):
        assert name in legend


def readout(page: Path, lon: float, lat: float, tmp_path) -> str:
    dom = chromium("--dump-dom", f"{page.resolve().as_uri()}#cursor={lon:.7f},{lat:.7f}", home=tmp_path).stdout
    return re.search(r'id="gt-travel">([^<]*)<', dom).group(1)


def test_the_travel_time_under_the_cursor_is_the_rasters(chain, sar, tmp_path):
    """The mouse moved over a point: the readout shows the minutes of travel_minutes.tif there (rasterio) within
    the cells around it (the page's grid is warped to Web Mercator); over water, "not reached"."""
    out, _ = chain
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    page = Path(web_map(copy, travel=sar / "travel")["html"])
    points = [(START[0] + 150, START[1] - 90), (START[0] - 230, START[1] + 310), (START[0] + 700, START[1] - 600)]
    with rasterio.open(sar / "travel" / "travel_minutes.tif") as src:
        t = src.read(1, masked=True).filled(np.nan)
        shown = 0
        for x, y in points:
            r, c = src.index(x, y)
            around = t[r - 1:r + 2, c - 1:c + 2]
            assert np.isfinite(around).all()
            p = gpd.GeoSeries(gpd.points_from_xy([x], [y]), crs=src.crs.to_wkt()).to_crs(4326).iloc[0]
            text = readout(page, p.x, p.y, tmp_path)
            minutes = float(re.fullmatch(r"travel time: ([0-9.]+) min", text).group(1))
            assert np.nanmin(around) - 0.05 <= minutes <= np.nanmax(around) + 0.05, (x, y, text, around)
            assert minutes > 0.5
            shown += 1
        assert shown == 3
        # the middle of the water body: no path reaches it
        water = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="WATERBODY").to_crs(src.crs.to_wkt())
        lake = max(water.geometry, key=lambda g: g.area)
        inner = lake.buffer(-15.0)
        x, y = inner.representative_point().x, inner.representative_point().y
        r, c = src.index(x, y)
        assert np.isnan(t[r - 1:r + 2, c - 1:c + 2]).all()
    p = gpd.GeoSeries(gpd.points_from_xy([x], [y]), crs=src.crs.to_wkt()).to_crs(4326).iloc[0]
    assert readout(page, p.x, p.y, tmp_path) == "travel time: not reached"


def test_the_viewshed_and_the_canopy_base_height_are_drawn(chain, sar, tmp_path):
    """The cells seen (viewshed.tif == 1, read by rasterio) are cyan at 110/255 over the map; the canopy base height
    cells (cbh.vrt, classed here at 4 and 8 m) are their class colour at 60 %."""
    out, _ = chain
    under, data, _ = shot(out, tmp_path, "under.png")
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    img, _, page = shot(copy, tmp_path, "viewshed.png", viewshed=sar / "viewshed")
    html = page.read_text()
    assert html.count("data:image/png;base64,") == 1
    with rasterio.open(sar / "viewshed" / "viewshed.tif") as src:
        seen = src.read(1)
        crs = src.crs.to_wkt()
        solid = scipy_ndimage_erosion(seen == 1, 4)
        hidden = scipy_ndimage_erosion(seen == 0, 4)
        regions = [shapely.union_all([shapely.geometry.shape(g) for g, v in rasterio.features.shapes(
            m.astype(np.uint8), mask=m, transform=src.transform)]) for m in (solid, hidden)]
    shrub = gpd.read_file(out / "shrub_classes.gpkg")
    edges = shapely.union_all([g.boundary for g in shrub.geometry]).buffer(15.0)
    alpha = 110 / 255
    for region, expect_seen in zip(regions, (True, False)):
        probes = probes_in(region.difference(edges), crs, data)
        assert probes
        for _, _, (px, py) in probes:
            r, c = int(round(py)), int(round(px))
            want = alpha * np.array([0, 229, 255]) + (1 - alpha) * under[r, c] if expect_seen else under[r, c]
            assert np.abs(img[r, c] - want).max() <= 12, (expect_seen, img[r, c], want)
    # the canopy base height classes
    copy2 = tmp_path / "copy2"
    shutil.copytree(out, copy2)
    img, _, page = shot(copy2, tmp_path, "fuels.png", fuels=sar / "fuels")
    colours = {1: "#d7301f", 2: "#fdae61", 3: "#1a9641"}
    with rasterio.open(sar / "fuels" / "cbh.vrt") as src:
        cbh_m = src.read(1, masked=True).filled(0) * 1200 / 3937
        classes = np.where(cbh_m > 0, 1 + (cbh_m >= 4) + (cbh_m >= 8), 0)
        checked = 0
        for code, colour in colours.items():
            for r, c in zip(*np.nonzero(classes == code)):
                x, y = src.xy(r, c)
                cell = box(x - 20, y - 20, x + 20, y + 20).difference(edges)  # the middle of the 100 ft cell
                for _, _, (px, py) in probes_in(cell, src.crs.to_wkt(), data, count=1):
                    rr, cc = int(round(py)), int(round(px))
                    want = 0.6 * rgb(colour) + 0.4 * under[rr, cc]
                    assert np.abs(img[rr, cc] - want).max() <= 12, (code, img[rr, cc], want)
                    checked += 1
    assert checked >= 5


def scipy_ndimage_erosion(mask: np.ndarray, cells: int) -> np.ndarray:
    from scipy import ndimage

    return ndimage.binary_erosion(mask, iterations=cells)


def test_bad_layer_folders_are_refused_before_anything_is_written(chain, sar, tmp_path):
    out, _ = chain
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "shrub_map.html").unlink()
    for kw, words in ((dict(travel=tmp_path / "none"), "^travel=.*no such folder"),
                      (dict(viewshed=sar / "travel"), "^viewshed=.*no viewshed.tif"),
                      (dict(fuels=sar / "viewshed"), "^fuels=.*no cbh.vrt")):
        with pytest.raises(InputError, match=words):
            web_map(copy, **kw)
    assert not (copy / "shrub_map.html").exists()


def test_no_markup_of_the_points_last_seen_runs(chain, sar, tmp_path):
    out, _ = chain
    travel = tmp_path / "travel"
    shutil.copytree(sar / "travel", travel)
    seen = gpd.read_file(travel / "travel.gpkg", layer="last_seen")
    seen["source"] = PAYLOADS[0]
    seen.to_file(travel / "travel.gpkg", layer="last_seen", driver="GPKG")
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    page = Path(web_map(copy, travel=travel)["html"])
    ran, dom = ran_script(page, tmp_path)
    assert not ran
    assert "<b>Last seen</b><br>&lt;img src=x onerror=" in dom  # the last popup opened: shown as text


@pytest.fixture(scope="module")
def plan(chain, tmp_path_factory):
    """The chain's search plan for a child of 1-3 years last seen at START, staged at the road bridge."""
    from gistools.products.search_plan import SearchSettings, search_plan

    out, _ = chain
    root = tmp_path_factory.mktemp("plan") / "plan"
    search_plan(out, root, f"{START[0]},{START[1]}", "child_1_3", SearchSettings(segment_size="10ac"),
                staging="431200,1810600")
    return root


def test_the_search_segments_and_routes_are_on_the_page_with_their_figures(chain, plan, tmp_path):
    """Every segment of segments.gpkg is on the page with its rank, POA and POD under the cursor (every tooltip
    opened: #popups), the routes and the litter carry with their minutes."""
    out, _ = chain
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    page = Path(web_map(copy, plan=plan)["html"])
    seg = gpd.read_file(plan / "segments.gpkg", layer="segments")
    routes = gpd.read_file(plan / "routes.gpkg", layer="routes")
    litter = gpd.read_file(plan / "routes.gpkg", layer="litter")
    dom = chromium("--dump-dom", page.resolve().as_uri() + "#popups", home=tmp_path).stdout
    for _, r in seg.iterrows():
        assert f"Segment {r['segment']} (rank {r['rank']})" in dom
    top = seg.sort_values("rank").iloc[0]
    assert f"POA {100 * top['poa']:.2f} %" in dom.replace("\u00a0", " ")
    assert dom.count("Route to segment") == len(routes) and len(routes) > 0
    assert f"Litter carry to {litter['target'].iloc[0]}" in dom
    assert "Search segments" in dom and "Routes" in dom


def test_no_markup_of_a_search_plan_runs(chain, plan, tmp_path):
    out, _ = chain
    hostile = tmp_path / "plan"
    shutil.copytree(plan, hostile)
    routes = gpd.read_file(hostile / "routes.gpkg", layer="routes")
    litter = gpd.read_file(hostile / "routes.gpkg", layer="litter")
    routes["target"] = PAYLOADS[0]
    routes.to_file(hostile / "routes.gpkg", layer="routes", driver="GPKG")
    litter.to_file(hostile / "routes.gpkg", layer="litter", driver="GPKG")
    seg = gpd.read_file(hostile / "segments.gpkg", layer="segments")
    seg["vegetation"] = PAYLOADS[1]
    seg.to_file(hostile / "segments.gpkg", layer="segments", driver="GPKG")
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    page = Path(web_map(copy, plan=hostile)["html"])
    ran, dom = ran_script(page, tmp_path)
    assert not ran
    assert "Route to segment &lt;img src=x onerror=" in dom  # shown as text
