"""``gistools terrain`` (slope, aspect, hillshade, ruggedness of a DEM) and ``gistools viewshed``."""

from __future__ import annotations

import click

from ..parameters import PARAMETERS
from .options import out_opt, progress_bar
from .spec import spec_options


@click.command()
@click.argument("dem", type=click.Path(exists=True))
@out_opt("Output folder (slope.tif, aspect.tif, ... and report.json).")
@spec_options("terrain")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def terrain(dem, out, terrain_products, azimuth, altitude, dem_z_unit, overwrite, quiet):
    """Slope (degrees, percent), aspect, hillshade and ruggedness (Riley's TRI) of DEM, as gdaldem computes them
    (Horn's method): DEM is a raster (GeoTIFF, or a VRT mosaic of tiles) or a folder written by gistools rasters
    (its dem.vrt). The mosaic is read block by block with a one-cell halo, so tiles join without seams. Elevations
    in another unit than x and y are scaled (gdaldem -s).

    \b
    Examples:
      $ gistools terrain out/dem.vrt --out out/terrain
      $ gistools terrain out --out terrain --products slope,hillshade --azimuth 270
    """
    from ..products.terrain import terrain_from_dem

    with progress_bar(quiet) as progress:
        report = terrain_from_dem(dem, out, products=terrain_products, azimuth=azimuth, altitude=altitude,
                                  z_unit=dem_z_unit, overwrite=overwrite, progress=progress)
    u = report["units"]
    kept = report.get("kept") or []
    made = [p for p in report["outputs"] if p not in kept]
    done = (f"{', '.join(made)} written" if made else "") + ("; " if made and kept else "") + \
        (f"{', '.join(kept)} kept (made before with these settings; --overwrite remakes them)" if kept else "")
    click.echo(f"{done} ({report['cells'][0]} x {report['cells'][1]} cells; x, y in "
               f"{u['horizontal']}, z in {u['vertical']}, scale {u['scale']:.6g}); report: {out}/report.json")
    for w in report.get("warnings", []):
        click.echo(f"warning: {w}", err=True)


@click.command()
@click.argument("surface", type=click.Path(exists=True))
@out_opt("Output folder (viewshed.tif, viewshed_count.tif, report.json).")
@spec_options("viewshed", skip=("observer",))
@click.option("--from", "observer", multiple=True, metavar="X,Y",
              help=PARAMETERS["observer"].help_text("cli"))
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def viewshed(surface, out, observer, observers, observer_height, target_height, hiding_surface, max_distance,
             curvature, curvature_coefficient, dem_z_unit, overwrite, quiet):
    """Cells seen from one or several observers, as gdal_viewshed: SURFACE is a raster (GeoTIFF or VRT mosaic) or a
    folder written by gistools rasters (its dsm.vrt: trees and buildings hide; --surface dem: bare ground). Writes
    OUT/viewshed.tif (1 seen by at least one observer, 0 hidden, 255 nodata) and OUT/viewshed_count.tif (how many
    observers see each cell).

    \b
    Examples:
      $ gistools viewshed out --out out/viewshed --from 565300,654400 --height 6ft
      $ gistools viewshed out/dsm.vrt --out seen --from 565300,654400 --from 566100,655000 --curvature
    """
    from ..products.viewshed import viewshed_from_surface

    with progress_bar(quiet) as progress:
        report = viewshed_from_surface(surface, out, observers=list(observer), observers_layer=observers,
                                       observer_height=observer_height, target_height=target_height,
                                       surface_kind=hiding_surface, max_distance=max_distance, curvature=curvature,
                                       curvature_coefficient=curvature_coefficient, z_unit=dem_z_unit,
                                       overwrite=overwrite, progress=progress)
    click.echo(f"{len(report['observers'])} observer(s); {report['cells_seen']:,} cells seen "
               f"({report['area_seen']:,.0f} {report['area_unit']}); outputs: {', '.join(report['outputs'].values())}; "
               f"report: {out}/report.json")
    for w in report.get("warnings", []):
        click.echo(f"warning: {w}", err=True)
