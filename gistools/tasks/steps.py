"""The shrub chain one step at a time, raster file in, raster file out (the dissertation's ModelBuilder steps).

These are what the QGIS algorithms ``gistools:ndsm / bands / breaklines / clip / density /
classify`` call, and what a script calls to rerun one step on its own rasters. Each reads
its inputs (a GeoTIFF, or a VRT mosaic of a county) in blocks of ``block`` x ``block``
cells and writes one tiled GeoTIFF block by block, atomically, so memory stays flat
whatever the extent. The arithmetic is the same pure functions ``gistools shrub`` runs per
tile, so the step-by-step chain gives the same cells as the whole chain.

Lengths take a unit ("25ft", "0.1m") or are in the raster's CRS units.
"""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import numpy as np
import pyproj
import rasterio
import shapely
from rasterio.features import rasterize
from rasterio.windows import Window, from_bounds

from ..errors import CRSMismatchError, DataFileError, InputError
from ..io.raster import DEFLATE_LEVEL, NODATA, atomic_path, crs_from_wkt, predictor_for, verify_raster
from ..io.vector import check_crs, read_layer, verify_gpkg, write_layer
from ..lidar.bands import BAND_NODATA, band_thresholds, height_bands
from ..lidar.density import halo_cells
from ..lidar.gridding import ndsm_from
from ..lidar.shrub import (CLASS_NAMES, CLASS_NODATA, DEFAULT_BREAKS, breaks_from_sample, lattice_sample, sample_step,
                            shrub_classes)
from ..lidar.vegetation import VEG_NODATA, VEG_ROAD, VEG_WATER, vegetation, vegetation_cover
from ..progress import ProgressCallback, report
from ..units import LinearUnit, horizontal_unit, length_to_crs_units, unit_from_word
from ..vector.breaklines import road_polygons, water_polygons
from ..vector.regions import class_polygons
from ..validation import check_breaks, check_length
from .rasters import GROUNDISH

__all__ = ["ndsm_from_rasters", "bands_from_ndsm", "breakline_polygons", "clip_bands", "density_from_vegetation",
           "classes_from_cover", "BLOCK"]

BLOCK = 2048


# ---------------------------------------------------------------- raster plumbing

def _open(path, what: str):
    try:
        return rasterio.open(path)
    except Exception as err:  # rasterio raises RasterioIOError, CPLE_* for unreadable files
        raise DataFileError(f"cannot open the {what} raster ({err})", path=path,
                            hint="Give a GeoTIFF or VRT written by gistools (or any single-band raster on the same grid)") from None


def _crs(src, path) -> pyproj.CRS:
    if src.crs is None:
        raise InputError("raster has no CRS", path=path, hint="Assign one (gdal_edit.py -a_srs) or rerun the step that wrote it")
    return crs_from_wkt(src.crs.to_wkt())


def _same_grid(base, base_path, other, other_path) -> None:
    """Refuse ``other`` unless it shares ``base``'s CRS and cell lattice."""
    a, b = _crs(base, base_path), _crs(other, other_path)
    if not a.equals(b, ignore_axis_order=True):
        raise CRSMismatchError(f"CRS {b.name!r} differs from {a.name!r} of {base_path}", path=other_path,
                               hint="Give rasters of one run (same CRS), or reproject one with gdalwarp")
    ta, tb = base.transform, other.transform
    cs = ta.a
    offx, offy = (tb.c - ta.c) / cs, (tb.f - ta.f) / cs
    if abs(tb.a - cs) > 1e-9 * cs or abs(offx - round(offx)) > 1e-6 or abs(offy - round(offy)) > 1e-6:
        raise InputError(f"raster is not on the cell lattice of {base_path} (cell {tb.a} vs {cs})", path=other_path,
                         hint="Give rasters of one run, or align it with gdalwarp -tr CELL CELL -tap")


