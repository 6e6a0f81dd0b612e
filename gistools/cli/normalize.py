"""``gistools normalize``: heights above ground of LAS/LAZ tiles, and vegetation classes from them."""

from __future__ import annotations

import click

from ..lidar.bands import PRESETS
from ..tasks.ground import FORMATS
from ..tasks.normalize import NormalizeSettings, normalize_from_tiles
from .options import finish_batch, batch_report, crs_opt, jobs_opt, overwrite_opt, progress_bar

_D = NormalizeSettings()


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--replace-z", is_flag=True, help="Write the heights above ground as z (no extra dimension).")
@click.option("--classify-vegetation", is_flag=True,
              help="Unclassified points (0, 1) become low / medium / high vegetation (3 / 4 / 5) by the height bands; "
                   "with breaklines, surface points in roads road surface (11), in water water (9).")
@click.option("--bands", type=click.Choice(list(PRESETS)), default=_D.bands, show_default=True,
              help="Height bands for --classify-vegetation: exact 1 / 2 / 6 m; low vegetation up to 1 m, medium to 6 m.")
@click.option("--noise-floor", default=_D.noise_floor, show_default=True,
              help="Points at most this high above the ground are not vegetation (and are road / water surface).")
@click.option("--roads", help="Edge-of-pavement lines (file.gpkg:LAYER or a shapefile), for --classify-vegetation.")
@click.option("--hydro", help="Hydrographic lines (single and dual-line streams), for --classify-vegetation.")
@click.option("--waterbodies", help="Water body polygons (islands as holes), for --classify-vegetation.")
@click.option("--reproject-vectors", is_flag=True, help="Reproject breakline layers to the tiles' CRS.")
@click.option("--buffer", default=_D.buffer, show_default=True, help="How far the neighbouring tiles' ground points are read.")
@click.option("--format", "fmt", type=click.Choice(FORMATS), default=_D.format, show_default=True, help="Output format.")
@crs_opt
@jobs_opt
@overwrite_opt
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler address, or 'local'.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def normalize(inputs, out, replace_z, classify_vegetation, bands, noise_floor, roads, hydro, waterbodies, reproject_vectors,
              buffer, fmt, crs, jobs, overwrite, scheduler, quiet):
    """Height above ground of every point of INPUTS (files, folders, globs or a .vpc), from the TIN of the ground
    points (classes 2 and 9) of each tile and its neighbours: OUT/<tile>.laz with a HeightAboveGround dimension
    (float32, in the tiles' vertical unit) or, with --replace-z, as z; OUT/normalized.vpc; OUT/report.json.

    \b
    Examples:
      $ gistools normalize sample_tiles --out out/normalized
      $ gistools normalize tiles --out hag --replace-z --format copc --jobs 2
      $ gistools normalize tiles --out veg --classify-vegetation --roads breaklines.gpkg:ROADBREAKLINE \\
          --waterbodies breaklines.gpkg:WATERBODY
    """
    settings = NormalizeSettings(buffer=buffer, replace_z=replace_z, classify_vegetation=classify_vegetation, bands=bands,
                                 noise_floor=noise_floor, format=fmt, crs=crs)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: normalize_from_tiles(inputs, out, settings, roads=roads, hydro=hydro,
                                                           waterbodies=waterbodies, reproject_vectors=reproject_vectors,
                                                           jobs=jobs, scheduler=scheduler, overwrite=overwrite,
                                                           progress=progress))
    counts = report["counts"]
    finish_batch(report, f"{counts['ok']} tiles normalized, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"virtual point cloud: {report['vpc']}; report: {out}/report.json")
