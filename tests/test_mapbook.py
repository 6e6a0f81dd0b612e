"""The map book: one page per tile of the tile index (pdfinfo), each rendered by pdftoppm with the classes in their
colours and a locator map; a grid of sheets at a scale covers every class cell; bad options refused."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio

from conftest import SAMPLE
from gistools.errors import InputError
from gistools.grid import affine_apply
from gistools.lidar.shrub import CLASS_STYLE
from gistools.deliver.mapbook import map_book

FOOTPRINT = f"{SAMPLE / 'breaklines.gpkg'}:FOOTPRINT"
if shutil.which("pdftoppm") is None:  # pragma: no cover - depends on the machine
    import os

    if os.environ.get("CI"):
        raise RuntimeError("CI must run the map book tests: the test command installs poppler-utils (pdftoppm)")
    pytest.skip("map book tests: pdftoppm is not installed (apt-get install poppler-utils)", allow_module_level=True)


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    from gistools.products.shrub import shrub_from_tiles

    out = tmp_path_factory.mktemp("chain")
    b = SAMPLE / "breaklines.gpkg"
    shrub_from_tiles(SAMPLE, out, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                     waterbodies=f"{b}:WATERBODY", tile_index=FOOTPRINT, make_map=False)
    return out


def pages_of(pdf) -> int:
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    return int(next(line.split()[-1] for line in info.splitlines() if line.startswith("Pages:")))


def test_a_page_per_tile_rendered_with_the_class_colours(chain, tmp_path):
    from PIL import Image

    result = map_book(chain, tile_index=FOOTPRINT)
    assert result["pages"] == 4 == pages_of(result["pdf"])
    assert sorted(result["labels"]) == [f"tile {t}" for t in ("35712", "35713", "35812", "35813")]
    subprocess.run(["pdftoppm", "-r", "50", "-png", result["pdf"], str(tmp_path / "page")], check=True)
    pngs = sorted(tmp_path.glob("page*.png"))
    assert len(pngs) == 4
    seen = set()
    for png in pngs:
        img = np.asarray(Image.open(png).convert("RGB")).astype(int)
        assert img.shape[1] > img.shape[0]  # landscape
        for code, (_name, colour) in CLASS_STYLE.items():
            rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
            if code and (np.abs(img - rgb).max(axis=2) <= 6).sum() > 20:
                seen.add(code)
    assert seen == {1, 2, 3, 4, 5}  # every class, roads and water included, is on the pages
    assert all(1000 < s < 3000 for s in result["scales"])  # a 1000 ft tile on a letter page: about 1:1,760


def test_a_grid_of_sheets_at_a_scale_covers_every_class_cell(chain):
    result = map_book(chain, scale=2500)
    assert result["pages"] == pages_of(result["pdf"]) and set(result["scales"]) == {2500.0}
    with rasterio.open(chain / "classes.vrt") as src:
        classes = src.read(1)
        rows, cols = np.nonzero(classes != 255)
        xs, ys = affine_apply(src.transform, (cols + 0.5, rows + 0.5))
    covered = np.zeros(len(xs), bool)
    for w, s, e, n in result["bounds"]:
        covered |= (xs >= w) & (xs <= e) & (ys >= s) & (ys <= n)
    assert covered.all()


def test_bad_map_book_options_are_refused(chain, tmp_path):
    for kw, words in ((dict(scale=0), "^scale 0"), (dict(paper="napkin"), "^paper 'napkin'"),
                      (dict(max_pages=0), "^max_pages 0")):  # a Python call names the argument
        with pytest.raises(InputError, match=words):
            map_book(chain, **kw)
    with pytest.raises(InputError, match="more than max_pages=3"):  # a Python call names the argument
        map_book(chain, scale=100, max_pages=3)
    with pytest.raises(InputError, match="Run gistools shrub"):
        map_book(tmp_path)


def test_a_pdf_gistools_did_not_write_is_kept(chain, tmp_path):
    from gistools.errors import OutputExistsError

    copy = tmp_path / "copy"
    shutil.copytree(chain, copy)
    (copy / "map_book.pdf").write_bytes(b"%PDF-1.4 someone else's")
    with pytest.raises(OutputExistsError):
        map_book(copy)
    assert (copy / "map_book.pdf").read_bytes() == b"%PDF-1.4 someone else's"
    (copy / "map_book.pdf").unlink()
    map_book(copy, tile_index=FOOTPRINT)
    assert map_book(copy, tile_index=FOOTPRINT)["pages"] == 4  # its own book is replaced


START = (430500.0, 1811500.0)  # the point last seen, in tile 35712 (US survey feet)
BANDS = {"0-2 min": "#1a9850", "2-4 min": "#91cf60", "4-6 min": "#fee08b"}  # gistools travel's band colours
MAGENTA = np.array([255, 0, 255])


@pytest.fixture(scope="module")
def layers(chain, tmp_path_factory):
    from gistools.products.fuels import fuels_from_tiles
    from gistools.products.travel import TravelSettings, travel_from_dem

    root = tmp_path_factory.mktemp("layers")
    b = SAMPLE / "breaklines.gpkg"
    travel_from_dem(chain, root / "travel", [f"{START[0]},{START[1]}"], TravelSettings(isochrones=(2, 4, 6)),
                    roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE", waterbodies=f"{b}:WATERBODY")
    fuels_from_tiles(SAMPLE, root / "fuels")
    return root


def rendered(pdf, folder, dpi=100) -> list:
    from PIL import Image

    folder.mkdir()
    subprocess.run(["pdftoppm", "-r", str(dpi), "-png", str(pdf), str(folder / "page")], check=True)
    return [np.asarray(Image.open(p).convert("RGB")).astype(int) for p in sorted(folder.glob("page*.png"))]


def in_frame(img) -> np.ndarray:
    """The map's frame of a page (gistools.plot.MAP_FRAME, figure fractions from the lower left)."""
    from gistools.plot import MAP_FRAME

    h, w = img.shape[:2]
    x0, y0, fw, fh = MAP_FRAME
    return img[int(h * (1 - y0 - fh)) + 2:int(h * (1 - y0)) - 2, int(w * x0) + 2:int(w * (x0 + fw)) - 2]


