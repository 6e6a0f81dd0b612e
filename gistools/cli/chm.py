"""``gistools chm``: canopy height models of LAS/LAZ tiles (p2r, pit-free, TIN)."""

from __future__ import annotations

import click

from ..tasks.chm import CHM_METHODS, ChmSettings, chm_from_tiles
from .options import finish_batch, batch_report, crs_opt, jobs_opt, overwrite_opt, progress_bar

_D = ChmSettings()


def _lengths(ctx, param, value):
    items = tuple(v.strip() for v in str(value).split(",") if v.strip())
    if not items:
        raise click.BadParameter(f"{value!r}: give comma-separated lengths, e.g. 0m,2m,5m")
    return items


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--method", type=click.Choice(CHM_METHODS), default=_D.method, show_default=True,
              help="p2r: the highest first return of each cell; pitfree: Khosravipour et al. 2014 (lidR pitfree()); "
                   "tin: a TIN of the first returns.")
@click.option("--cell-size", default=_D.cell_size, show_default=True, help="Cell size (with unit).")
@click.option("--thresholds", default=",".join(_D.thresholds), show_default=True, callback=_lengths,
              help="pitfree: the height thresholds of the layers (then one every --threshold-step).")
@click.option("--threshold-step", default=_D.threshold_step, show_default=True,
              help="pitfree: a threshold every this above the last given, up to the highest return (0: none; lidR's "
                   "pitfree() is --thresholds 0m,2m,5m,10m,15m --threshold-step 0 --max-edge 0,1m).")
@click.option("--max-edge", default=",".join(_D.max_edge), show_default=True, callback=_lengths,
              help="pitfree: the longest triangle edge of the first layer, then of the upper layers (0: no limit).")
@click.option("--tin-max-edge", default=_D.tin_max_edge, show_default=True,
              help="tin: the longest triangle edge (0: no limit).")
@click.option("--buffer", default=_D.buffer, show_default=True, help="How far the neighbouring tiles' points are read.")
@crs_opt
@jobs_opt
@overwrite_opt
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler address, or 'local'.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def chm(inputs, out, method, cell_size, thresholds, threshold_step, max_edge, tin_max_edge, buffer, crs, jobs, overwrite, scheduler, quiet):
    """Canopy height model of every tile of INPUTS (files, folders, globs or a .vpc): first returns' heights above
    the ground TIN, gridded by METHOD into OUT/chm/<tile>.tif and OUT/chm.vrt; OUT/report.json counts the pits
    (cells more than 1 m below all 8 neighbours) left in each tile.

    \b
    Examples:
      $ gistools chm sample_tiles --out out/chm --cell-size 5ft
      $ gistools chm tiles --out chm_p2r --method p2r --cell-size 0.5m --jobs 2
    """
    settings = ChmSettings(cell_size=cell_size, method=method, thresholds=thresholds, threshold_step=threshold_step,
                           max_edge=max_edge,
                           tin_max_edge=tin_max_edge, buffer=buffer, crs=crs)
    with progress_bar(quiet) as progress:
        report = batch_report(lambda: chm_from_tiles(inputs, out, settings, jobs=jobs, scheduler=scheduler,
                                                     overwrite=overwrite, progress=progress))
    counts = report["counts"]
    finish_batch(report, f"{counts['ok']} tiles done, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed; "
               f"{report['pits']:,} pits left; mosaic: {report['mosaic']}; report: {out}/report.json")
