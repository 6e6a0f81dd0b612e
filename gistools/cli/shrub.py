"""``gistools shrub``: the whole shrub chain, tiles and breaklines to a shrub density map."""

from __future__ import annotations

import click

from ..lidar.bands import PRESETS
from ..lidar.shrub import CLASS_METHODS
from ..lidar.dsmfill import DSM_FILLS
from ..tasks.rasters import RasterSettings
from ..tasks.shrub import ShrubSettings, shrub_from_tiles
from .deliver import basemap_opt
from .options import (batch_report, chunk_opt, classify_ground_opt, crs_opt, dem_options, jobs_opt, overwrite_opt, parse_classes,
                      progress_bar)


def _floats(ctx, param, value):
    if value is None:
        return None
    try:
        return tuple(float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a comma-separated list of numbers") from None


_S = ShrubSettings()  # the defaults are the library's, not copies


def _options(opts):
    def apply(fn):
        for opt in reversed(opts):
            fn = opt(fn)
        return fn

    return apply


# the breakline layers (clip step)
_vector_options = _options([
    click.option("--roads", help="Edge-of-pavement lines (file.gpkg:LAYER or a shapefile)."),
    click.option("--hydro", help="Hydrographic breaklines: dual-line banks and single-line features."),
    click.option("--waterbodies", help="Water body polygons (islands as holes)."),
    click.option("--wetlands", help="Wetland polygons: vegetation inside them is written apart (wetveg/)."),
    click.option("--tile-index", help="Tile footprints (FOOTPRINT) that split the breaklines, as the dissertation did."),
    click.option("--tile-field", default=_S.tile_field, show_default=True, help="Tile-number field of --tile-index."),
    click.option("--reproject-vectors", is_flag=True, help="Reproject vector layers to the points' CRS instead of refusing."),
])

# the parameters of the steps after the rasters
_step_parameters = _options([
    click.option("--bands", "band_preset", type=click.Choice(list(PRESETS)), default=_S.bands, show_default=True,
                 help="Height bands: exact 1 / 2 / 6 m, or the dissertation's printed 3.28 / 6.56 / 19.658 ft."),
    click.option("--band-breaks", callback=_floats, default=None, help="Three band limits in metres, e.g. 1,2,6."),
    click.option("--noise-floor", default=_S.noise_floor, show_default=True, help="Heights up to this are bare ground (B0)."),
    click.option("--radius", default=_S.radius, show_default=True, help="Density neighbourhood radius."),
    click.option("--density-bands", callback=parse_classes, default=",".join(map(str, _S.density_bands)), show_default=True,
                 help="Bands whose vegetation is counted; 1 is the dissertation's choice."),
    click.option("--classify", type=click.Choice(CLASS_METHODS), default=_S.classify, show_default=True,
                 help="breaks: --breaks on cover; quantile / jenks: breaks from the data."),
    click.option("--breaks", "class_breaks", callback=_floats, default=",".join(f"{b:g}" for b in _S.class_breaks),
                 show_default=True, help="Cover fraction breaks light/medium and medium/heavy."),
    click.option("--max-road-width", default=_S.max_road_width, show_default=True,
                 help="Wider faces between road lines are blocks, not road."),
    click.option("--snap", default=_S.snap, show_default=True, help="Breakline snapping tolerance."),
    click.option("--no-map", is_flag=True, help="Skip the PNG / PDF map."),
])


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@_vector_options
@click.option("--cell-size", default=_S.raster.cell_size, show_default=True, help="Cell size with its unit.")
@click.option("--dsm-classes", callback=parse_classes, default=None, help="Classes in the DSM, e.g. 1,2. Default: all but 7, 18.")
@dem_options(_S.raster)
@click.option("--dsm-fill", type=click.Choice(DSM_FILLS), default=_S.raster.dsm_fill, show_default=True,
              help="DSM cells without a first return: nearest (the nearest return's height, up to 3 cells), tin (a TIN "
                   "of the cells' highest returns across holes up to 3 cells), subcircle (lidR's p2r(subcircle), half "
                   "a cell) or none (the dissertation's; filling raises the cover of sparse data: README).")
@classify_ground_opt
@_step_parameters
@click.option("--web-map", is_flag=True, help="Also write OUT/shrub_map.html, the offline web map (gistools webmap).")
@basemap_opt
@click.option("--band-points", is_flag=True, help="Also write cell-centre points per band with their height (band_points/).")
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler (tcp://host:8786) or 'local'.")
@crs_opt
@jobs_opt
@chunk_opt
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def shrub(inputs, out, roads, hydro, waterbodies, wetlands, tile_index, tile_field, reproject_vectors, cell_size, dem_method,
          dsm_fill,
          dsm_classes, dem_max_distance, classify_ground, band_preset, band_breaks, noise_floor, radius, density_bands, classify, class_breaks,
          max_road_width, snap, no_map, web_map, basemap, band_points, scheduler, crs, jobs, chunk_size, overwrite, quiet):
    """Shrub density map of LAS/LAZ tiles: DSM/DEM/nDSM, height bands, road and water clipping,
    vegetation density, light / medium / heavy classes, polygons and a printable map.

    \b
    Examples:
      $ gistools shrub sample_tiles --out out \\
          --roads sample_tiles/breaklines.gpkg:ROADBREAKLINE --hydro sample_tiles/breaklines.gpkg:HYDROGRAPHICFEATURE \\
          --waterbodies sample_tiles/breaklines.gpkg:WATERBODY --wetlands sample_tiles/breaklines.gpkg:WETLAND \\
          --tile-index sample_tiles/breaklines.gpkg:FOOTPRINT
      $ gistools shrub tiles --out out --roads roads.shp --hydro hydro.shp --density-bands 1 --bands text_literal
    """
    settings = ShrubSettings(
        raster=RasterSettings(cell_size=cell_size, dem_method=dem_method, dsm_classes=dsm_classes,
                              dem_max_distance=dem_max_distance, crs=crs, chunk_size=chunk_size,
                              classify_ground=classify_ground, dsm_fill=dsm_fill),
        bands=band_preset, band_breaks_m=band_breaks, noise_floor=noise_floor, radius=radius,
        density_bands=tuple(density_bands), classify=classify, class_breaks=tuple(class_breaks),
        max_road_width=max_road_width, snap=snap, tile_field=tile_field,
    )
    if web_map:
        from ..tasks.webmap import check_options

        check_options(basemap)
    elif basemap:
        raise click.UsageError("--basemap is for --web-map")
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: shrub_from_tiles(
            inputs, out, settings, roads=roads, hydro=hydro, waterbodies=waterbodies, wetlands=wetlands,
            tile_index=tile_index, reproject_vectors=reproject_vectors, jobs=jobs, scheduler=scheduler,
            overwrite=overwrite, make_map=not no_map, band_points=band_points, progress=progress))
    counts = report.get("counts", {})
    unit = report.get("area_unit", "")
    click.echo(f"{counts.get('ok', 0)} tiles ok, {counts.get('failed', 0)} failed; report: {out}/report.json")
    if "class_area" in report:
        click.echo("class area (" + unit + "): " + ", ".join(f"{k} {v:,.0f}" for k, v in report["class_area"].items()))
        click.echo(_breaks_line(report))
    if web_map and "class_area" in report:
        from ..tasks.webmap import web_map as write_web_map

        page = write_web_map(out, basemap=basemap)
        click.echo(f"web map: {page['html']} ({page['bytes'] / 1e6:.1f} MB)")
    for tile in report.get("tiles", []):
        if tile.get("status") == "failed":
            click.echo(f"  FAILED {tile['error']}", err=True)
    if counts.get("failed"):
        raise SystemExit(1)


def _breaks_line(report: dict) -> str:
    """The cover breaks the classes used, and how they were chosen (given, quantile or Jenks)."""
    b1, b2 = report["class_breaks"]
    how = {"breaks": "given", "quantile": "quantile, from the data", "jenks": "Jenks, from the data"}.get(
        report.get("class_method", "breaks"), report.get("class_method"))
    return (f"class breaks ({how}): none 0 < light <= {b1:.3f} < medium <= {b2:.3f} < heavy, on the cover fraction "
            f"within {report['density_radius']:g} {report.get('horizontal_unit', 'CRS units')}")


_RECORDED = "Default: as the earlier run (OUT/report.json)."


def _step_command(stage, *own):
    """A one-step command: OUT, the options of its own step (each defaulting to what the earlier run recorded), the
    map, the pool and progress options. The steps after it are redone with the settings they were made with."""
    def wrap(fn):
        fn = _options([*own, click.option("--no-map", is_flag=True, help="Skip the PNG / PDF map."),
                       click.option("--scheduler", default=None, metavar="ADDRESS",
                                    help="Dask scheduler (tcp://host:8786) or 'local' (for runs past one machine)."),
                       jobs_opt, click.option("--quiet", "-q", is_flag=True, help="No progress bar.")])(fn)
        return click.argument("out", type=click.Path(exists=True, file_okay=False))(fn)
    return wrap


_bands_own = [
    click.option("--bands", "bands", type=click.Choice(list(PRESETS)), default=None,
                 help="Height bands: exact 1 / 2 / 6 m, or the dissertation's printed 3.28 / 6.56 / 19.658 ft. " + _RECORDED),
    click.option("--band-breaks", "band_breaks_m", callback=_floats, default=None,
                 help="Three band limits in metres, e.g. 1,2,6. " + _RECORDED),
    click.option("--noise-floor", default=None, help="Heights up to this are bare ground (B0), e.g. 0.1m. " + _RECORDED),
]
_clip_own = [
    click.option("--roads", help="Edge-of-pavement lines (file.gpkg:LAYER or a shapefile). " + _RECORDED),
    click.option("--hydro", help="Hydrographic breaklines: dual-line banks and single-line features. " + _RECORDED),
    click.option("--waterbodies", help="Water body polygons (islands as holes). " + _RECORDED),
    click.option("--wetlands", help="Wetland polygons: vegetation inside them is written apart (wetveg/). " + _RECORDED),
    click.option("--tile-index", help="Tile footprints (FOOTPRINT) that split the breaklines. " + _RECORDED),
    click.option("--tile-field", default=None, help="Tile-number field of --tile-index. " + _RECORDED),
    click.option("--reproject-vectors", is_flag=True, default=None,
                 help="Reproject vector layers to the points' CRS instead of refusing."),
    click.option("--max-road-width", default=None, help="Wider faces between road lines are blocks, not road, e.g. 60ft. "
                 + _RECORDED),
    click.option("--snap", default=None, help="Breakline snapping tolerance, e.g. 0.2ft. " + _RECORDED),
]
_density_own = [
    click.option("--radius", default=None, help="Density neighbourhood radius, e.g. 25ft. " + _RECORDED),
    click.option("--density-bands", callback=parse_classes, default=None,
                 help="Bands whose vegetation is counted, e.g. 1,2,3 (1 is the dissertation's choice). " + _RECORDED),
]
_classes_own = [
    click.option("--classify", type=click.Choice(CLASS_METHODS), default=None,
                 help="breaks: --breaks on cover; quantile / jenks: breaks from the data. " + _RECORDED),
    click.option("--breaks", "class_breaks", callback=_floats, default=None,
                 help="Cover fractions (0-1) between light / medium and medium / heavy, e.g. 0.3,0.7. " + _RECORDED),
]


def _run_step(stage, out, no_map, scheduler, jobs, quiet, **given):
    """Rerun ``stage`` (and the steps after it) on ``out`` with the given options changed."""
    from ..tasks.shrub import step_settings

    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in given.items() if v is not None and v is not False}
    settings, layers = step_settings(out, stage, **changes)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: shrub_from_tiles(None, out, settings, **layers, jobs=jobs, scheduler=scheduler,
                                                       make_map=not no_map, from_stage=stage, progress=progress))
    if not report.get("rolled_back"):
        click.echo(f"{stage} and the steps after it rerun on {out}; class area ({report['area_unit']}): "
                   + ", ".join(f"{k} {v:,.0f}" for k, v in report["class_area"].items()))
        click.echo(_breaks_line(report))
    for tile in report.get("tiles", []):
        if tile.get("status") == "failed":
            click.echo(f"  FAILED {tile['error']}", err=True)
    if report.get("rolled_back"):
        click.echo(f"gistools: error: {stage} failed on {report['counts']['failed']} tile(s); {out} was put back as it "
                   "was before this rerun. Fix the tiles named above and run the step again", err=True)
    if report["counts"].get("failed"):
        raise SystemExit(1)


