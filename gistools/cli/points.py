"""``gistools points``: LAS/LAZ tiles to point layers (the dissertation's LAS To Multipoint)."""

from __future__ import annotations

import click

from .options import finish_batch, batch_report, chunk_opt, crs_opt, overwrite_opt, parse_classes


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder (one layer per tile).")
@click.option("--classes", callback=parse_classes, default="1,2", show_default=True, help="ASPRS classes to keep.")
@click.option("--returns", type=click.Choice(["first", "last", "any"]), default="any", show_default=True)
@click.option("--format", "fmt", type=click.Choice(["gpkg", "parquet"]), default="gpkg", show_default=True,
              help="GeoPackage, or GeoParquet (needs pyarrow) for tiles of millions of points.")
@crs_opt
@chunk_opt
@overwrite_opt
def points(inputs, out, classes, returns, fmt, crs, chunk_size, overwrite):
    """LAS/LAZ tiles to point layers with x, y, z, class, return number and intensity
    (the dissertation's LAS To Multipoint).

    \b
    Examples (the dissertation's two runs):
      $ gistools points tiles --classes 1,2 --returns first --out non-ground
      $ gistools points tiles --classes 2 --returns any --out ground
    """
    from ..tasks.points import points_from_tiles

    summary = batch_report(lambda: points_from_tiles(inputs, out, classes=classes, returns=returns, fmt=fmt, crs=crs,
                                                     overwrite=overwrite, chunk_size=chunk_size))
    c = summary["counts"]
    finish_batch(summary, f"{c['ok']} tiles ok, {c['skipped']} skipped, {c['failed']} failed; "
               f"{sum(t['points'] for t in summary['tiles']):,} points written to {out}")
