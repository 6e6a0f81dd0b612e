"""``gistools ground``: ground (2) and noise (7, 18) classes of LAS/LAZ tiles."""

from __future__ import annotations

import click

from ..lidar.ground import GROUND_METHODS
from ..lidar.noise import NOISE_METHODS
from ..tasks.ground import FORMATS, GroundSettings, ground_from_tiles
from .options import finish_batch, batch_report, crs_opt, jobs_opt, overwrite_opt, progress_bar

_D = GroundSettings()  # the options' defaults are the library's


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--method", type=click.Choice(GROUND_METHODS), default=_D.method, show_default=True,
              help="smrf: Simple Morphological Filter (Pingel et al. 2013); csf: Cloth Simulation Filter (needs "
                   "cloth-simulation-filter).")
@click.option("--noise", type=click.Choice(NOISE_METHODS), default=_D.noise, show_default=True,
              help="Noise first: ivf (isolated voxels), sor (statistical outliers) or none.")
@click.option("--cell", default=_D.cell, show_default=True, help="SMRF cell size (with unit).")
@click.option("--slope", type=float, default=_D.slope, show_default=True, help="SMRF slope (rise over run).")
@click.option("--window", default=_D.window, show_default=True, help="SMRF largest window radius (with unit).")
@click.option("--threshold", default=_D.threshold, show_default=True, help="SMRF elevation threshold (with unit).")
@click.option("--scalar", default=_D.scalar, show_default=True, help="SMRF elevation scalar: threshold added per unit of slope (with unit).")
@click.option("--csf-resolution", default=_D.csf_resolution, show_default=True, help="CSF cloth resolution (with unit).")
@click.option("--csf-threshold", default=_D.csf_threshold, show_default=True, help="CSF class threshold (with unit).")
@click.option("--csf-rigidness", type=click.IntRange(1, 3), default=_D.csf_rigidness, show_default=True, help="CSF rigidness 1-3.")
@click.option("--csf-iterations", type=click.IntRange(1), default=_D.csf_iterations, show_default=True, help="CSF iterations.")
@click.option("--csf-time-step", type=float, default=_D.csf_time_step, show_default=True, help="CSF time step.")
@click.option("--csf-slope-smooth", is_flag=True, default=_D.csf_slope_smooth, help="CSF post-processing of steep slopes.")
@click.option("--ivf-res", default=_D.ivf_res, show_default=True, help="IVF voxel size (with unit).")
@click.option("--ivf-n", type=click.IntRange(0), default=_D.ivf_n, show_default=True,
              help="IVF: a point with at most this many other points in its 27 voxels is noise.")
@click.option("--low-noise-depth", default=_D.low_noise_depth, show_default=True,
              help="Points this far below the ground surface are low noise (7), even in clusters.")
@click.option("--buffer", default=None, help="How far to read neighbouring tiles' points. Default: 2 x --window + 10 cells.")
@click.option("--keep-classes", is_flag=True, help="Points that were ground or noise and are not now keep their class (else 1).")
@click.option("--format", "fmt", type=click.Choice(FORMATS), default=_D.format, show_default=True, help="Output format.")
@crs_opt
@jobs_opt
@overwrite_opt
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler address, or 'local'.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def ground(inputs, out, method, noise, cell, slope, window, threshold, scalar, csf_resolution, csf_threshold, csf_rigidness,
           csf_iterations, csf_time_step, csf_slope_smooth, ivf_res, ivf_n, low_noise_depth, buffer, keep_classes, fmt, crs, jobs, overwrite, scheduler, quiet):
    """Classify ground (2) and noise (7 low, 18 high) of every tile of INPUTS (files, folders, globs or a .vpc).

    Writes OUT/<tile>.laz with only the classification changed (every point, the point order and every
    other attribute as they were), OUT/ground.vpc (a virtual point cloud QGIS 3.32+ opens) and
    OUT/report.json. Points of other classes (water 9, buildings 6, ...) keep their class. Neighbouring
    tiles' points within the buffer are read, so tiles equal one merged run. Lengths are converted to the
    tiles' units.

    \b
    Examples:
      $ gistools ground sample_tiles --out classified
      $ gistools ground tiles --out classified --method csf --jobs 2
      $ gistools ground tiles.vpc --out classified --noise sor --format las
    """
    settings = GroundSettings(method=method, noise=noise, cell=cell, slope=slope, window=window, threshold=threshold,
                              scalar=scalar, csf_resolution=csf_resolution, csf_threshold=csf_threshold,
                              csf_rigidness=csf_rigidness, csf_iterations=csf_iterations, csf_time_step=csf_time_step,
                              csf_slope_smooth=csf_slope_smooth, ivf_res=ivf_res, ivf_n=ivf_n,
                              low_noise_depth=low_noise_depth, buffer=buffer, keep_classes=keep_classes, format=fmt, crs=crs)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: ground_from_tiles(inputs, out, settings, jobs=jobs, scheduler=scheduler,
                                                        overwrite=overwrite, progress=progress))
    counts = report["counts"]
    finish_batch(report, f"{counts['ok']} tiles classified, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"virtual point cloud: {report['vpc']}; report: {out}/report.json")
