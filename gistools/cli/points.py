"""``gistools points``: LAS/LAZ tiles to point layers (the dissertation's LAS To Multipoint)."""

from __future__ import annotations

import click

from .options import batch_report, finish_batch, out_opt, overwrite_opt, takes_area
from .spec import spec_options


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@out_opt("Output folder (one layer per tile).")
@spec_options("points", skip=("overwrite",))
@overwrite_opt
@takes_area
def points(inputs, out, classes, returns, fmt, crs, chunk_size, overwrite):
    """LAS/LAZ tiles to point layers with x, y, z, class, return number and intensity
    (the dissertation's LAS To Multipoint).

    \b
    Examples (the dissertation's two runs):
      $ gistools points tiles --classes 1,2 --returns first --out non-ground
      $ gistools points tiles --classes 2 --returns all --out ground
    """
    from ..products.points import points_from_tiles

    summary = batch_report(lambda: points_from_tiles(inputs, out, classes=classes, returns=returns, fmt=fmt, crs=crs,
                                                     overwrite=overwrite, chunk_size=chunk_size))
    c = summary["counts"]
    finish_batch(summary, f"{c['ok']} tiles ok, {c['skipped']} skipped, {c['failed']} failed; "
               f"{sum(t['points'] for t in summary['tiles']):,} points written to {out}")