def _read(src, base, win: Window, *, halo: int = 0, fill=None) -> np.ndarray:
    """Block ``win`` of ``base``'s grid (grown by ``halo`` cells) read from ``src`` (same lattice); float nodata -> NaN.

    Cells outside ``src`` are ``fill`` (default: its nodata, NaN for floats).
    """
    west, north = base.transform * (win.col_off - halo, win.row_off - halo)
    cs = base.transform.a
    east, south = west + (win.width + 2 * halo) * cs, north - (win.height + 2 * halo) * cs
    w = from_bounds(west, south, east, north, src.transform).round_offsets().round_lengths()
    nodata = src.nodata
    if fill is None:
        fill = nodata if nodata is not None else 0
    data = src.read(1, window=w, boundless=True, fill_value=fill, masked=False)
    if np.issubdtype(data.dtype, np.floating):
        data = data.astype(np.float64)
        if nodata is not None:
            data[data == nodata] = np.nan
    return data


def _windows(width: int, height: int, block: int):
    for row in range(0, height, block):
        for col in range(0, width, block):
            yield Window(col, row, min(block, width - col), min(block, height - row))


def _profile(base, dtype: str, nodata, product: str | None = None) -> dict:
    return dict(driver="GTiff", width=base.width, height=base.height, count=1, dtype=dtype, crs=base.crs,
                transform=base.transform, nodata=nodata, compress="deflate", zlevel=DEFLATE_LEVEL,
                predictor=predictor_for(dtype, product),
                tiled=True, blockxsize=256, blockysize=256, BIGTIFF="IF_SAFER")


def _check_outputs(outputs: dict, inputs) -> None:
    ins = {Path(p).resolve() for p in inputs if p is not None}
    for path in outputs.values():
        if path is not None and Path(path).resolve() in ins:
            raise InputError("the output would overwrite an input", path=path, hint="Choose another output file")


def _blockwise(base, outputs: dict, compute, *, progress, label: str, overwrite: bool, block: int) -> dict:
    """Write each product of ``outputs`` {name: (path | None, dtype, nodata, tags)} block by block.

    ``compute(window) -> {name: array}``. Every file is written to ``<name>.partial`` and renamed
    only when all blocks are done, so a cancelled or failed run leaves no output at all.
    """
    windows = list(_windows(base.width, base.height, block))
    wanted = {k: v for k, v in outputs.items() if v[0] is not None}
    with contextlib.ExitStack() as stack:
        dsts = {}
        for name, (path, dtype, nodata, tags) in wanted.items():
            tmp = stack.enter_context(atomic_path(path, overwrite=overwrite, verify=verify_raster))
            dst = stack.enter_context(rasterio.open(tmp, "w", **_profile(base, dtype, nodata, (tags or {}).get("GISTOOLS_PRODUCT"))))
            dst.update_tags(**{k: str(v) for k, v in (tags or {}).items()})
            if (tags or {}).get("units"):
                dst.units = (tags["units"],)
            dsts[name] = (dst, dtype, nodata)
        for i, win in enumerate(windows):
            report(progress, i / max(len(windows), 1), f"{label}: block {i + 1} of {len(windows)}")
            arrays = compute(win)
            for name, (dst, dtype, nodata) in dsts.items():
                a = np.asarray(arrays[name])
                if np.issubdtype(a.dtype, np.floating) and not np.issubdtype(np.dtype(dtype), np.floating):
                    raise AssertionError("float block for an integer raster")
                if np.issubdtype(a.dtype, np.floating):
                    a = np.where(np.isnan(a), nodata, a)
                dst.write(a.astype(dtype), 1, window=win)
        # the rasterio datasets close before the atomic renames (ExitStack unwinds in reverse)
    report(progress, 1.0, f"{label}: done")
    return {name: Path(v[0]) for name, v in wanted.items()}


