"""``gistools metrics``: per-cell statistics of the points of LAS/LAZ tiles (lasR / lidR cell metrics)."""

from __future__ import annotations

import click

from ..tasks.metrics import DEFAULT_METRICS, RETURNS, MetricsSettings, metrics_from_tiles
from .options import finish_batch, batch_report, crs_opt, jobs_opt, overwrite_opt, parse_classes, progress_bar

_D = MetricsSettings()


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--cell-size", default=_D.cell_size, show_default=True, help="Cell size (with unit), on the lattice of "
              "gistools rasters.")
@click.option("--metrics", "metrics", default=",".join(DEFAULT_METRICS), show_default=True,
              help="Comma-separated names: count, density; z_ / i_ / hag_ + min, max, mean, median, sum, sd, cv, pNN, "
                   "aboveX; cover_aboveX; fhd; vci; fuel_A_B (README \"Cell metrics\").")
@click.option("--normalized", is_flag=True, help="Compute the z_* metrics on heights above ground (named hag_*).")
@click.option("--classes", callback=parse_classes, default=None, help="ASPRS classes whose points count, e.g. 1,2,3,4,5 "
              "(default: all but noise 7, 18).")
@click.option("--returns", type=click.Choice(RETURNS), default=_D.returns, show_default=True, help="Which returns count.")
@click.option("--buffer", default=_D.buffer, show_default=True,
              help="How far the neighbouring tiles' ground points are read for heights above ground.")
@crs_opt
@jobs_opt
@overwrite_opt
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler address, or 'local'.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def metrics(inputs, out, cell_size, metrics, normalized, classes, returns, buffer, crs, jobs, overwrite, scheduler, quiet):
    """Cell metrics of every tile of INPUTS (files, folders, globs or a .vpc): OUT/<metric>/<tile>.tif, OUT/<metric>.vrt
    and OUT/report.json. Cells without points are nodata. Neighbouring tiles' points are read, so tiles equal one
    merged run. Thresholds in names take a unit (hag_above2m, cover_above6ft); a bare number is in the tiles'
    vertical unit.

    \b
    Examples:
      $ gistools metrics sample_tiles --out out/metrics --cell-size 10m
      $ gistools metrics tiles --out m --metrics z_p95,cover_above2m,fuel_1_3m,fhd --classes 1,2,3,4,5 --jobs 2
      $ gistools metrics tiles --out m --metrics z_max,z_p50 --normalized --returns first
    """
    settings = MetricsSettings(cell_size=cell_size, metrics=tuple(m.strip() for m in metrics.split(",") if m.strip()),
                               normalized=normalized, classes=classes, returns=returns, buffer=buffer, crs=crs)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: metrics_from_tiles(inputs, out, settings, jobs=jobs, scheduler=scheduler,
                                                         overwrite=overwrite, progress=progress))
    counts = report["counts"]
    finish_batch(report, f"{counts['ok']} tiles done, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"metrics {', '.join(report['metrics'])}; mosaics {out}/<metric>.vrt; report: {out}/report.json")
