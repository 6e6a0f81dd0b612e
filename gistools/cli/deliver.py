"""Deliverables for field teams from a shrub chain's output folder: ``gistools webmap``."""

from __future__ import annotations

import click

basemap_opt = click.option("--basemap", default=None, metavar="URL",
                           help="An XYZ tile URL under the polygons, for users who are online (default: none; the page "
                                "then makes no request to any network address).")


@click.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@basemap_opt
@click.option("--split-mb", type=float, default=40.0, show_default=True,
              help="Above this many megabytes of polygons the map is split by tile into parts (and an index page).")
def webmap(out, basemap, split_mb):
    """Write OUT/shrub_map.html: the shrub classes of a gistools shrub folder as one self-contained offline web map
    (Leaflet and the polygons inlined; legend, scale bar, the parameters, a popup per polygon with its class, area
    and tile). Open it from a USB stick or a tablet with no network.

    \b
    Examples:
      $ gistools webmap out
      $ gistools webmap out --basemap 'https://tile.openstreetmap.org/{z}/{x}/{y}.png'
    """
    from ..tasks.webmap import web_map

    result = web_map(out, basemap=basemap, split_mb=split_mb)
    parts = f" and {len(result['parts'])} parts" if result["parts"] else ""
    click.echo(f"wrote {result['html']}{parts} ({result['bytes'] / 1e6:.1f} MB, {result['features']:,} polygons)")