@click.command()
@_step_command("bands", *_bands_own)
def bands(**kw):
    """Rerun the height bands (and the steps after them, with their recorded settings) on OUT, an output folder of
    gistools shrub.

    \b
    Example:
      $ gistools bands out --bands text_literal --noise-floor 0.05m
    """
    _run_step("bands", **kw)


@click.command()
@_step_command("clip", *_clip_own)
def clip(**kw):
    """Rerun road / water clipping and vegetation selection (and the steps after, with their recorded settings) on OUT.

    \b
    Example:
      $ gistools clip out --roads roads.gpkg:ROADBREAKLINE --hydro roads.gpkg:HYDROGRAPHICFEATURE --max-road-width 40ft
    """
    _run_step("clip", **kw)


@click.command()
@_step_command("density", *_density_own)
def density(**kw):
    """Rerun the point density and cover (and the classes, with their recorded settings) on OUT.

    \b
    Example:
      $ gistools density out --radius 50ft --density-bands 1
    """
    _run_step("density", **kw)


@click.command()
@_step_command("classes", *_classes_own)
def classify(**kw):
    """Rerun the light / medium / heavy classes (polygons, map, report) on OUT.

    \b
    Example:
      $ gistools classify out --classify jenks
    """
    _run_step("classes", **kw)


@click.command(name="map")
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@click.option("--title", default=None, help="Map title (default: the title the chain gave it, from OUT/report.json).")
def map_(out, title):
    """Draw the printable shrub map (PNG and PDF) of OUT/classes.vrt.

    \b
    Example:
      $ gistools map out --title "Levy County shrub density"
    """
    from ..tasks.shrub import map_from_classes

    result = map_from_classes(out, title=title)
    click.echo("wrote " + ", ".join(str(p) for p in result["paths"]))

