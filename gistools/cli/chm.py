"""``gistools chm``: canopy height models of LAS/LAZ tiles (p2r, pit-free, TIN)."""

from __future__ import annotations

from .options import finish_batch, run_batch, tiles_command, tiles_counted


def _lengths(text: str) -> tuple:
    """'0m,2m,5m' -> ('0m', '2m', '5m') (the settings check each, and refuse an empty list)."""
    return tuple(v.strip() for v in str(text).split(",") if v.strip())


@tiles_command("chm")
def chm(inputs, out, chm_method, cell_size, thresholds, threshold_step, max_edge, tin_max_edge, buffer, crs, jobs,
        overwrite, scheduler, quiet):
    """Canopy height model of every tile of INPUTS (files, folders, globs or a .vpc): first returns' heights above
    the ground TIN, gridded by METHOD into OUT/chm/<tile>.tif and OUT/chm.vrt; OUT/report.json counts the pits
    (cells more than 1 m below all 8 neighbours) left in each tile.

    \b
    Examples:
      $ gistools chm sample_tiles --out out/chm --cell-size 5ft
      $ gistools chm tiles --out chm_p2r --method p2r --cell-size 0.5m --jobs 2
    """
    from ..products.chm import ChmSettings, chm_from_tiles

    settings = ChmSettings(cell_size=cell_size, method=chm_method, thresholds=_lengths(thresholds),
                           threshold_step=threshold_step, max_edge=_lengths(max_edge), tin_max_edge=tin_max_edge,
                           buffer=buffer, crs=crs)
    report = run_batch(quiet, chm_from_tiles, inputs, out, settings, jobs=jobs, scheduler=scheduler,
                       overwrite=overwrite)
    finish_batch(report, f"{tiles_counted(report)}; {report['pits']:,} pits left; mosaic: {report['mosaic']}"
                 f"; report: {out}/report.json")
