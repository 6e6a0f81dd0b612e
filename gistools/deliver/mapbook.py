"""The map book of a shrub chain's output folder (``gistools mapbook OUT``, ``gistools:mapbook``): ``OUT/map_book.pdf``,
one page per tile of a tile index (each fitted to the page), or per sheet of a grid at a scale (1:10,000 by
default), what a field team prints: the classes with the roads and water, a coordinate grid, a locator map, legend,
scale bar, north arrow and the parameters (gistools.plot.mapbook_page). Given a ``gistools travel`` folder, every page
also draws its isochrones and points last seen (a ``gistools viewshed`` folder: the cells seen); given a ``gistools fuels`` folder, a last page shows its canopy base
height classes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.windows import from_bounds

from ..errors import InputError, OutputExistsError
from ..io.outdir import claim_output, output_folder
from ..io.atomic import atomic_path
from ..parameters import check, choices, default_for, option, render
from ..units import LinearUnit
from ..engine.record import add_run, read_folder_report
from .layers import check_folders

__all__ = ["map_book", "PAPERS"]

PAPERS = choices("paper")  # declared in gistools.parameters.deliver
MAX_PAGES = default_for("max_pages")
CREATOR = "gistools mapbook"  # the PDF's Creator: the mark of a map book gistools wrote


def _check(scale, paper, max_pages) -> None:
    if not (isinstance(scale, (int, float)) and scale > 0):
        raise InputError(f"{option('scale')} {scale!r} must be a positive number (the n of 1:n)",
                         hint=f"e.g. {option('scale', '10000')}")
    check("paper", paper)
    if not (isinstance(max_pages, int) and max_pages > 0):
        raise InputError(f"{option('max_pages')} {max_pages!r} must be a positive integer",
                         hint=f"e.g. {option('max_pages', '1000')}")


def _fitted(bounds, frame_w: float, frame_h: float) -> tuple:
    """``bounds`` grown about their centre to the frame's proportions."""
    w, s, e, n = bounds
    cx, cy = (w + e) / 2, (s + n) / 2
    half_w, half_h = (e - w) / 2, (n - s) / 2
    if half_w / frame_w > half_h / frame_h:
        half_h = half_w * frame_h / frame_w
    else:
        half_w = half_h * frame_w / frame_h
    return cx - half_w, cy - half_h, cx + half_w, cy + half_h


def _sheets(extent, ground_w: float, ground_h: float) -> list:
    """A grid of sheets of ``ground_w`` x ``ground_h`` (CRS units) over ``extent``, from its north-west corner."""
    w, s, e, n = extent
    cols, rows = max(1, math.ceil((e - w) / ground_w)), max(1, math.ceil((n - s) / ground_h))
    return [(w + c * ground_w, n - (r + 1) * ground_h, w + (c + 1) * ground_w, n - r * ground_h)
            for r in range(rows) for c in range(cols)]


