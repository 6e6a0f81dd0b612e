"""Point clouds read by area from a service: real EPT and COPC datasets (PDAL's test data, not gistools' own output:
tests/data/pdal) served by nginx on loopback, which answers byte ranges as object storage does. The points read from
the URL equal, as a set of (x, y, z, class, return), the dataset's own files read with laspy and cut to the area by
numpy; only the nodes that meet the area are fetched (nginx's access log counts the bytes)."""

from __future__ import annotations

import shutil
import socket
import subprocess
import time
from pathlib import Path

import laspy
import numpy as np
import pytest

from conftest import ROOT

DATA = ROOT / "tests" / "data" / "pdal"
NGINX = shutil.which("nginx") or "/usr/sbin/nginx"
BOX = (515375.0, 4918350.0, 515395.5, 4918371.3)  # across the octree's nodes (the cube is 515363-515407)
TRIANGLE = ((515366.13, 4918341.77), (515404.31, 4918352.29), (515381.97, 4918380.61))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """nginx serving a copy of the datasets on loopback: (base URL, its access log)."""
    import os

    if not Path(NGINX).exists():
        if os.environ.get("CI"):
            pytest.fail("nginx is missing: the test command installs Debian's nginx-light")
        pytest.skip("nginx is absent (apt-get install nginx-light)")
    work = tmp_path_factory.mktemp("nginx")
    root = work / "www"
    shutil.copytree(DATA, root)
    port = _free_port()
    conf = work / "nginx.conf"
    temp = "".join(f"  {kind}_temp_path {work}/{kind};\n" for kind in ("client_body", "proxy", "fastcgi", "uwsgi",
                                                                          "scgi"))
    user = "user root;\n" if hasattr(os, "geteuid") and os.geteuid() == 0 else ""  # the workers read pytest's tmp
    conf.write_text(f"""daemon off;
{user}worker_processes 1;
pid {work}/nginx.pid;
error_log {work}/error.log;
events {{ worker_connections 64; }}
http {{
  log_format bytes '$request_uri $status $body_bytes_sent $http_range';
  access_log {work}/access.log bytes;
{temp}  types {{ application/json json; application/octet-stream laz; }}
  server {{
    listen 127.0.0.1:{port};
    root {root};
  }}
}}
""", encoding="utf-8")
    proc = subprocess.Popen([NGINX, "-c", str(conf), "-p", str(work)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    for _ in range(100):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.1).close()
            break
        except OSError:
            time.sleep(0.05)
    else:
        proc.kill()
        pytest.fail(f"nginx did not start: {proc.stderr.read().decode()[-2000:]}")
    yield f"http://127.0.0.1:{port}", work / "access.log"
    proc.terminate()
    proc.wait(timeout=10)


def _served_bytes(log: Path, since: int) -> int:
    lines = log.read_text(encoding="utf-8").splitlines()[since:]
    return sum(int(line.split()[2]) for line in lines)


def _log_lines(log: Path) -> int:
    return len(log.read_text(encoding="utf-8").splitlines()) if log.exists() else 0


def _rows(points: dict) -> set:
    return set(zip(np.round(points["x"], 5), np.round(points["y"], 5), np.round(points["z"], 5),
                   points["classification"].tolist(), points["return_number"].tolist()))


def _reference(files, inside) -> set:
    """The points of the dataset's own files (laspy) that ``inside(x, y)`` keeps (numpy)."""
    rows = set()
    for f in files:
        las = laspy.read(f)
        x, y = np.asarray(las.x), np.asarray(las.y)
        keep = inside(x, y)
        rows |= _rows({"x": x[keep], "y": y[keep], "z": np.asarray(las.z)[keep],
                       "classification": np.asarray(las.classification)[keep],
                       "return_number": np.asarray(las.return_number)[keep]})
    return rows


def _in_box(x, y):
    return (x >= BOX[0]) & (x <= BOX[2]) & (y >= BOX[1]) & (y <= BOX[3])


def _in_triangle(x, y):
    """Inside the triangle by the signs of three cross products (numpy; no point of the data lies on an edge)."""
    (ax, ay), (bx, by), (cx, cy) = TRIANGLE
    d1 = (x - bx) * (ay - by) - (ax - bx) * (y - by)
    d2 = (x - cx) * (by - cy) - (bx - cx) * (y - cy)
    d3 = (x - ax) * (cy - ay) - (cx - ax) * (y - ay)
    return ~(((d1 < 0) | (d2 < 0) | (d3 < 0)) & ((d1 > 0) | (d2 > 0) | (d3 > 0)))


EPT_FILES = sorted((DATA / "lone-star-laszip" / "ept-data").glob("*.laz"))
COPC_FILE = DATA / "lone-star.copc.laz"


@pytest.mark.parametrize("kind", ["ept", "copc"])
@pytest.mark.parametrize("area", ["box", "polygon"])
def test_the_points_of_an_area_read_from_a_url_are_the_datasets_own(server, kind, area):
    import shapely

    from gistools.io.area import open_source
    from gistools.io.http import RangeClient

    base, _log = server
    url = f"{base}/lone-star-laszip/ept.json" if kind == "ept" else f"{base}/lone-star.copc.laz"
    aoi = BOX if area == "box" else shapely.Polygon(TRIANGLE)
    client = RangeClient()
    points = open_source(url, client).read(aoi)
    expected = _reference(EPT_FILES if kind == "ept" else [COPC_FILE], _in_box if area == "box" else _in_triangle)
    assert len(points["x"]) == len(expected) > 10_000
    assert _rows(points) == expected
    local = open_source(DATA / "lone-star-laszip" if kind == "ept" else COPC_FILE).read(aoi)  # the same, from disk
    assert _rows(local) == expected


def test_only_the_nodes_that_meet_the_area_are_fetched(server):
    """COPC: the bytes nginx sends for an area are at most 1.2 x the sum of the nodes that meet it (the hierarchy
    says their sizes), well under the file; EPT: only the node files of the area are asked for."""
    from gistools.io.area import open_source
    from gistools.io.http import RangeClient

    base, log = server
    small = (515368.0, 4918341.0, 515370.0, 4918343.0)  # a corner: the root and one deep node
    before = _log_lines(log)
    source = open_source(f"{base}/lone-star.copc.laz", RangeClient())
    plan = source.plan(small)
    source.read(small)
    sent = _served_bytes(log, before)
    assert plan.bytes and sent <= 1.2 * plan.bytes + 200_000, (sent, plan)  # + the header and hierarchy pages
    assert sent < 0.5 * COPC_FILE.stat().st_size
    before = _log_lines(log)
    ept = open_source(f"{base}/lone-star-laszip/ept.json", RangeClient())
    wanted = {"-".join(map(str, key)) for key, _count in ept.nodes(small)}
    ept.read(small)
    asked = [line.split()[0] for line in log.read_text(encoding="utf-8").splitlines()[before:]]
    data = {Path(uri).stem for uri in asked if "/ept-data/" in uri}
    assert data == wanted and len(data) < len(EPT_FILES)


def test_a_resolution_reads_the_coarse_depths_only(server):
    from gistools.io.area import open_source

    base, _log = server
    ept = open_source(f"{base}/lone-star-laszip/ept.json")
    spacing = (515407.0 - 515363.0) / 128  # the cube's width / span: the root's point spacing
    assert {key[0] for key, _ in ept.nodes(BOX, resolution=spacing)} == {0}
    assert {key[0] for key, _ in ept.nodes(BOX, resolution=spacing / 2)} == {0, 1}
    full = len(ept.read(BOX)["x"])
    assert 0 < len(ept.read(BOX, resolution=spacing)["x"]) < full


def test_a_wrong_service_is_one_line_naming_the_url(server, tmp_path):
    from gistools.errors import DataFileError
    from gistools.io.area import open_source
    from gistools.io.http import RangeClient

    base, _log = server
    client = RangeClient(retries=0)
    with pytest.raises(DataFileError, match=r"ept.json: not found \(HTTP 404\)") as err:
        open_source(f"{base}/no-such-dataset/ept.json", client)
    assert "\n" not in str(err.value) and base in str(err.value)
    with pytest.raises(DataFileError, match="is not a JSON object"):
        open_source(f"{base}/lone-star-laszip/ept-sources/list.json", client)
    with pytest.raises(DataFileError, match="not EPT metadata"):
        open_source(f"{base}/lone-star-laszip/ept-build.json", client)
    with pytest.raises(DataFileError, match="not a COPC file"):
        open_source(f"{base}/lone-star-laszip/ept-data/0-0-0-0.laz", client)


def _forward(handler, base: str) -> bytes:
    """A proxy's request passed to nginx (its Range kept), the answer's status and headers sent back: its body."""
    import urllib.error
    import urllib.request

    request = urllib.request.Request(base + handler.path, headers={k: v for k, v in handler.headers.items()
                                                                   if k.lower() == "range"})
    try:
        with urllib.request.urlopen(request) as answer:
            status, headers, body = answer.status, answer.headers, answer.read()
    except urllib.error.HTTPError as err:
        status, headers, body = err.code, err.headers, err.read()
    handler.send_response(status)
    for name in ("Content-Range", "Content-Type"):
        if headers.get(name):
            handler.send_header(name, headers[name])
    handler.send_header("Content-Length", str(len(body)))
    handler.end_headers()
    return body


@pytest.fixture()
def faulty(server):
    """A proxy in front of nginx that spoils requests in turn: a 503, a body cut short, a connection reset without
    an answer, a slow body, then one passed through, and again (20 % 503s, 20 % short bodies, 20 % resets)."""
    import http.server
    import itertools
    import threading
    import urllib.request

    base, _log = server
    turn = itertools.count()

    class Proxy(http.server.BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, *args):
            pass

        def do_GET(self):  # noqa: N802 - http.server's name
            fault = next(turn) % 5
            if fault == 0:
                self.send_response(503)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            if fault == 2:  # a reset: the connection closed before any answer
                self.close_connection = True
                self.connection.close()
                return
            body = _forward(self, base)
            if fault == 1 and len(body) > 10:  # cut short: half the body, then the connection closed
                self.wfile.write(body[: len(body) // 2])
                self.close_connection = True
                return
            if fault == 3:  # slow: the body in pieces
                for k in range(0, len(body), max(1, len(body) // 4)):
                    self.wfile.write(body[k:k + max(1, len(body) // 4)])
                    time.sleep(0.01)
                return
            self.wfile.write(body)

    proxy = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Proxy)
    thread = threading.Thread(target=proxy.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{proxy.server_address[1]}"
    proxy.shutdown()
    proxy.server_close()


@pytest.mark.parametrize("kind", ["ept", "copc"])
def test_a_faulty_service_gives_the_same_points(faulty, kind):
    """Through 503s, short bodies, resets and slow bodies the client retries (never taking a short body for data)
    and reads the same points as from the dataset's own files."""
    from gistools.io.area import open_source
    from gistools.io.http import RangeClient

    url = f"{faulty}/lone-star-laszip/ept.json" if kind == "ept" else f"{faulty}/lone-star.copc.laz"
    client = RangeClient(backoff=0.01, timeout=5)
    points = open_source(url, client).read(BOX)
    assert _rows(points) == _reference(EPT_FILES if kind == "ept" else [COPC_FILE], _in_box)
    assert client.retried > 0


def test_a_service_that_keeps_failing_is_one_line(faulty):
    from gistools.errors import DataFileError
    from gistools.io.http import RangeClient

    client = RangeClient(retries=0, backoff=0.01, timeout=5)
    with pytest.raises(DataFileError, match=r"no complete answer after 1 tries \(HTTP 503\)") as err:
        for _ in range(5):  # the proxy's first answer of five is a 503
            client.get(f"{faulty}/lone-star-laszip/ept.json")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["ept", "copc"])
def test_an_area_fetched_into_tiles_once(server, tmp_path, kind):
    """fetch_area: the area's points as LAZ tiles on a 10 m lattice, equal (as a set of points) to the dataset's own
    files cut to the area; each node fetched once (COPC: at most 1.2 x the nodes' bytes, nginx's count); a rerun
    fetches nothing and keeps every tile as it was; the same tiles from the local copy."""
    from gistools.io.http import RangeClient
    from gistools.products.fetch import fetch_area

    base, log = server
    url = f"{base}/lone-star-laszip/ept.json" if kind == "ept" else f"{base}/lone-star.copc.laz"
    before = _log_lines(log)
    report = fetch_area(url, tmp_path / "url", aoi=BOX, tile_size=10.0, client=RangeClient())
    sent = _served_bytes(log, before)
    rows = set()
    for tile in report["outputs"]["tiles"]:
        las = laspy.read(tile)
        x0, y0 = (float(v) for v in Path(tile).stem.split("_"))
        assert np.all((las.x >= x0) & (las.x < x0 + 10) & (las.y >= y0) & (las.y < y0 + 10))
        rows |= _rows({"x": np.asarray(las.x), "y": np.asarray(las.y), "z": np.asarray(las.z),
                       "classification": np.asarray(las.classification),
                       "return_number": np.asarray(las.return_number)})
    assert rows == _reference(EPT_FILES if kind == "ept" else [COPC_FILE], _in_box)
    cells = {(int(np.floor(x / 10)) * 10, int(np.floor(y / 10)) * 10) for x, y, *_ in rows}
    assert report["points"] == len(rows)
    assert sorted(Path(t).name for t in report["outputs"]["tiles"]) == sorted(f"{x}_{y}.laz" for x, y in cells)
    if kind == "copc":
        assert sent <= 1.2 * report["estimate"]["bytes"] + 200_000, (sent, report["estimate"])
    stamps = {t: Path(t).stat().st_mtime_ns for t in report["outputs"]["tiles"]}
    before = _log_lines(log)
    again = fetch_area(url, tmp_path / "url", aoi=BOX, tile_size=10.0, client=RangeClient())
    assert _log_lines(log) == before and again["kept"]  # nothing asked of the server
    assert {t: Path(t).stat().st_mtime_ns for t in report["outputs"]["tiles"]} == stamps
    local = fetch_area(DATA / "lone-star-laszip" if kind == "ept" else COPC_FILE, tmp_path / "local", aoi=BOX,
                       tile_size=10.0)
    assert sorted(Path(t).name for t in local["outputs"]["tiles"]) == sorted(Path(t).name for t in report["outputs"]["tiles"])
    for name in (Path(t).name for t in local["outputs"]["tiles"]):
        a, b = laspy.read(tmp_path / "local" / name), laspy.read(tmp_path / "url" / name)
        assert np.array_equal(a.x, b.x) and np.array_equal(a.classification, b.classification)


def test_an_area_larger_than_allowed_is_refused_before_any_point(server, tmp_path):
    from gistools.errors import InputError
    from gistools.products.fetch import fetch_area

    base, _log = server
    with pytest.raises(InputError, match=r"more than the 1\.0 MB allowed"):
        fetch_area(f"{base}/lone-star.copc.laz", tmp_path / "big", aoi=BOX, tile_size=10.0, max_download=1e6)
    assert not list((tmp_path / "big").glob("*.laz")) if (tmp_path / "big").exists() else True


# --- commands on an area of a service, and on a local copy of it ----------------------------------------------------
AOI = ",".join(repr(v) for v in BOX)
AREA_OPTIONS = ["--aoi", AOI, "--tile-size", "10m", "--classify-ground", "smrf", "--quiet"]


def _gistools(*args, check=True):
    """``gistools`` as a user runs it (the venv's console script beside this Python)."""
    import sys

    exe = Path(sys.executable).with_name("gistools")
    done = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=900)
    if check:
        assert done.returncode == 0, done.stderr[-3000:]
    return done


def _same_rasters(a: Path, b: Path, folders) -> int:
    """Every GeoTIFF of ``folders`` in ``a`` equals its namesake in ``b``, cell for cell (grid, nodata, values);
    the number compared."""
    import rasterio

    compared = 0
    for folder in folders:
        names = sorted(p.name for p in (a / folder).glob("*.tif"))
        assert names and names == sorted(p.name for p in (b / folder).glob("*.tif")), folder
        for name in names:
            with rasterio.open(a / folder / name) as x, rasterio.open(b / folder / name) as y:
                assert x.transform == y.transform and x.shape == y.shape and x.nodata == y.nodata, name
                np.testing.assert_array_equal(x.read(), y.read(), err_msg=f"{folder}/{name}")
            compared += 1
    return compared


@pytest.mark.parametrize("kind", ["ept", "copc"])
def test_rasters_of_a_service_equal_those_of_its_local_copy(server, tmp_path, kind):
    """gistools rasters URL --aoi ... equals gistools rasters LOCAL_COPY --aoi ... cell for cell, on 10 m tiles of
    the area (ground classified first: the dataset has none); a rerun asks nothing of the server."""
    base, log = server
    url = f"{base}/lone-star-laszip/ept.json" if kind == "ept" else f"{base}/lone-star.copc.laz"
    local = DATA / "lone-star-laszip" / "ept.json" if kind == "ept" else COPC_FILE
    _gistools("rasters", url, *AREA_OPTIONS, "--cell-size", "1m", "--out", tmp_path / "a")
    _gistools("rasters", local, *AREA_OPTIONS, "--cell-size", "1m", "--out", tmp_path / "b")
    assert _same_rasters(tmp_path / "a", tmp_path / "b", ("dsm", "dem", "ndsm")) >= 3 * 6
    before = _log_lines(log)
    again = _gistools("rasters", url, *AREA_OPTIONS, "--cell-size", "1m", "--out", tmp_path / "a")
    assert _log_lines(log) == before, "a rerun fetched again"
    assert "6 skipped" in again.stdout or "skipped (outputs exist)" in again.stdout


def test_the_shrub_chain_of_a_service_equals_its_local_copy(server, tmp_path):
    base, log = server
    _gistools("shrub", f"{base}/lone-star.copc.laz", *AREA_OPTIONS, "--no-map", "--out", tmp_path / "a")
    _gistools("shrub", COPC_FILE, *AREA_OPTIONS, "--no-map", "--out", tmp_path / "b")
    assert _same_rasters(tmp_path / "a", tmp_path / "b", ("dem", "ndsm", "bands", "density", "classes")) >= 5 * 6


def test_a_service_needs_an_area_and_an_area_is_checked_first(server, tmp_path):
    base, _log = server
    done = _gistools("rasters", f"{base}/lone-star.copc.laz", "--out", tmp_path / "o", check=False)
    assert done.returncode == 2 and "give --aoi" in done.stderr and "Traceback" not in done.stderr
    done = _gistools("rasters", COPC_FILE, "--aoi", AOI, "--max-download", "lots", "--out", tmp_path / "o",
                     check=False)
    assert done.returncode != 0 and "is not a size" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists()
    done = _gistools("rasters", COPC_FILE, "--aoi", AOI, "--cell-size", "-1", "--out", tmp_path / "o", check=False)
    assert done.returncode != 0 and not (tmp_path / "o" / "fetched").exists()  # no point fetched for a bad option


def test_an_area_given_in_another_crs_or_as_a_polygon_layer(server, tmp_path):
    """A box in EPSG:4326 is reprojected to the data's CRS; a polygon layer (GeoPackage) reads its points only."""
    import geopandas as gpd
    import pyproj
    import shapely

    from gistools.products.fetch import Area

    crs = pyproj.CRS.from_user_input(laspy.open(COPC_FILE).header.parse_crs())
    polygon = shapely.Polygon(TRIANGLE)
    gpd.GeoDataFrame(geometry=[polygon], crs=crs).to_file(tmp_path / "area.gpkg", layer="search")
    tiles = Area(str(COPC_FILE), f"{tmp_path / 'area.gpkg'}|layername=search", tmp_path / "cache", tile_size=10.0,
                 margin=0).local_tiles()
    rows = set()
    for tile in tiles:
        las = laspy.read(tile)
        rows |= _rows({"x": np.asarray(las.x), "y": np.asarray(las.y), "z": np.asarray(las.z),
                       "classification": np.asarray(las.classification), "return_number": np.asarray(las.return_number)})
    assert rows == _reference([COPC_FILE], _in_triangle)
    # a box in longitude / latitude over the sample block (its CRS is a state plane in feet): every point inside
    # it (each point reprojected by pyproj) is read, and few more (the box reprojected is not a rectangle there)
    sample = sorted((ROOT / "sample_tiles").glob("*.la?"))
    tiles_crs = laspy.open(sample[0]).header.parse_crs()
    box = (-82.7085, 29.3115, -82.7055, 29.3145)
    geo = Area([str(p) for p in sample], ",".join(map(repr, box)) + ",EPSG:4326", tmp_path / "cache2", margin=0)
    got = set()
    for tile in geo.local_tiles():
        las = laspy.read(tile)
        got |= set(zip(np.round(las.x, 2), np.round(las.y, 2), np.round(las.z, 2)))
    to_geo = pyproj.Transformer.from_crs(tiles_crs, "EPSG:4326", always_xy=True)
    inside = set()
    for f in sample:
        las = laspy.read(f)
        lon, lat = to_geo.transform(np.asarray(las.x), np.asarray(las.y))
        keep = (lon >= box[0]) & (lon <= box[2]) & (lat >= box[1]) & (lat <= box[3])
        inside |= set(zip(np.round(las.x[keep], 2), np.round(las.y[keep], 2), np.round(las.z[keep], 2)))
    assert len(inside) > 1000 and inside <= got and len(got) <= 1.05 * len(inside)


def test_a_server_stopped_mid_run_then_started_again(server, tmp_path):
    """The service goes away after a few requests: the run stops with one line naming the URL, no tile of the area
    is taken for complete; once the service is back, the rerun completes to the rasters of a clean run."""
    import http.server
    import threading
    import urllib.request

    from gistools.errors import DataFileError
    from gistools.io.http import RangeClient
    from gistools.products.fetch import Area
    from gistools.products.rasters import RasterSettings, rasters_from_tiles

    base, _log = server
    served = {"left": 6}

    class Proxy(http.server.BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, *args):
            pass

        def do_GET(self):  # noqa: N802 - http.server's name
            if served["left"] <= 0:  # stopped: the connection closed without an answer
                self.close_connection = True
                self.connection.close()
                return
            served["left"] -= 1
            self.wfile.write(_forward(self, base))

    proxy = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Proxy)
    threading.Thread(target=proxy.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{proxy.server_address[1]}/lone-star-laszip/ept.json"
    settings = RasterSettings(cell_size="1m", classify_ground="smrf")
    try:
        area = Area(url, AOI, tmp_path / "cache", tile_size="10m", client=RangeClient(retries=1, backoff=0.01))
        with pytest.raises(DataFileError) as err:
            rasters_from_tiles(area, tmp_path / "a", settings)
        assert url.rsplit("/", 1)[0] in str(err.value) and "\n" not in str(err.value)
        assert not list((tmp_path / "cache").rglob("*.laz")), "a tile written from part of the area"
        served["left"] = 10_000  # started again
        area = Area(url, AOI, tmp_path / "cache", tile_size="10m", client=RangeClient(retries=1, backoff=0.01))
        report = rasters_from_tiles(area, tmp_path / "a", settings)
        assert report["counts"]["failed"] == 0
    finally:
        proxy.shutdown()
        proxy.server_close()
    clean = Area(DATA / "lone-star-laszip" / "ept.json", AOI, tmp_path / "cache3", tile_size="10m")
    rasters_from_tiles(clean, tmp_path / "b", settings)
    assert _same_rasters(tmp_path / "a", tmp_path / "b", ("dsm", "dem", "ndsm")) >= 3 * 6


def test_an_index_of_datasets_picks_those_that_meet_the_area(server, tmp_path):
    """An index (GeoJSON of dataset boundaries and their URLs, as USGS publishes 3DEP's): only the datasets that
    meet the area are opened (another's URL is never asked for), and their points are the dataset's own; two
    datasets of different CRSs over one area are refused in one line."""
    import geopandas as gpd
    import shapely

    from gistools.errors import InputError
    from gistools.products.fetch import Area

    from gistools.io.area import open_source

    base, log = server
    crs = open_source(DATA / "lone-star-laszip").crs_wkt  # NAD83 / UTM 12N (the COPC file's header says geocentric)
    near = shapely.box(515363, 4918339, 515407, 4918383)
    far = shapely.box(600000, 5000000, 600100, 5000100)
    gpd.GeoDataFrame({"name": ["lone star", "elsewhere"], "url": [f"{base}/lone-star-laszip/ept.json",
                                                                  f"{base}/elsewhere/ept.json"]},
                     geometry=[near, far], crs=crs).to_file(tmp_path / "index.gpkg")
    before = _log_lines(log)
    tiles = Area(str(tmp_path / "index.gpkg"), AOI, tmp_path / "cache", tile_size=10.0, margin=0).local_tiles()
    asked = log.read_text(encoding="utf-8").splitlines()[before:]
    assert asked and not any("/elsewhere/" in line for line in asked)
    rows = set()
    for tile in tiles:
        las = laspy.read(tile)
        rows |= _rows({"x": np.asarray(las.x), "y": np.asarray(las.y), "z": np.asarray(las.z),
                       "classification": np.asarray(las.classification), "return_number": np.asarray(las.return_number)})
    expected = _reference(EPT_FILES, _in_box)
    assert rows == expected, (len(rows), len(expected), sorted(rows - expected)[:5], sorted(expected - rows)[:5])
    other = ROOT / "sample_tiles" / "35712.las"  # another CRS (Florida West, US feet), said to cover the same area
    gpd.GeoDataFrame({"url": [f"{base}/lone-star-laszip/ept.json", str(other)]},
                     geometry=[near, near], crs=crs).to_file(tmp_path / "two.gpkg")
    with pytest.raises(InputError, match="in different CRSs") as err:
        Area(str(tmp_path / "two.gpkg"), AOI, tmp_path / "cache2", tile_size=10.0).local_tiles()
    assert "\n" not in str(err.value)


def test_a_vpc_of_served_files_is_read_by_area(server, tmp_path):
    """A virtual point cloud whose item is served (its href a URL): read by area, the rasters of the COPC file's
    local copy; without an area it is refused in one line naming the area's option."""
    import json

    base, _log = server
    vpc = tmp_path / "served.vpc"
    vpc.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "stac_version": "1.0.0", "id": "lone-star", "properties": {},
         "assets": {"data": {"href": f"{base}/lone-star.copc.laz"}}}]}), encoding="utf-8")
    _gistools("rasters", vpc, *AREA_OPTIONS, "--cell-size", "1m", "--out", tmp_path / "a")
    _gistools("rasters", COPC_FILE, *AREA_OPTIONS, "--cell-size", "1m", "--out", tmp_path / "b")
    assert _same_rasters(tmp_path / "a", tmp_path / "b", ("dsm", "dem")) >= 2 * 6
    done = _gistools("rasters", vpc, "--out", tmp_path / "c", check=False)
    assert done.returncode == 1 and "read by area" in done.stderr and "--aoi" in done.stderr
    assert "Traceback" not in done.stderr


def test_rasters_through_a_faulty_service_equal_the_clean_runs(faulty, tmp_path):
    """503s, cut and slow bodies and resets on the way: the rasters of the area equal those of the local copy."""
    from gistools.io.http import RangeClient
    from gistools.products.fetch import Area
    from gistools.products.rasters import RasterSettings, rasters_from_tiles

    settings = RasterSettings(cell_size="1m", classify_ground="smrf")
    client = RangeClient(backoff=0.01, timeout=5)
    rasters_from_tiles(Area(f"{faulty}/lone-star.copc.laz", AOI, tmp_path / "c1", tile_size="10m", client=client),
                       tmp_path / "a", settings)
    assert client.retried > 0
    rasters_from_tiles(Area(COPC_FILE, AOI, tmp_path / "c2", tile_size="10m"), tmp_path / "b", settings)
    assert _same_rasters(tmp_path / "a", tmp_path / "b", ("dsm", "dem", "ndsm")) >= 3 * 6


def test_an_area_on_a_lattice_of_odd_size_keeps_each_point_once_and_its_margin(tmp_path):
    """The sample block (US survey feet) cut on 500 m tiles (1640.416... ft) with a 30 m margin: every point of the
    area grown by the margin is in exactly one tile (counted, not only as a set), the margin on every side; no tile
    is made of the margin alone (each tile's cell meets the area)."""
    from gistools.products.fetch import Area
    from gistools.units import US_SURVEY_FOOT

    sample = sorted((ROOT / "sample_tiles").glob("*.la?"))
    w, s, e, n = 430210.0, 1810333.0, 431790.0, 1811650.0
    margin = 30 / US_SURVEY_FOOT
    size = 500 / US_SURVEY_FOOT
    tiles = Area([str(p) for p in sample], f"{w},{s},{e},{n}", tmp_path / "cache", tile_size="500m",
                 margin="30m").local_tiles()
    got = []
    for tile in tiles:
        las = laspy.read(tile)
        got += list(zip(np.round(las.x, 2), np.round(las.y, 2), np.round(las.z, 2)))
        x0, y0 = (float(v) for v in Path(tile).stem.split("_"))
        assert x0 < e and x0 + size > w and y0 < n and y0 + size > s, tile.name  # the cell meets the area
    expected = []
    for f in sample:
        las = laspy.read(f)
        x, y = np.asarray(las.x), np.asarray(las.y)
        keep = (x >= w - margin) & (x <= e + margin) & (y >= s - margin) & (y <= n + margin)
        expected += list(zip(np.round(x[keep], 2), np.round(y[keep], 2), np.round(np.asarray(las.z)[keep], 2)))
    assert len(got) == len(set(got)) == len(expected) and set(got) == set(expected)
    assert min(x for x, _, _ in got) < w and max(x for x, _, _ in got) > e  # the margin on the west and the east
    assert min(y for _, y, _ in got) < s and max(y for _, y, _ in got) > n
