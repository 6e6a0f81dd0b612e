"""Deliverables for field teams from a shrub chain's output folder: ``gistools webmap``, ``gistools scene``,
``gistools mapbook``."""

from __future__ import annotations

import click

from .spec import spec_options


@click.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@spec_options("webmap")
def webmap(out, travel, viewshed, fuels, plan, basemap, split_mb):
    """Write OUT/shrub_map.html: the shrub classes of a gistools shrub folder as one self-contained offline web map
    (Leaflet and the polygons inlined; legend, scale bar, the parameters, a popup per polygon with its class, area
    and tile). Open it from a USB stick or a tablet with no network. With the output folders of gistools travel,
    viewshed, fuels or search-plan, their layers too: the isochrones and points last seen (and the travel time under
    the cursor), the cells seen, the canopy base height classes, the search segments (POA and POD under the cursor)
    and routes.

    \b
    Examples:
      $ gistools webmap out
      $ gistools webmap out --travel travel --viewshed viewshed --fuels fuels
      $ gistools webmap out --basemap 'https://tile.openstreetmap.org/{z}/{x}/{y}.png'
    """
    from ..deliver.webmap import web_map

    result = web_map(out, travel=travel, viewshed=viewshed, fuels=fuels, plan=plan, basemap=basemap,
                     split_mb=split_mb)
    parts = f" and {len(result['parts'])} parts" if result["parts"] else ""
    click.echo(f"wrote {result['html']}{parts} ({result['bytes'] / 1e6:.1f} MB, {result['features']:,} polygons)")


@click.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@spec_options("scene")
def scene(out, exaggeration, max_mb, surface):
    """Write OUT/scene.glb: the surface of a gistools shrub folder as a glTF mesh in metres with the shrub classes
    as vertex colours (x east, y up, z south from the mosaic's south-west corner; the origin and CRS in the asset's
    extras, OUT/scene.prj and OUT/scene.wld beside it), for QGIS 3D, Cesium or Blender.

    \b
    Examples:
      $ gistools scene out
      $ gistools scene out --exaggeration 3 --max-mb 20
    """
    from ..deliver.scene import scene_glb

    r = scene_glb(out, exaggeration=exaggeration, max_mb=max_mb, surface=surface)
    click.echo(f"wrote {r['glb']} ({r['bytes'] / 1e6:.1f} MB, {r['vertices']:,} vertices, every {r['step']} cell(s); "
               f"heights {r['height_range_m'][0]:.1f} to {r['height_range_m'][1]:.1f} m)")


@click.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@spec_options("mapbook")
def mapbook(out, tile_index, tile_field, travel, viewshed, fuels, plan, scale, paper, max_pages):
    """Write OUT/map_book.pdf: a page per tile of --tile-index, each fitted to it (without it: per sheet of a grid
    at 1:SCALE) of a gistools shrub folder's classes, with the roads and water, a coordinate grid, a locator map,
    legend, scale bar, north arrow and the parameters: what a field team prints. With the output folder of gistools
    travel, the isochrones and points last seen on every page; of gistools viewshed, the cells seen; of gistools
    fuels, a last page of the canopy base height classes; of gistools search-plan, a page per segment assignment.

    \b
    Examples:
      $ gistools mapbook out --tile-index sample_tiles/breaklines.gpkg:FOOTPRINT
      $ gistools mapbook out --travel travel --viewshed viewshed --fuels fuels
      $ gistools mapbook out --scale 5000 --paper a4
    """
    from ..deliver.mapbook import map_book

    r = map_book(out, tile_index=tile_index, tile_field=tile_field, travel=travel, viewshed=viewshed, fuels=fuels,
                 plan=plan, scale=scale, paper=paper, max_pages=max_pages)
    click.echo(f"wrote {r['pdf']} ({r['pages']} pages, 1:{min(r['scales']):,.0f} to 1:{max(r['scales']):,.0f})")