def _read(src, bounds, max_px: int) -> np.ndarray:
    """The class raster over ``bounds`` (255 beyond it), at most ``max_px`` pixels a side (the mode of each block)."""
    window = from_bounds(*bounds, transform=src.transform)
    width, height = max(1, round(window.width)), max(1, round(window.height))
    k = max(1, math.ceil(max(width, height) / max_px))
    return src.read(1, window=window, boundless=True, fill_value=255, out_shape=(max(1, height // k), max(1, width // k)),
                    resampling=Resampling.mode if k > 1 else Resampling.nearest)


def sheets_with_classes(src, ground_w: float, ground_h: float) -> int:
    """How many sheets of the grid (``_sheets``) hold a class cell, at least: the sheets of the valid cells of the
    class raster read at most 1,000 cells a side (a lower bound, from one read, before any sheet is listed)."""
    w, s, e, n = src.bounds
    k = max(1, math.ceil(max(src.width, src.height) / 1000))
    data = src.read(1, out_shape=(max(1, src.height // k), max(1, src.width // k)), resampling=Resampling.nearest)
    rows, cols = np.nonzero(data != 255)
    x = w + (cols + 0.5) * (e - w) / data.shape[1]
    y = n - (rows + 0.5) * (n - s) / data.shape[0]
    ncols = max(1, math.ceil((e - w) / ground_w))
    return int(np.unique((np.floor((n - y) / ground_h) * ncols + np.floor((x - w) / ground_w)).astype(np.int64)).size)


MAX_SHEETS = 1_000_000  # sheets of the grid listed at most (empty ones included), whatever --max-pages says


def _check_sheets(src, ground_w: float, ground_h: float, scale, max_pages: int) -> None:
    """Refuse a grid of sheets too many to list, or whose sheets with classes alone exceed ``max_pages``, before
    any sheet is read (the arithmetic in the message)."""
    w, s, e, n = src.bounds
    cols, rows = max(1, math.ceil((e - w) / ground_w)), max(1, math.ceil((n - s) / ground_h))
    if cols * rows <= max_pages:
        return
    many = cols * rows > MAX_SHEETS
    at_least = 0 if many else sheets_with_classes(src, ground_w, ground_h)
    if many or at_least > max_pages:
        found = f"more than the {MAX_SHEETS:,} a map book is cut into" if many else f"{at_least:,} or more with classes"
        raise InputError(f"at 1:{scale:,.0f} a sheet covers {ground_w:,.4g} x {ground_h:,.4g} of the map's "
                         f"{e - w:,.6g} x {n - s:,.6g}: {cols:,} x {rows:,} sheets, {found}, more than "
                         f"{option('max_pages', max_pages)}",
                         hint=f"Give a smaller scale (a larger n, e.g. {option('scale', '25000')}), or a higher "
                              f"{option('max_pages')}")


def _pages(src, tile_index, tile_field, frame_w, frame_h, scale, unit_m, max_pages: int = MAX_PAGES
           ) -> tuple[list, list, float | None]:
    """(page bounds, page labels, the scale when it is fixed)."""
    if tile_index is None:
        ground_w, ground_h = frame_w * 0.0254 * scale / unit_m, frame_h * 0.0254 * scale / unit_m
        _check_sheets(src, ground_w, ground_h, scale, max_pages)
        sheets = _sheets(tuple(src.bounds), ground_w, ground_h)
        return sheets, [f"sheet {i + 1}" for i in range(len(sheets))], float(scale)
    import pyproj

    from ..io.vector import check_crs, check_field, read_layer

    layer = read_layer(tile_index, ("polygon",), render(option("tile_index")))  # also in a log line: named now
    check_field(layer, tile_field, tile_index)
    layer = check_crs(layer, pyproj.CRS.from_wkt(src.crs.to_wkt()), str(tile_index), reproject=None)
    pages = [_fitted(g.bounds, frame_w, frame_h) for g in layer.geometry if g is not None and not g.is_empty]
    labels = [f"tile {t}" for t, g in zip(layer[tile_field], layer.geometry) if g is not None and not g.is_empty]
    return pages, labels, None


def map_book(out, *, tile_index=None, tile_field: str = "TILE_ID", travel=None, viewshed=None, fuels=None,
             plan=None, scale: float = 10000, paper: str = "letter", max_pages: int = MAX_PAGES) -> dict:
    """A PDF map book of a shrub chain's classes, what a field team prints: ``gistools mapbook``.

    Writes ``out/map_book.pdf``: a page per tile of ``tile_index`` (each fitted to its page), or per sheet of a grid at
    1:``scale``.

    Parameters
    ----------
    out : str or path
        The folder of a shrub chain run.
    tile_index : str, optional
        Tile footprints, a path or ``file.gpkg:LAYER``; None: a grid of sheets.
    tile_field : str
        The tile index's field holding the tile number, printed on each page.
    travel : str or path, optional
        The output folder of ``gistools travel``: its isochrones and points last seen drawn on every page.
    viewshed : str or path, optional
        The output folder of ``gistools viewshed``: the cells seen, semi-transparent cyan on every page.
    fuels : str or path, optional
        The output folder of ``gistools fuels``: a last page of its canopy base height classes over the whole area.
    plan : str or path, optional
        The output folder of ``gistools search-plan``: a page per segment assignment (the segments given hours in
        its effort, by rank; every segment by rank when none is), fitted to the segment, with its outline, the route
        to it and the assignment (area, POA, POD, hours, sweep width, minutes from staging).
    scale : float
        The n of 1:n, for the grid of sheets.
    paper : str
        The paper (landscape), e.g. ``"letter"``.
    max_pages : int
        Refuse a map book of more pages than this.

    Returns
    -------
    dict
        ``pdf`` (the path, as text), ``pages`` (with the fuels page), ``labels`` and ``scales`` (the n of 1:n of each
        map page).

    Raises
    ------
    InputError
        An option is not valid, ``out`` is not a folder, or the book would have more than ``max_pages`` pages.
    OutputExistsError
        A file gistools did not write is in the way.

    Examples
    --------
    >>> from gistools import map_book, shrub_from_tiles
    >>> report = shrub_from_tiles("sample_tiles", "shrub", make_map=False)  # doctest: +SKIP
    >>> map_book("shrub", tile_index="sample_tiles/breaklines.gpkg:FOOTPRINT")["pages"]  # doctest: +SKIP
    4
    """
    import time

    started = time.time()
    _check(scale, paper, max_pages)  # every option before the folder is touched
    layers = check_folders(travel=travel, viewshed=viewshed, fuels=fuels, plan=plan)
    out = output_folder(out)
    if not out.is_dir():
        raise InputError(f"{out}: no such folder", hint="Run gistools shrub into it first")
    with claim_output(out, "gistools mapbook"):  # the folder's lock; a killed run's partial file is removed first
        result = _map_book(out, tile_index=tile_index, tile_field=tile_field, scale=scale, paper=paper, max_pages=max_pages,
                           **layers)
        add_run(out, {"tool": "gistools mapbook", "seconds": round(time.time() - started, 3),
                      "settings": {"tile_index": tile_index, "tile_field": tile_field, "scale": scale, "paper": paper,
                                   **{k: str(v) for k, v in layers.items()}}})
    return result


def _draw_pages(pdf, src, pages, labels, book: dict) -> list:
    """Each map page into ``pdf`` (the tiles' or sheets', then the segment assignments'); the n of 1:n of each."""
    from ..plot import mapbook_page
    from .layers import viewshed_on

    scales, unit, tiles = [], book["unit"], book["tiles"]
    for i, (bounds, label) in enumerate(zip(pages, labels)):
        page_scale = book["fixed"] or (bounds[2] - bounds[0]) * unit.metres / (book["frame_w"] * 0.0254)
        scales.append(page_scale)
        data = _read(src, bounds, 1500)
        seen = None if book["viewshed"] is None else viewshed_on(book["viewshed"], src.crs, bounds, data.shape)
        job = book["assignments"][i - tiles] if i >= tiles else None
        fig = mapbook_page(data, bounds, title=f"{book['title']} - {label}", unit=unit, crs=src.crs, scale=page_scale,
                           locator=book["locator"], locator_bounds=book["locator_bounds"], pages=pages, page_index=i,
                           parameters=job["text"] if job else book["parameters"], paper=book["paper"],
                           travel=book["travel"], seen=seen, segment=(job["outline"], job["route"]) if job else None)
        pdf.savefig(fig)
    return scales


def _assignments(plan, crs, frame_w: float, frame_h: float, unit) -> list[dict]:
    """A page per segment assignment of a search plan folder: the segments given hours, by rank (every segment by
    rank when none is), each with its page's bounds (the segment and a tenth around it, fitted to the frame), its
    outline, the route to it and the assignment's text."""
    from .layers import plan_frames

    frames = plan_frames(plan, crs)
    seg = frames["segments"].sort_values("rank")
    if (seg["hours"] > 0).any():
        seg = seg[seg["hours"] > 0]
    routes = frames["routes"]
    jobs = []
    for _, r in seg.iterrows():
        w, s, e, n = r.geometry.bounds
        pad = 0.1 * max(e - w, n - s) + 1e-9
        bounds = _fitted((w - pad, s - pad, e + pad, n + pad), frame_w, frame_h)
        to = routes[(routes["kind"] == "segment") & (routes["target"].astype(str) == str(int(r["segment"])))]
        minutes = r.get("minutes_from_staging")
        text = (f"Segment {int(r['segment'])}, rank {int(r['rank'])}\n{r['area_ha']:.2f} ha "
                f"({r['area_ha'] * 1e4 / 4046.8564224:.2f} acres), {r['vegetation']}\n"
                f"POA {100 * r['poa']:.2f} %, sweep width {r['sweep_width_m']:.1f} m\n"
                f"{r['hours']:g} searcher-hours: POD {100 * r['pod']:.1f} %\n"
                + (f"{minutes:.1f} min from staging" if minutes == minutes and minutes is not None else
                   "not reached from staging"))
        jobs.append({"bounds": bounds, "label": f"segment {int(r['segment'])} (rank {int(r['rank'])})",
                     "outline": r.geometry, "route": to.geometry.iloc[0] if len(to) else None, "text": text})
    return jobs


def _map_book(out, *, tile_index=None, tile_field: str = "TILE_ID", scale: float = 10000, paper: str = "letter",
              max_pages: int = MAX_PAGES, travel=None, viewshed=None, fuels=None, plan=None) -> dict:
    """Write ``out/map_book.pdf`` from the chain's ``classes.vrt``: a page per tile of ``tile_index`` (fitted), or
    per sheet of a grid at 1:``scale`` (with a travel folder's isochrones and points last seen), and a fuels folder's
    canopy base height page; returns {"pdf", "pages", "scales"}."""
    from matplotlib.backends.backend_pdf import PdfPages

    from ..plot import fuels_page, map_frame_inches, map_parameters
    from .layers import CBH_CLASSES, cbh_classes_on, travel_frames

    _check(scale, paper, max_pages)
    out = output_folder(out)
    report = read_folder_report(out) or {}
    if not (out / "classes.vrt").exists() or not report.get("horizontal_unit_m"):
        raise InputError(f"{out}: no classes.vrt and report.json to print", hint="Run gistools shrub into this folder first")
    unit = LinearUnit(report["horizontal_unit"], report["horizontal_unit_m"])
    title = report.get("map_title") or f"Shrub density - {out.name}"
    frame_w, frame_h = map_frame_inches(paper)
    parameters = map_parameters(out / "classes.vrt", out / "cover.vrt", unit)
    target = out / "map_book.pdf"
    if target.exists() and CREATOR.encode() not in target.read_bytes():
        raise OutputExistsError("a file gistools did not write is in the way", path=target,
                                hint="Move it, or write the map book from another folder")
    with rasterio.open(out / "classes.vrt") as src:
        pages, labels, fixed = _pages(src, tile_index, tile_field, frame_w, frame_h, scale, unit.metres, max_pages)
        keep = [i for i, b in enumerate(pages) if (_read(src, b, 64) != 255).any()]  # sheets with classes on them
        pages, labels = [pages[i] for i in keep], [labels[i] for i in keep]
        if not pages:
            raise InputError(f"{out}: no page has classes on it", hint="Check the tile index's CRS and extent")
        assignments = [] if plan is None else _assignments(plan, src.crs.to_wkt(), frame_w, frame_h, unit)
        tiles = len(pages)
        pages += [a["bounds"] for a in assignments]
        labels += [a["label"] for a in assignments]
        if len(pages) > max_pages:
            raise InputError(f"{len(pages):,} pages at 1:{scale:,.0f} is more than {option('max_pages', max_pages)}",
                             hint=f"Give a smaller scale (a larger n, e.g. {option('scale', '25000')}), or a higher "
                                  f"{option('max_pages')}")
        locator_bounds = tuple(src.bounds)
        locator = _read(src, locator_bounds, 400)
        drawn = None if travel is None else travel_frames(travel, src.crs.to_wkt())
        book = {"title": title, "unit": unit, "locator": locator, "locator_bounds": locator_bounds, "paper": paper,
                "parameters": parameters, "travel": drawn, "viewshed": viewshed, "fixed": fixed, "frame_w": frame_w,
                "tiles": tiles, "assignments": assignments}
        with atomic_path(out / "map_book.pdf", overwrite=True) as tmp:
            with PdfPages(tmp, metadata={"Creator": CREATOR, "Title": title}) as pdf:
                scales = _draw_pages(pdf, src, pages, labels, book)
                if fuels is not None:
                    whole = _fitted(locator_bounds, frame_w, frame_h)
                    shape = (int(round(1500 * frame_h / frame_w)), 1500)
                    fig = fuels_page(cbh_classes_on(fuels, src.crs, whole, shape), whole,
                                     title=f"{title} - canopy base height", unit=unit, crs=src.crs, classes=CBH_CLASSES,
                                     parameters=f"from {Path(fuels).name}", paper=paper)
                    pdf.savefig(fig)
    return {"pdf": str(out / "map_book.pdf"), "pages": len(pages) + (fuels is not None),
            "labels": labels + (["canopy base height"] if fuels is not None else []), "scales": scales,
            "bounds": pages}
