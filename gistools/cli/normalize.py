"""``gistools normalize``: heights above ground of LAS/LAZ tiles, and vegetation classes from them."""

from __future__ import annotations

from .options import finish_batch, run_batch, tiles_command, tiles_counted


@tiles_command("normalize")
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
    report = run_batch(quiet, normalize_from_tiles, inputs, out, settings, roads=roads, hydro=hydro,
                       waterbodies=waterbodies, reproject_vectors=reproject_vectors, jobs=jobs, scheduler=scheduler,
                       overwrite=overwrite)
    finish_batch(report, f"{tiles_counted(report, 'normalized')}; virtual point cloud: {report['vpc']}"
                 f"; report: {out}/report.json")
