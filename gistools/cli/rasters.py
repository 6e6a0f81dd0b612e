"""``gistools rasters``: DSM, DEM and nDSM GeoTIFFs for a folder of tiles."""

from __future__ import annotations

from .options import finish_batch, run_batch, tiles_command, tiles_counted


@tiles_command("rasters")
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
    from ..products.rasters import RasterSettings, rasters_from_tiles

    settings = RasterSettings(cell_size=cell_size, dem_method=dem_method, dsm_classes=dsm_classes,
                              dem_max_distance=dem_max_distance, buffer=buffer, crs=crs, chunk_size=chunk_size,
                              classify_ground=classify_ground, dem_fill=dem_fill, dsm_fill=dsm_fill,
                              subcircle=subcircle, hydro_flatten=hydro_flatten, shore_width=shore_width,
                              products=products)
    summary = run_batch(quiet, rasters_from_tiles, inputs, out, settings, jobs=jobs, overwrite=overwrite,
                        scheduler=scheduler)
    cell = f"cell size {summary['cell_size']:.6g} {summary['horizontal_unit']}; " if summary["cell_size"] is not None else ""
    finish_batch(summary, f"{tiles_counted(summary, 'ok')}; {cell}report: {out}/report.json")
