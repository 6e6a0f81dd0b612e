"""``gistools search-plan``: where the lost person likely is, the segments to search, their detection, routes."""

from __future__ import annotations

import click

from ..parameters import PARAMETERS
from .options import overwrite_opt, progress_bar
from .spec import spec_options

_MANY = ("last_seen", "staging", "route_to")


def _list_categories(ctx, _param, value):
    """--list-categories: the table's categories and terrains, then exit."""
    if not value or ctx.resilient_parsing:
        return
    from ..products.search_plan import lost_person_table

    table = lost_person_table()
    click.echo(f"{'category':<24} {'ecoregion':<22} 25%    50%    75%    95% (km)")
    for r in table:
        rings = " ".join(f"{v / 1000:6.2f}" for v in r["rings_m"])
        click.echo(f"{r['category']:<24} {r['ecoregion']:<22} {rings}")
    click.echo(f"source: {table[0]['source']}")
    ctx.exit(0)


def _many(name: str):
    p = PARAMETERS[name]
    return click.option(p.cli_flag, name, multiple=True, required=name == "last_seen", metavar=p.metavar,
                        help=p.help_text("cli") + (f" Default: {p.default_help('cli')}." if p.default_text else ""))


@click.command(name="search-plan")
@click.argument("out", type=click.Path(file_okay=False))
@_many("last_seen")
@_many("staging")
@_many("route_to")
@spec_options("search-plan", skip=("overwrite", "list_categories", *_MANY))
@overwrite_opt
@click.option("--list-categories", is_flag=True, default=False, expose_value=False, is_eager=True, callback=_list_categories,
              help=PARAMETERS["list_categories"].help_text("cli"))
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def search_plan(out, last_seen, staging, route_to, dem, category, categories, effort, shrub_classes, roads, trails,
                hydro, waterbodies, overwrite, quiet, **settings):
    """The search plan of a lost person from the point last seen: the probability of area of their category's
    distance rings (Koester's Lost Person Behavior) weighted by the linear features they follow, barriers and
    handrails from the DEM and the shrub classes, segments of about --segment-size bounded by roads, trails,
    drainages, ridges and thickets, the probability of detection of the hours in --effort, and the quickest routes
    from the staging points (and a litter carry out). DEM is a gistools shrub folder (its dem.vrt and
    classes.vrt) or a DEM raster. Writes OUT/poa.tif, OUT/segments.gpkg, OUT/routes.gpkg, OUT/barriers.gpkg,
    rasters of the segments and barriers, and OUT/report.json.

    \b
    Examples:
      $ gistools search-plan out/plan --dem out --from 431000,1811000 --category dementia --staging 431200,1810600
      $ gistools search-plan out/plan --dem out --from 431000,1811000 --category dementia --effort hours.csv
      $ gistools search-plan --list-categories
    """
    from ..products.search_plan import SearchSettings, search_plan as plan

    with progress_bar(quiet) as progress:
        rep = plan(dem, out, list(last_seen), category, SearchSettings(**settings), staging=list(staging) or None,
                   route_to=list(route_to) or None, effort=effort, classes=shrub_classes, roads=roads, trails=trails,
                   hydro=hydro, waterbodies=waterbodies, categories=categories, overwrite=overwrite,
                   progress=progress)
    if rep.get("kept"):
        click.echo(f"kept the outputs of an earlier run with the same settings in {out} (--overwrite makes them "
                   "again)")
    rings = ", ".join(f"{p}% {d / 1000:.2f} km" for p, d in zip((25, 50, 75, 95), rep["rings_m"]))
    click.echo(f"{rep['category']} ({rep['ecoregion']}): {rings}; on the DEM {1 - rep['rest_of_world']:.1%} of the "
               f"probability, rest of the world {rep['rest_of_world']:.1%}")
    click.echo(f"{rep['segments']} segments, {rep['segment_area_ha']:,.1f} ha; first to search: "
               + ", ".join(str(s) for s in rep["ranked"][:5])
               + (f"; {rep['effort_hours']:g} searcher-hours give a cumulative POS of {rep['pos_cumulative']:.1%}"
                  if rep["effort_hours"] else ""))
    if rep.get("litter"):
        click.echo(f"litter carry out: {rep['litter']['minutes']:.0f} min, {rep['litter']['length_m']:,.0f} m")
    for warning in rep.get("warnings", []):
        click.echo(f"warning: {warning}", err=True)
    click.echo(f"report: {out}/report.json")