def _z_unit(src, path, z_unit) -> LinearUnit:
    if z_unit:
        return unit_from_word(z_unit, name="z unit")
    word = (src.units or (None,))[0] or src.tags().get("GISTOOLS_Z_UNIT")
    if not word:
        raise InputError("raster carries no vertical unit", path=path,
                         hint="Give the z unit (m, ft or ftUS): --z-unit in the CLI, 'Z unit' in QGIS")
    return unit_from_word(word, name=f"{path}: vertical unit")


# ---------------------------------------------------------------- the steps

def ndsm_from_rasters(dsm, dem, out, *, overwrite: bool = True, block: int = BLOCK,
                      progress: ProgressCallback | None = None) -> Path:
    """nDSM = DSM - DEM (heights above ground, S3) on the DSM's grid; NaN where either has no value."""
    _check_outputs({"out": out}, [dsm, dem])
    with _open(dsm, "DSM") as s_dsm, _open(dem, "DEM") as s_dem:
        _same_grid(s_dsm, dsm, s_dem, dem)
        unit = (s_dsm.units or (None,))[0] or (s_dem.units or (None,))[0] or s_dsm.tags().get("GISTOOLS_Z_UNIT")

        def compute(win):
            return {"ndsm": ndsm_from(_read(s_dsm, s_dsm, win), _read(s_dem, s_dsm, win))}

        tags = {"GISTOOLS_PRODUCT": "ndsm", **({"GISTOOLS_Z_UNIT": unit, "units": unit} if unit else {})}
        return _blockwise(s_dsm, {"ndsm": (out, "float32", NODATA, tags)}, compute, progress=progress, label="nDSM",
                          overwrite=overwrite, block=block)["ndsm"]


def bands_from_ndsm(ndsm, out, *, top_class=None, preset: str = "exact", breaks_m=None, noise_floor: str | float = "0.1m",
                    z_unit: str | None = None, points_out=None, overwrite: bool = True, block: int = BLOCK,
                    progress: ProgressCallback | None = None) -> dict:
    """Height bands of an nDSM raster (S4-S5): B0 <= 0 (or the noise floor), B1, B2, B3, 4 above, 255 nodata.

    ``top_class``: the class-of-highest-first-return raster (``topclass``); cells topped by a
    ground or water point are B0. Thresholds in metres (``preset`` "exact" 1/2/6 m or
    "text_literal", or ``breaks_m``) are converted to the nDSM's vertical unit, read from
    the raster (or ``z_unit``). ``points_out``: also write the cell-centre points of B0-B3
    with band and height (``grid_code``), a GeoPackage (Raster To Point).
    Returns {"bands": path, "points": path?, "thresholds": (T1, T2, T3), "z_unit": name}.
    """
    check_length(noise_floor, "noise floor", allow_equal=True, example="0.1m")
    if breaks_m is not None:
        check_breaks(breaks_m, "band breaks", count=3, low=0, high=float("inf"), low_open=True, example="1,2,6")
    _check_outputs({"out": out, "points": points_out}, [ndsm, top_class])
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(_open(ndsm, "nDSM"))
        top = stack.enter_context(_open(top_class, "top class")) if top_class else None
        if top is not None:
            _same_grid(src, ndsm, top, top_class)
        unit = _z_unit(src, ndsm, z_unit)
        thresholds = band_thresholds(unit, preset, breaks_m)
        floor = length_to_crs_units(noise_floor, unit, name="noise floor")
        crs = _crs(src, ndsm)
        writer = _PointWriter(points_out, crs, overwrite) if points_out else None
        if writer:
            stack.enter_context(writer)

        def compute(win):
            h = _read(src, src, win)
            ground = np.isin(_read(top, src, win, fill=255), GROUNDISH) if top is not None else None
            codes = height_bands(h, thresholds, top_is_ground=ground, noise_floor=floor)
            if writer:
                writer.add(codes, h, src.window_transform(win))
            return {"bands": codes}

        tags = {"GISTOOLS_PRODUCT": "bands", "GISTOOLS_BAND_THRESHOLDS": json.dumps(list(thresholds)),
                "GISTOOLS_Z_UNIT": unit.short}
        paths = _blockwise(src, {"bands": (out, "uint8", BAND_NODATA, tags)}, compute, progress=progress, label="bands",
                           overwrite=overwrite, block=block)
    result = {"bands": paths["bands"], "thresholds": thresholds, "z_unit": unit.name}
    if points_out:
        result["points"] = Path(points_out)
    return result


