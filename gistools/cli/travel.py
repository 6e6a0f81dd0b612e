"""``gistools travel``: a walker's travel time from the points last seen (search and rescue)."""

from __future__ import annotations

import click

from ..parameters import PARAMETERS
from .options import overwrite_opt, progress_bar
from .spec import spec_options

_FROM = PARAMETERS["last_seen"]


@click.command()
@click.argument("out", type=click.Path(file_okay=False))
@click.option(_FROM.cli_flag, "last_seen", multiple=True, required=True, metavar=_FROM.metavar,
              help=_FROM.help_text("cli"))
@spec_options("travel", skip=("overwrite", "last_seen"))
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def travel(out, last_seen, dem, shrub_classes, roads, hydro, waterbodies, overwrite, quiet, **settings):
    """Minutes for a walker to reach every cell of DEM from the nearest point last seen: Tobler's hiking function
    on the slope along each step (uphill and downhill differ), slowed by shrub, roads clear, water impassable.
    Writes OUT/travel_minutes.tif, OUT/isochrone_bands.tif, OUT/travel.gpkg (isochrones, last_seen) and
    OUT/report.json. A rerun with the same settings keeps the complete outputs (or makes again those a stopped run
    left incomplete); one with other settings is refused unless --overwrite.

    \b
    Examples:
      $ gistools travel out/travel --dem out --from 431000,1811000
      $ gistools travel sar --dem dem.vrt --classes classes.vrt --from seen.gpkg:POINTS --wade-speed 1
    """
    from ..products.travel import TravelSettings, travel_from_dem

    settings = TravelSettings(**settings)
    with progress_bar(quiet) as progress:
        rep = travel_from_dem(dem, out, list(last_seen), settings, classes=shrub_classes, roads=roads, hydro=hydro,
                              waterbodies=waterbodies, overwrite=overwrite, progress=progress)
    if rep.get("kept"):
        click.echo(f"kept the complete outputs of an earlier run with the same settings in {out} (--overwrite makes "
                   "them again)")
    click.echo(f"{len(rep['last_seen'])} point(s) last seen; {rep['reached_share']:.1%} of the cells reached, the "
               f"farthest in {rep['max_minutes']:.1f} min ({rep['neighbours']} neighbours)")
    for iso in rep["isochrones"]:
        click.echo(f"within {iso['minutes']:g} min: {iso['hectares']:,.2f} ha ({iso['acres']:,.2f} acres)")
    click.echo(f"report: {out}/report.json")
