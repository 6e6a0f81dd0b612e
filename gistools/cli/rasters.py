"""``gistools rasters``: DSM, DEM and nDSM GeoTIFFs for a folder of tiles."""

from __future__ import annotations

import click

from ..lidar.dsmfill import DSM_FILLS
from ..lidar.gridding import DEM_FILLS
from ..tasks.rasters import RasterSettings, rasters_from_tiles
from .options import (finish_batch, batch_report, chunk_opt, classify_ground_opt, crs_opt, dem_options, jobs_opt, overwrite_opt, parse_classes,
                      progress_bar)


_DEFAULTS = RasterSettings()  # the options' defaults are the library's


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--cell-size", default=_DEFAULTS.cell_size, show_default=True, help="Cell size with its unit: 5ft, 1.5m, or a bare number in CRS units.")
@click.option("--dsm-classes", callback=parse_classes, default=None,
              help="Classes in the DSM (first returns), e.g. 1,2 as in the dissertation. Default: all but noise (7, 18).")
@dem_options(_DEFAULTS)
@click.option("--buffer", default=None, help="How far to read ground points from neighbouring tiles. Default: 2 x --dem-max-distance, at least 20 cells.")
@click.option("--products", default=",".join(_DEFAULTS.products), show_default=True, help="Which rasters to write, comma-separated.")
@classify_ground_opt
@click.option("--hydro-flatten", metavar="LAYER", default=None,
              help="Water polygons (file.gpkg:LAYER, e.g. the WATERBODY breaklines): the DEM cells inside each are set "
                   "to its lowest ground elevation along the shore, filled where empty; the nDSM follows.")
@click.option("--dem-fill", type=click.Choice(DEM_FILLS), default=_DEFAULTS.dem_fill, show_default=True,
              help="DEM voids (cells farther than --dem-max-distance from ground, e.g. under big buildings): tin (a TIN "
                   "across them), idw (the 8 nearest ground points) or none; water cells stay empty.")
@click.option("--dsm-fill", type=click.Choice(DSM_FILLS), default=_DEFAULTS.dsm_fill, show_default=True,
              help="DSM cells without a first return: tin (a TIN of the cells' highest returns across holes up to 3 "
                   "cells; never above them), subcircle (each return also on a circle of --subcircle, lidR's "
                   "p2r(subcircle)) or none.")
@click.option("--subcircle", default=None, help="--dsm-fill subcircle: the circle's radius. Default: half a cell.")
@click.option("--shore-width", default=None, help="--hydro-flatten: how far outside a water polygon its shore's ground "
              "points are taken. Default: 2 cells.")
@crs_opt
@jobs_opt
@chunk_opt
@overwrite_opt
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the tiles on a Dask cluster: its scheduler address (tcp://host:8786), or 'local' for a "
                   "LocalCluster of --jobs workers. Workers must see the tiles and --out at the same paths.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def rasters(inputs, out, cell_size, dem_method, dsm_classes, dem_max_distance, buffer, products, classify_ground,
            dem_fill, dsm_fill, subcircle, hydro_flatten, shore_width, crs, jobs, chunk_size, overwrite, scheduler, quiet):
    """DSM, DEM and nDSM GeoTIFFs for every tile of INPUTS (files, folders or globs).

    Writes OUT/dsm/<tile>.tif, OUT/dem/<tile>.tif, OUT/ndsm/<tile>.tif, VRT mosaics
    OUT/dsm.vrt ... and OUT/report.json. Cells near tile edges use points of the
    neighbouring tiles, so the mosaic is seamless. A bad tile is reported and the
    rest completes; the exit status is then 1.

    \b
    Examples:
      $ gistools rasters sample_tiles --out out
      $ gistools rasters 'tiles/*.laz' --out out --cell-size 1m --jobs 2
      $ gistools rasters tiles --out out --dem-method max --dsm-classes 1,2
      $ gistools rasters tiles --out out --hydro-flatten breaklines.gpkg:WATERBODY
      $ gistools rasters /shared/tiles --out /shared/out --scheduler tcp://scheduler:8786
    """
    settings = RasterSettings(cell_size=cell_size, dem_method=dem_method, dsm_classes=dsm_classes,
                              dem_max_distance=dem_max_distance, buffer=buffer, crs=crs, chunk_size=chunk_size,
                              classify_ground=classify_ground, dem_fill=dem_fill, dsm_fill=dsm_fill,
                              subcircle=subcircle, hydro_flatten=hydro_flatten, shore_width=shore_width,
                              products=tuple(p.strip() for p in products.split(",") if p.strip()))
    with progress_bar(quiet) as progress:
        summary = batch_report(lambda: rasters_from_tiles(inputs, out, settings, jobs=jobs, overwrite=overwrite,
                                                          scheduler=scheduler, progress=progress))
    counts = summary["counts"]
    cell = f"cell size {summary['cell_size']:.6g} {summary['horizontal_unit']}; " if summary["cell_size"] is not None else ""
    finish_batch(summary, f"{counts['ok']} tiles ok, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"{cell}report: {out}/report.json")
