"""``gistools normalize``: heights above ground of LAS/LAZ tiles, and vegetation classes from them."""

from __future__ import annotations

import click

from .options import out_opt, batch_report, finish_batch, overwrite_opt, progress_bar
from .spec import spec_options


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@out_opt()
@spec_options("normalize", skip=("overwrite",))
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def normalize(inputs, out, replace_z, classify_vegetation, bands, noise_floor, roads, hydro, waterbodies, reproject_vectors,
              buffer, format, crs, jobs, overwrite, scheduler, quiet):  # noqa: A002
    """Height above ground of every point of INPUTS (files, folders, globs or a .vpc), from the TIN of the ground
    points (classes 2 and 9) of each tile and its neighbours: OUT/<tile>.laz with a HeightAboveGround dimension
    (float32, in the tiles' vertical unit) or, with --replace-z, as z; OUT/normalized.vpc; OUT/report.json.
    The breaklines (--roads, --hydro, --waterbodies) are used with --classify-vegetation.

    \b
    Examples:
      $ gistools normalize sample_tiles --out out/normalized
      $ gistools normalize tiles --out hag --replace-z --format copc --jobs 2
      $ gistools normalize tiles --out veg --classify-vegetation --roads breaklines.gpkg:ROADBREAKLINE \\
          --waterbodies breaklines.gpkg:WATERBODY
    """
    from ..products.normalize import NormalizeSettings, normalize_from_tiles

    settings = NormalizeSettings(buffer=buffer, replace_z=replace_z, classify_vegetation=classify_vegetation, bands=bands,
                                 noise_floor=noise_floor, format=format, crs=crs)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: normalize_from_tiles(inputs, out, settings, roads=roads, hydro=hydro,
                                                           waterbodies=waterbodies, reproject_vectors=reproject_vectors,
                                                           jobs=jobs, scheduler=scheduler, overwrite=overwrite,
                                                           progress=progress))
    counts = report["counts"]
    finish_batch(report, f"{counts['ok']} tiles normalized, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"virtual point cloud: {report['vpc']}; report: {out}/report.json")