def near(img, colour, tol=8) -> np.ndarray:
    rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)]) if isinstance(colour, str) else colour
    return np.abs(img - rgb).max(axis=2) <= tol


def test_the_isochrones_and_the_point_last_seen_are_on_the_pages(chain, layers, tmp_path):
    """Each isochrone's colour is drawn in the map frames, which the book without --travel never shows; the magenta
    dot of the point last seen is on the one page whose footprint holds it, where the point falls on that page."""
    from gistools.plot import MAP_FRAME

    plain = map_book(chain, tile_index=FOOTPRINT)
    before = [in_frame(p) for p in rendered(plain["pdf"], tmp_path / "plain")]
    result = map_book(chain, tile_index=FOOTPRINT, travel=layers / "travel")
    assert result["pages"] == 4 == pages_of(result["pdf"])
    pages = rendered(result["pdf"], tmp_path / "travel")
    after = [in_frame(p) for p in pages]
    for name, colour in BANDS.items():
        assert sum(near(p, colour).sum() for p in before) < 5, name
        assert sum(near(p, colour).sum() for p in after) > 100, name
    holding = [i for i, (w, s, e, n) in enumerate(result["bounds"]) if w < START[0] < e and s < START[1] < n]
    assert len(holding) == 1
    for i, img in enumerate(after):
        dots = near(img, MAGENTA, 12)
        if i != holding[0]:
            assert dots.sum() == 0
            continue
        assert dots.sum() > 20
        # where the point is on the page: its place in the page's bounds, in the map frame (no margin: the bounds
        # are fitted to the frame)
        w, s, e, n = result["bounds"][i]
        h, wpx = pages[i].shape[:2]
        x0, y0, fw, fh = MAP_FRAME
        px = wpx * (x0 + fw * (START[0] - w) / (e - w)) - (int(wpx * x0) + 2)
        py = h * (1 - y0 - fh * (START[1] - s) / (n - s)) - (int(h * (1 - y0 - fh)) + 2)
        rows, cols = np.nonzero(dots)
        assert abs(cols.mean() - px) < 3 and abs(rows.mean() - py) < 3, (cols.mean(), px, rows.mean(), py)


def test_the_fuels_page_shows_the_canopy_base_height_classes(chain, layers, tmp_path):
    """A last page of the canopy base height classes: each class's share of the coloured map equals its share of
    the cells of cbh.vrt (classed here at 4 and 8 m, US survey feet to metres)."""
    result = map_book(chain, tile_index=FOOTPRINT, travel=layers / "travel", fuels=layers / "fuels")
    assert result["pages"] == 5 == pages_of(result["pdf"]) and result["labels"][-1] == "canopy base height"
    page = in_frame(rendered(result["pdf"], tmp_path / "fuels")[-1])
    with rasterio.open(layers / "fuels" / "cbh.vrt") as src:
        cbh_m = src.read(1, masked=True).filled(0) * 1200 / 3937
    cells = {1: np.count_nonzero((cbh_m > 0) & (cbh_m < 4)), 2: np.count_nonzero((cbh_m >= 4) & (cbh_m < 8)),
             3: np.count_nonzero(cbh_m >= 8)}
    pixels = {code: near(page, colour, 6).sum() for code, colour in {1: "#d7301f", 2: "#fdae61", 3: "#1a9641"}.items()}
    assert sum(cells.values()) > 5
    for code in cells:
        assert pixels[code] / sum(pixels.values()) == pytest.approx(cells[code] / sum(cells.values()), abs=0.03), pixels
    with pytest.raises(InputError, match="^fuels=.*no cbh.vrt"):
        map_book(chain, fuels=layers / "travel")


