"""``gistools shrub``: the whole shrub chain, tiles and breaklines to a shrub density map."""

from __future__ import annotations

import click
from click.core import ParameterSource

from ..parameters import COMMANDS, option, render
from .options import batch_report, progress_bar, tiles_command
from .spec import spec_options

_RECORDED = "Default: as the earlier run (OUT/report.json)."


def _spec(command, *, recorded=(), skip=()):
    """The command's options from their declarations (gistools.parameters.shrub, cli/spec.py). ``recorded``: the
    options that default to what the earlier run recorded (a step rerun changes only those given: _run_step)."""
    def apply(fn):
        fn = spec_options(command, skip=skip)(fn)
        names = [n for n in COMMANDS[command] if n not in skip]
        for opt in fn.__click_params__[-len(names):]:
            if opt.name in recorded:
                opt.show_default = False
                opt.help = f"{opt.help} {_RECORDED}"
        return fn

    return apply


@tiles_command("shrub", options=_spec)
def shrub(inputs, out, roads, hydro, waterbodies, wetlands, tile_index, tile_field, reproject_vectors, cell_size,
          dsm_classes, dem_method, dem_max_distance, dsm_fill, classify_ground, bands, band_breaks_m, noise_floor, radius,
          density_bands, classify, class_breaks, max_road_width, snap, make_map, web_map, basemap, band_points,
          scheduler, crs, jobs, chunk_size, overwrite, quiet):
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
    from ..products.rasters import RasterSettings
    from ..products.shrub import ShrubSettings, shrub_from_tiles

    settings = ShrubSettings(
        raster=RasterSettings(cell_size=cell_size, dem_method=dem_method, dsm_classes=dsm_classes,
                              dem_max_distance=dem_max_distance, crs=crs, chunk_size=chunk_size,
                              classify_ground=classify_ground, dsm_fill=dsm_fill),
        bands=bands, band_breaks_m=band_breaks_m, noise_floor=noise_floor, radius=radius,
        density_bands=density_bands, classify=classify, class_breaks=class_breaks,
        max_road_width=max_road_width, snap=snap, tile_field=tile_field,
    )
    if web_map:
        from ..deliver.webmap import check_options

        check_options(basemap)
    elif basemap:
        raise click.UsageError(render(f"{option('basemap')} is for {option('web_map')}", "cli"))
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: shrub_from_tiles(
            inputs, out, settings, roads=roads, hydro=hydro, waterbodies=waterbodies, wetlands=wetlands,
            tile_index=tile_index, reproject_vectors=reproject_vectors, jobs=jobs, scheduler=scheduler,
            overwrite=overwrite, make_map=make_map, band_points=band_points, progress=progress))
    counts = report.get("counts", {})
    unit = report.get("area_unit", "")
    click.echo(f"{counts.get('ok', 0)} tiles ok, {counts.get('failed', 0)} failed; report: {out}/report.json")
    _settings_line(report)
    if "class_area" in report:
        click.echo("class area (" + unit + "): " + ", ".join(f"{k} {v:,.0f}" for k, v in report["class_area"].items()))
        click.echo(_breaks_line(report))
    if web_map and "class_area" in report:
        from ..deliver.webmap import web_map as write_web_map

        page = write_web_map(out, basemap=basemap)
        click.echo(f"web map: {page['html']} ({page['bytes'] / 1e6:.1f} MB)")
    for tile in report.get("tiles", []):
        if tile.get("status") == "failed":
            click.echo(f"  FAILED {tile['error']}", err=True)
    if counts.get("failed"):
        raise SystemExit(1)


def _settings_line(report: dict) -> None:
    """The cell size and density radius the chain used, in the data's unit (the defaults follow it)."""
    if report.get("cell_size") is None or not report.get("horizontal_unit_m"):
        return
    from ..units import LinearUnit

    u = LinearUnit(report.get("horizontal_unit") or "", float(report["horizontal_unit_m"])).short
    click.echo(f"cell size {report['cell_size']:g} {u}, density radius {report.get('density_radius', 0):g} {u} "
               "(the defaults follow the data's unit: --help)")


def _breaks_line(report: dict) -> str:
    """The cover breaks the classes used, and how they were chosen (given, quantile or Jenks)."""
    b1, b2 = report["class_breaks"]
    how = {"breaks": "given", "quantile": "quantile, from the data", "jenks": "Jenks, from the data"}.get(
        report.get("class_method", "breaks"), report.get("class_method"))
    return (f"class breaks ({how}): none 0 < light <= {b1:.3f} < medium <= {b2:.3f} < heavy, on the cover fraction "
            f"within {report['density_radius']:g} {report.get('horizontal_unit', 'CRS units')}")


def _step_command(stage):
    """A one-step command: OUT, the options of its own step (each defaulting to what the earlier run recorded), the
    map, the pool and progress options. The steps after it are redone with the settings they were made with."""
    def wrap(fn):
        from ..parameters.shrub import STAGE_SETTINGS, STEP_COMMANDS

        fn = click.option("--quiet", "-q", is_flag=True, help="No progress bar.")(fn)
        fn = _spec(STEP_COMMANDS[stage], recorded=STAGE_SETTINGS[stage])(fn)
        return click.argument("out", type=click.Path(exists=True, file_okay=False))(fn)
    return wrap


def _run_step(stage, out, make_map, scheduler, jobs, quiet, **given):
    """Rerun ``stage`` (and the steps after it) on ``out`` with the options given on the command line changed (the
    others keep what the earlier run recorded)."""
    from ..products.shrub import shrub_from_tiles, step_settings

    ctx = click.get_current_context()
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in given.items()
               if ctx.get_parameter_source(k) not in (ParameterSource.DEFAULT, ParameterSource.DEFAULT_MAP)}
    settings, layers = step_settings(out, stage, **changes)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: shrub_from_tiles(None, out, settings, **layers, jobs=jobs, scheduler=scheduler,
                                                       make_map=make_map, from_stage=stage, progress=progress))
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
@_step_command("bands")
def bands(**kw):
    """Rerun the height bands (and the steps after them, with their recorded settings) on OUT, an output folder of
    gistools shrub.

    \b
    Example:
      $ gistools bands out --bands text_literal --noise-floor 0.05m
    """
    _run_step("bands", **kw)


@click.command()
@_step_command("clip")
def clip(**kw):
    """Rerun road / water clipping and vegetation selection (and the steps after, with their recorded settings) on OUT.

    \b
    Example:
      $ gistools clip out --roads roads.gpkg:ROADBREAKLINE --hydro roads.gpkg:HYDROGRAPHICFEATURE --max-road-width 40ft
    """
    _run_step("clip", **kw)


@click.command()
@_step_command("density")
def density(**kw):
    """Rerun the point density and cover (and the classes, with their recorded settings) on OUT.

    \b
    Example:
      $ gistools density out --radius 50ft --density-bands 1
    """
    _run_step("density", **kw)


@click.command()
@_step_command("classes")
def classify(**kw):
    """Rerun the light / medium / heavy classes (polygons, map, report) on OUT.

    \b
    Example:
      $ gistools classify out --classify jenks
    """
    _run_step("classes", **kw)


@click.command(name="map")
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@_spec("map")
def map_(out, title):
    """Draw the printable shrub map (PNG and PDF) of OUT/classes.vrt.

    \b
    Example:
      $ gistools map out --title "Levy County shrub density"
    """
    from ..products.shrub import map_from_classes

    result = map_from_classes(out, title=title)
    click.echo("wrote " + ", ".join(str(p) for p in result["paths"]))