class _PointWriter:
    """Cell-centre points of bands B0-B3 appended block by block to a GeoPackage layer, renamed into place at the end."""

    def __init__(self, path, crs, overwrite):
        self.path, self.crs, self.overwrite = Path(path), crs, overwrite
        self.layer = self.path.stem
        self._ctx = None
        self.count = 0

    def __enter__(self):
        self._ctx = atomic_path(self.path, overwrite=self.overwrite, keep_suffix=True, verify=verify_gpkg)
        self.gpkg = self.tmp = self._ctx.__enter__()
        return self

    def add(self, codes, h, transform):
        import geopandas as gpd
        import pyogrio

        from ..lidar.bands import BAND_NAMES

        rows, cols = np.nonzero(codes <= 3)
        xs, ys = transform * (cols + 0.5, rows + 0.5)
        gdf = gpd.GeoDataFrame({"band": np.asarray(BAND_NAMES)[codes[rows, cols]], "grid_code": h[rows, cols]},
                               geometry=shapely.points(xs, ys), crs=self.crs)
        pyogrio.write_dataframe(gdf, self.gpkg, layer=self.layer, driver="GPKG", append=self.count > 0)
        self.count += len(gdf)

    def __exit__(self, *exc):
        try:
            if exc[0] is None and self.count == 0:
                import geopandas as gpd

                gpd.GeoDataFrame({"band": [], "grid_code": []}, geometry=[], crs=self.crs).to_file(
                    self.gpkg, layer=self.layer, driver="GPKG")
        except BaseException:
            self._ctx.__exit__(*sys.exc_info())
            raise
        return self._ctx.__exit__(*exc)


def breakline_polygons(*, roads=None, hydro=None, waterbodies=None, tile_index=None, tile_field: str = "TILE_ID",
                       road_out=None, water_out=None, crs=None, reproject: bool = False, snap: str | float = "0.2ft",
                       max_road_width: str | float = "60ft", max_hydro_width: str | float = "500ft",
                       single_line_width: str | float = "8ft", overwrite: bool = True,
                       progress: ProgressCallback | None = None) -> dict:
    """Road and water polygons from breaklines (S6-S7): split by each tile footprint, noded, polygonised.

    Layers are paths or ``file.gpkg:LAYER``; all must share one CRS (``crs``, else the first
    layer's) unless ``reproject``. Without a tile index the lines' extent is one frame.
    Writes one polygon per tile and kind, with the tile number in ``tile_field``
    (GeoPackages ``road_out`` / ``water_out``). Returns {"road": path, "water": path, "crs": wkt}.
    """
    check_length(snap, "snap", allow_equal=True, example="0.2ft")
    for value, name in ((max_road_width, "max road width"), (max_hydro_width, "max hydro width"),
                        (single_line_width, "single-line hydro width")):
        check_length(value, name, example="60ft")
    layers = {"roads": roads, "hydro": hydro, "waterbodies": waterbodies, "tile index": tile_index}
    loaded, target = _breakline_layers(layers, crs, reproject)
    unit = horizontal_unit(target)
    length = lambda v, n: length_to_crs_units(v, unit, name=n)  # noqa: E731
    p = dict(snap=length(snap, "snap"), max_road=length(max_road_width, "max road width"),
             max_hydro=length(max_hydro_width, "max hydro width"), single=length(single_line_width, "single-line hydro width"))
    geoms = {k: [g for g in gdf.geometry if g is not None and not g.is_empty] for k, gdf in loaded.items()}
    frames = _breakline_frames(loaded, geoms, tile_field, tile_index, p["snap"])
    trees = {k: shapely.STRtree(v) for k, v in geoms.items()}

    def near(kind, frame):
        return [geoms[kind][i] for i in trees[kind].query(frame)] if kind in trees else []

    rows = {"road": [], "water": []}
    for i, (tile, frame) in enumerate(frames):
        report(progress, i / max(len(frames), 1), f"breaklines: tile {tile} ({i + 1} of {len(frames)})")
        road = road_polygons(near("roads", frame), frame, snap=p["snap"], max_width=p["max_road"])
        water = water_polygons(near("hydro", frame), near("waterbodies", frame), frame, snap=p["snap"],
                               max_width=p["max_hydro"], single_line_width=p["single"])
        for kind, geom in (("road", road), ("water", water)):
            if not geom.is_empty:
                rows[kind].append({tile_field: tile, "geometry": geom})
    report(progress, 1.0, "breaklines: writing")
    result = {"crs": target.to_wkt()}
    for kind, path in (("road", road_out), ("water", water_out)):
        if path is not None:
            result[kind], result[f"{kind}_count"] = _write_kind(rows[kind], path, target, tile_field, overwrite)
    return result


