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
        xs, ys = src.transform * (cols + 0.5, rows + 0.5)
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
