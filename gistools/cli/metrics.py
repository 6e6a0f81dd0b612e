"""``gistools metrics``: per-cell statistics of the points of LAS/LAZ tiles (lasR / lidR cell metrics)."""

from __future__ import annotations

import click

from .options import finish_batch, run_batch, tiles_command, tiles_counted


def _names(ctx, param, value):
    """'count,z_p99' -> ('count', 'z_p99'): any metric name (the library refuses one it cannot parse, naming it);
    the declared choices are only the dialog's checklist."""
    return () if value is None else tuple(m.strip() for m in str(value).split(",") if m.strip())


def any_metric_name(command: click.Command) -> click.Command:
    for param in command.params:
        if param.name == "metrics":
            param.callback = _names
    return command


@any_metric_name
@tiles_command("metrics")
def metrics(inputs, out, cell_size, metrics, more_metrics, normalized, classes, returns, buffer, crs, jobs, overwrite,
            scheduler, quiet):
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
    from ..products.metrics import MetricsSettings, metrics_from_tiles

    names = metrics + _names(None, None, more_metrics)
    settings = MetricsSettings(cell_size=cell_size, metrics=names, normalized=normalized, classes=classes,
                               returns=returns, buffer=buffer, crs=crs)
    report = run_batch(quiet, metrics_from_tiles, inputs, out, settings, jobs=jobs, scheduler=scheduler,
                       overwrite=overwrite)
    finish_batch(report, f"{tiles_counted(report)}; metrics {', '.join(report['metrics'])}; mosaics {out}/<metric>.vrt"
                 f"; report: {out}/report.json")