def _breakline_layers(layers: dict, crs, reproject) -> tuple[dict, pyproj.CRS]:
    """The given layers, checked for geometry type and read in one CRS: the tile index's (the tiles' grid),
    else ``crs``, else the first layer's."""
    kinds = {"roads": ("line",), "hydro": ("line",), "waterbodies": ("polygon",), "tile index": ("polygon",)}
    loaded = {k: read_layer(v, kinds[k], k) for k, v in layers.items() if v}
    if not loaded:
        raise InputError("no breakline layer given", hint="Give road lines and/or hydro lines or water bodies")
    first = "tile index" if "tile index" in loaded else next(iter(loaded))
    target = pyproj.CRS.from_user_input(crs) if crs else pyproj.CRS.from_user_input(loaded[first].crs)
    against = "the given" if crs else f"the {first} layer's ({layers[first]})"
    return {k: check_crs(g, target, str(layers[k]), reproject=reproject, against=against) for k, g in loaded.items()}, target


def _breakline_frames(loaded: dict, geoms: dict, tile_field: str, tile_index, snap: float) -> list:
    """(tile, footprint) of each tile of the index, or one frame around every line."""
    if "tile index" not in loaded:
        every = [g for k in ("roads", "hydro", "waterbodies") for g in geoms.get(k, [])]
        return [("all", shapely.box(*shapely.total_bounds(every)).buffer(snap * 10, join_style="mitre"))]
    idx = loaded["tile index"]
    if tile_field not in idx.columns:
        raise InputError(f"the tile index has no field {tile_field!r} (fields: {', '.join(map(str, idx.columns))})",
                         path=str(tile_index), hint="Name the tile-number field")
    return [(str(t), g) for t, g in zip(idx[tile_field], idx.geometry) if g is not None and not g.is_empty]


def _write_kind(rows: list, path, crs, tile_field: str, overwrite: bool):
    import geopandas as gpd

    gdf = gpd.GeoDataFrame(rows, geometry="geometry", crs=crs) if rows else \
        gpd.GeoDataFrame({tile_field: []}, geometry=gpd.GeoSeries([], crs=crs), crs=crs)
    gdf["area"] = gdf.geometry.area
    return write_layer(gdf, path, Path(path).stem, overwrite=overwrite), len(gdf)


def _polygons(spec, crs, reproject, against):
    if not spec:
        return None, []
    gdf = check_crs(read_layer(spec, ("polygon",), "polygon layer"), crs, str(spec), reproject=reproject, against=against)
    geoms = [g for g in gdf.geometry if g is not None and not g.is_empty]
    return shapely.STRtree(geoms), geoms


