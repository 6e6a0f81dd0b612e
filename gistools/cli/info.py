"""``gistools info``: header, CRS, units and point counts of tiles."""

from __future__ import annotations

import json as _json

import click

from .options import progress_bar
from .spec import spec_options


@click.command()
@click.argument("tiles", nargs=-1, required=True)
@spec_options("info")
@click.option("--json", "json", is_flag=True, help="Print JSON instead of text.")
def info(tiles, crs, json):
    """Print header, CRS, units and point counts by class and return of TILES.

    \b
    Examples:
      $ gistools info sample_tiles/35712.las
      $ gistools info sample_tiles --json
    """
    from ..products.info import tiles_summary

    with progress_bar(False) as progress:  # on a terminal only (stderr), done before the first line is printed
        result = tiles_summary(tiles, crs=crs, progress=progress)
    summaries = [{k: v for k, v in t.items() if k != "status"} for t in result["tiles"] if t["status"] == "ok"]
    for tile in result["tiles"]:
        if tile["status"] == "failed":
            click.echo(f"gistools: error: {tile['error']}", err=True)
    if json:
        click.echo(_json.dumps(summaries, indent=2))
    for s in [] if json else summaries:
        click.echo(f"{s['file']}")
        click.echo(f"  LAS {s['las_version']}, point format {s['point_format']}, {s['points']:,} points"
                   f"{' (LAZ)' if s['compressed'] else ''}")
        if s["crs_source"]:
            click.echo(f"  CRS: {s['crs']} (from {s['crs_source']}); units: x/y {s['horizontal_unit']}, "
                       f"z {s['vertical_unit']}")
        if s["crs_note"]:
            click.echo(f"  CRS: {s['crs_note']}")
        w, so, e, n = s["bounds"]
        click.echo(f"  bounds: x {w:.2f} .. {e:.2f}, y {so:.2f} .. {n:.2f}, z {s['z_range'][0]:.2f} .. "
                   f"{s['z_range'][1]:.2f}")
        click.echo("  by class: " + ", ".join(f"{c}: {n:,}" for c, n in s["points_by_class"].items()))
        click.echo("  by return: " + ", ".join(f"{r}: {n:,}" for r, n in s["points_by_return"].items()))
    if result["counts"]["failed"]:
        raise SystemExit(1)
