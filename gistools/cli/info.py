"""``gistools info``: header, CRS, units and point counts of tiles."""

from __future__ import annotations

import json

import click
import numpy as np

from ..errors import GistoolsError
from ..io.points import crs_label, iter_chunks, read_tile_info
from ..io.tiles import find_tiles
from .options import crs_opt


def tile_summary(path, crs=None) -> dict:
    """Header facts plus point counts by class and by return (reads every point, in chunks)."""
    info = read_tile_info(path, crs)
    by_class = np.zeros(256, np.int64)
    by_return = np.zeros(16, np.int64)
    for chunk in iter_chunks(info):
        by_class += np.bincount(chunk.classification, minlength=256)[:256]
        by_return += np.bincount(np.minimum(chunk.return_number, 15), minlength=16)[:16]
    return {
        "file": str(info.path),
        "las_version": info.version,
        "point_format": info.point_format,
        "compressed": info.compressed,
        "points": info.point_count,
        "bounds": info.bounds,
        "z_range": info.z_range,
        "scales": info.scales,
        "offsets": info.offsets,
        "crs": crs_label(info.crs),
        "crs_source": "file" if info.crs_from_file else "--crs",
        "horizontal_unit": info.unit.name,
        "vertical_unit": info.z_unit.name,
        "points_by_class": {int(c): int(n) for c, n in enumerate(by_class) if n},
        "points_by_return": {int(r): int(n) for r, n in enumerate(by_return) if n},
    }


@click.command()
@click.argument("tiles", nargs=-1, required=True)
@crs_opt
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
def info(tiles, crs, as_json):
    """Print header, CRS, units and point counts by class and return of TILES.

    \b
    Examples:
      $ gistools info sample_tiles/35712.las
      $ gistools info sample_tiles --json
    """
    failed = 0
    summaries = []
    for path in find_tiles(tiles):
        try:
            s = tile_summary(path, crs)
        except GistoolsError as err:
            click.echo(f"gistools: error: {err}", err=True)
            failed += 1
            continue
        summaries.append(s)
        if not as_json:
            click.echo(f"{s['file']}")
            click.echo(f"  LAS {s['las_version']}, point format {s['point_format']}, {s['points']:,} points"
                       f"{' (LAZ)' if s['compressed'] else ''}")
            click.echo(f"  CRS: {s['crs']} (from {s['crs_source']}); units: x/y {s['horizontal_unit']}, z {s['vertical_unit']}")
            w, so, e, n = s["bounds"]
            click.echo(f"  bounds: x {w:.2f} .. {e:.2f}, y {so:.2f} .. {n:.2f}, z {s['z_range'][0]:.2f} .. {s['z_range'][1]:.2f}")
            click.echo("  by class: " + ", ".join(f"{c}: {n:,}" for c, n in s["points_by_class"].items()))
            click.echo("  by return: " + ", ".join(f"{r}: {n:,}" for r, n in s["points_by_return"].items()))
    if as_json:
        click.echo(json.dumps(summaries, indent=2))
    if failed:
        raise SystemExit(1)