def clip_bands(bands, out, *, road_polygons=None, water_polygons=None, wetlands=None, wetland_out=None,
               reproject: bool = False, overwrite: bool = True, block: int = BLOCK,
               progress: ProgressCallback | None = None) -> dict:
    """Vegetation = band minus road minus water (S8), and vegetation inside wetlands (S9), by cell centre.

    ``road_polygons`` / ``water_polygons``: polygon layers (``breakline_polygons`` output);
    ``wetlands``: wetland polygons. Codes: 0 none, 1-3 band, 4 road, 5 water, 255 nodata.
    Returns {"veg": path, "wetveg": path?}.
    """
    _check_outputs({"out": out, "wet": wetland_out}, [bands])
    with _open(bands, "band") as src:
        crs = _crs(src, bands)
        layers = {k: _polygons(v, crs, reproject, f"the band raster's ({bands})") for k, v in
                  (("road", road_polygons), ("water", water_polygons), ("wetland", wetlands))}

        def mask(kind, win):
            tree, geoms = layers[kind]
            shape = (int(win.height), int(win.width))
            if tree is None:
                return np.zeros(shape, bool)
            west, north = src.transform * (win.col_off, win.row_off)
            east, south = src.transform * (win.col_off + win.width, win.row_off + win.height)
            hits = [geoms[i] for i in tree.query(shapely.box(west, south, east, north))]
            if not hits:
                return np.zeros(shape, bool)
            return rasterize(hits, out_shape=shape, transform=src.window_transform(win), fill=0, default_value=1,
                             all_touched=False, dtype="uint8").astype(bool)

        def compute(win):
            b = _read(src, src, win)
            veg, wetveg = vegetation(b, mask("road", win), mask("water", win), mask("wetland", win))
            return {"veg": veg, "wetveg": wetveg}

        outputs = {"veg": (out, "uint8", VEG_NODATA, {"GISTOOLS_PRODUCT": "veg"}),
                   "wetveg": (wetland_out, "uint8", VEG_NODATA, {"GISTOOLS_PRODUCT": "wetveg"})}
        return _blockwise(src, outputs, compute, progress=progress, label="clip", overwrite=overwrite, block=block)


def density_from_vegetation(veg, out, *, density_out=None, radius: str | float = "25ft", density_bands=(1, 2, 3),
                            overwrite: bool = True, block: int = BLOCK, progress: ProgressCallback | None = None) -> dict:
    """Cover (0-1) and point density of vegetation cells over a circle of ``radius`` (S10).

    ``density_bands``: the bands (1-3) whose vegetation counts. density is in cells per CRS
    area unit. Blocks read a halo of the radius, so block edges do not show.
    Returns {"cover": path, "density": path?, "radius": radius in CRS units}.
    """
    check_length(radius, "density radius", example="25ft")
    _check_outputs({"out": out, "density": density_out}, [veg])
    if not density_bands or any(b not in (1, 2, 3) for b in density_bands):
        raise InputError(f"density bands {tuple(density_bands)} must be among 1, 2, 3", hint="e.g. 1,2,3")
    with _open(veg, "vegetation") as src:
        unit = horizontal_unit(_crs(src, veg))
        r = length_to_crs_units(radius, unit, name="density radius")
        cs = src.transform.a
        halo = halo_cells(r, cs)

        def compute(win):
            big = _read(src, src, win, halo=halo, fill=0)
            density, cover = vegetation_cover(big, cs, r, tuple(density_bands), halo)
            return {"cover": cover, "density": density}

        outputs = {"cover": (out, "float32", NODATA, {"GISTOOLS_PRODUCT": "cover"}),
                   "density": (density_out, "float32", NODATA, {"GISTOOLS_PRODUCT": "density"})}
        paths = _blockwise(src, outputs, compute, progress=progress, label="density", overwrite=overwrite, block=block)
    return {**paths, "radius": r}