def test_the_cells_seen_are_washed_in_cyan_on_the_pages(chain, layers, tmp_path):
    """Over no-vegetation cells (white), a cell deep inside the viewshed (viewshed.tif == 1, read by rasterio) is
    cyan at 110/255 over white on its page, one deep inside the hidden part stays white."""
    from scipy import ndimage

    from gistools.plot import MAP_FRAME
    from gistools.products.viewshed import viewshed_from_surface

    viewshed_from_surface(chain / "dsm.vrt", tmp_path / "viewshed", observers=[f"{START[0]},{START[1]}"],
                          observer_height="6ft")
    result = map_book(chain, tile_index=FOOTPRINT, viewshed=tmp_path / "viewshed")
    pages = rendered(result["pdf"], tmp_path / "pages")
    with rasterio.open(tmp_path / "viewshed" / "viewshed.tif") as vs, rasterio.open(chain / "classes.vrt") as cl:
        assert vs.transform == cl.transform
        seen, white = vs.read(1), cl.read(1) == 0
        deep = {True: ndimage.binary_erosion(white & (seen == 1), iterations=2),
                False: ndimage.binary_erosion(white & (seen == 0), iterations=2)}
        alpha = 110 / 255
        want = {True: alpha * np.array([0, 229, 255]) + (1 - alpha) * 255, False: np.array([255, 255, 255])}
        checked = {True: 0, False: 0}
        for i, (w, s, e, n) in enumerate(result["bounds"]):
            h, wpx = pages[i].shape[:2]
            x0, y0, fw, fh = MAP_FRAME
            for is_seen, mask in deep.items():
                rows, cols = np.nonzero(mask)
                xs, ys = vs.xy(rows[::37], cols[::37])
                for x, y in zip(xs, ys):
                    if not (w < x < e and s < y < n):
                        continue
                    px = int(round(wpx * (x0 + fw * (x - w) / (e - w))))
                    py = int(round(h * (1 - y0 - fh * (y - s) / (n - s))))
                    if (np.abs(pages[i][py - 2:py + 3, px - 2:px + 3] - pages[i][py, px]).max() > 0
                            or abs(px - wpx * x0) < 6 or abs(py - h * (1 - y0)) < 6):
                        continue  # a grid line, or the frame's edge
                    assert np.abs(pages[i][py, px] - want[is_seen]).max() <= 8, (is_seen, pages[i][py, px])
                    checked[is_seen] += 1
    assert checked[True] >= 20 and checked[False] >= 20, checked


def test_a_page_per_segment_assignment_with_its_outline_and_figures(chain, tmp_path):
    """A search plan whose effort gives hours to two segments: two more pages, each fitted around its segment
    (the segment's bounds inside the page's), its outline drawn in the map frame, its figures printed
    (pdftotext)."""
    import geopandas as gpd

    from gistools.plot import SEGMENT_EDGE
    from gistools.products.search_plan import search_plan

    effort = tmp_path / "effort.csv"
    effort.write_text("segment,hours\n2,3\n1,1.5\n", encoding="utf-8")
    search_plan(chain, tmp_path / "plan", f"{START[0]},{START[1]}", "dementia", staging="431200,1810600",
                effort=effort)
    result = map_book(chain, tile_index=FOOTPRINT, plan=tmp_path / "plan")
    assert result["pages"] == 6 == pages_of(result["pdf"])
    seg = gpd.read_file(tmp_path / "plan" / "segments.gpkg", layer="segments").set_index("segment")
    jobs = seg[seg["hours"] > 0].sort_values("rank")
    assert result["labels"][4:] == [f"segment {k} (rank {r})" for k, r in zip(jobs.index, jobs["rank"])]
    for (w, s, e, n), geom in zip(result["bounds"][4:], jobs.geometry):
        gw, gs, ge, gn = geom.bounds
        assert w < gw and s < gs and ge < e and gn < n
    text = subprocess.run(["pdftotext", "-layout", result["pdf"], "-"], capture_output=True, text=True,
                          check=True).stdout
    for k, r in jobs.iterrows():
        assert f"Segment {k}, rank {r['rank']}" in text and f"POD {100 * r['pod']:.1f} %" in text
    pages = [in_frame(p) for p in rendered(result["pdf"], tmp_path / "plan_pages")]
    assert all(near(p, SEGMENT_EDGE).sum() > 50 for p in pages[4:])
    assert all(near(p, SEGMENT_EDGE).sum() < 5 for p in pages[:4])
