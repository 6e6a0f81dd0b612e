"""The offline web map in a real headless Chromium (Debian's ``chromium``, which the test command installs): each
class colour is drawn where its polygons are, the page asks the network for nothing (Chromium's network log, and a
run with the network blocked draws the same), and the polygons inlined in the page have the GeoPackage's areas."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import shapely

from conftest import SAMPLE
from gistools.errors import InputError, OutputExistsError
from gistools.lidar.shrub import CLASS_STYLE
from gistools.deliver.webmap import web_map

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:  # pragma: no cover - depends on the machine
    if os.environ.get("CI"):
        raise RuntimeError("CI must run the web map tests: the test command installs Debian's chromium")
    pytest.skip("web map tests: chromium is not installed (apt-get install chromium)", allow_module_level=True)

SIZE = (1000, 800)
QUIET = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-default-apps",
         "--disable-features=MediaRouter,OptimizationHints,Translate,NetworkTimeServiceQuerying", "--virtual-time-budget=4000"]
BLOCKED = ["--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND"]


def chromium(*args, home, size=SIZE):
    env = {**os.environ, "HOME": str(home)}
    run = subprocess.run([CHROMIUM, *QUIET, f"--window-size={size[0]},{size[1]}", f"--user-data-dir={home}/profile", *args],
                         capture_output=True,
                         text=True, timeout=120, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    return run


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