def _sample_breaks(src, method: str, block: int) -> tuple[float, float]:
    """Quantile / Jenks breaks of a cover raster (a tile, a mosaic) on the sample lattice, read block by block:
    the cells and breaks the chain gets per tile (lidar.shrub.lattice_sample)."""
    step = sample_step(src.width * src.height)
    cs = src.transform.a
    keys, values = [], []
    for win in _windows(src.width, src.height, block):
        t = src.window_transform(win)
        k, v = lattice_sample(_read(src, src, win), int(round(t.c / cs)), int(round(t.f / cs)), step)
        keys.append(k)
        values.append(v)
    return breaks_from_sample(keys, values, method)


def classes_from_cover(cover, out, *, veg=None, polygons_out=None, method: str = "breaks", breaks=DEFAULT_BREAKS,
                       overwrite: bool = True, block: int = BLOCK, progress: ProgressCallback | None = None) -> dict:
    """Shrub classes (S11): 0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water, 255 nodata, from cover.

    ``method``: "breaks" (``breaks`` on cover fraction), "quantile" or "jenks" (from a sample of
    the cover). ``veg`` (the clip output) marks road and water. ``polygons_out``: the classes
    as polygons, one feature per class and block, with area. Returns {"classes": path,
    "polygons": path?, "breaks": (b1, b2), "class_area": {name: CRS area units}}.
    """
    if method not in ("breaks", "quantile", "jenks"):
        raise InputError(f"classification {method!r} is not one of breaks, quantile, jenks")
    if method == "breaks":
        check_breaks(breaks, "class breaks", count=2, low=0, high=1, example="0.3,0.7")
    _check_outputs({"out": out, "polygons": polygons_out}, [cover, veg])
    with contextlib.ExitStack() as stack:
        src = stack.enter_context(_open(cover, "cover"))
        vsrc = stack.enter_context(_open(veg, "vegetation")) if veg else None
        if vsrc is not None:
            _same_grid(src, cover, vsrc, veg)
        use = tuple(breaks) if method == "breaks" else _sample_breaks(src, method, block)
        area = {name: 0.0 for name in CLASS_NAMES.values()}
        cell_area = src.transform.a ** 2
        polys = []

        def compute(win):
            c = _read(src, src, win)
            v = _read(vsrc, src, win, fill=VEG_NODATA) if vsrc is not None else None
            codes = shrub_classes(c, use, road=None if v is None else v == VEG_ROAD,
                                  water=None if v is None else v == VEG_WATER, nodata=np.isnan(c))
            for code, name in CLASS_NAMES.items():
                area[name] += float(np.count_nonzero(codes == code) * cell_area)
            if polygons_out:
                regions = class_polygons(codes, src.window_transform(win), mask=(codes >= 1) & (codes <= 5))
                polys.extend(regions.items())
            return {"classes": codes}

        tags = {"GISTOOLS_PRODUCT": "classes", "GISTOOLS_CLASSES": json.dumps(CLASS_NAMES),
                "GISTOOLS_CLASS_BREAKS": json.dumps(list(use))}
        paths = _blockwise(src, {"classes": (out, "uint8", CLASS_NODATA, tags)}, compute, progress=progress,
                           label="classes", overwrite=overwrite, block=block)
        crs = _crs(src, cover)
    result = {"classes": paths["classes"], "breaks": use, "class_area": area}
    if polygons_out:
        import geopandas as gpd

        gdf = gpd.GeoDataFrame({"class_code": [c for c, _ in polys], "class": [CLASS_NAMES[c] for c, _ in polys]},
                               geometry=[g for _, g in polys], crs=crs)
        gdf["area"] = gdf.geometry.area
        result["polygons"] = write_layer(gdf, polygons_out, Path(polygons_out).stem, overwrite=overwrite)
    return result
