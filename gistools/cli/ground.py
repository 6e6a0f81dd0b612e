"""``gistools ground``: ground (2) and noise (7, 18) classes of LAS/LAZ tiles."""

from __future__ import annotations

import click

from ..parameters import PARAMETERS, render
from ..parameters.lidar import DEFAULT_TEXTS
from .options import finish_batch, run_batch, tiles_command, tiles_counted


def own_default_texts(texts: dict):
    """The help of a shared option whose default this command computes otherwise: its declared help, then what
    ``texts`` ({name: text}) says of the default (gistools.parameters.lidar.DEFAULT_TEXTS)."""

    def apply(command: click.Command) -> click.Command:
        for param in command.params:
            if param.name in texts:
                param.help = f"{PARAMETERS[param.name].help_text('cli')} Default: {render(texts[param.name], 'cli')}."
        return command

    return apply


@own_default_texts(DEFAULT_TEXTS["ground"])
@tiles_command("ground")
def ground(inputs, out, ground_method, noise, cell, slope, window, threshold, scalar, smrftin_cell, smrftin_slope,
           smrftin_window, smrftin_threshold, smrftin_scalar, smrftin_step, smrftin_patch, csf_resolution, csf_threshold,
           csf_rigidness, csf_iterations, csf_time_step, csf_slope_smooth, ivf_res, ivf_n, sor_k, sor_multiplier,
           low_noise_depth, buffer, keep_classes, format, crs, jobs, overwrite, scheduler, quiet):  # noqa: A002
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
      $ gistools ground tiles --out classified --method smrftin
      $ gistools ground tiles.vpc --out classified --noise sor --format las
    """
    from ..products.ground import GroundSettings, ground_from_tiles

    settings = GroundSettings(method=ground_method, noise=noise, cell=cell, slope=slope, window=window,
                              threshold=threshold, scalar=scalar, smrftin_cell=smrftin_cell,
                              smrftin_slope=smrftin_slope, smrftin_window=smrftin_window,
                              smrftin_threshold=smrftin_threshold, smrftin_scalar=smrftin_scalar,
                              smrftin_step=smrftin_step, smrftin_patch=smrftin_patch,
                              csf_resolution=csf_resolution,
                              csf_threshold=csf_threshold, csf_rigidness=csf_rigidness, csf_iterations=csf_iterations,
                              csf_time_step=csf_time_step, csf_slope_smooth=csf_slope_smooth, ivf_res=ivf_res,
                              ivf_n=ivf_n, sor_k=sor_k, sor_multiplier=sor_multiplier, low_noise_depth=low_noise_depth,
                              buffer=buffer, keep_classes=keep_classes, format=format, crs=crs)
    report = run_batch(quiet, ground_from_tiles, inputs, out, settings, jobs=jobs, scheduler=scheduler,
                       overwrite=overwrite)
    finish_batch(report, f"{tiles_counted(report, 'classified')}; virtual point cloud: {report['vpc']}"
                 f"; report: {out}/report.json")
