"""``gistools runway``: a runway survey and the ICAO reference code to sections, areas and mass haul."""

from __future__ import annotations

import click

from ..errors import GistoolsError
from ..parameters import flag_of
from .aquifer import parse_fields
from .options import folder_command, kept_note, progress_bar


def _metres(name: str, value):
    """A length with its unit ("10m", "30ft", "32.8ftUS", or a bare number in metres) in metres (the ICAO template and
    the survey's CRS are in metres)."""
    from ..products.runway import runway_metres

    if value is None:
        return None
    try:
        return runway_metres(value, name)
    except GistoolsError as err:
        raise click.BadParameter(str(err), param_hint=f"'{flag_of(name)}'") from None


@folder_command("runway", click.argument("survey"))
def runway(survey, out, crs, fields, overwrite, quiet, z_max, max_offset, min_offset, **settings):
    """Cut and fill of a runway: SURVEY (id, type, x, y, z; type 1 = centre-line light, 2 = other) and the
    aerodrome reference code to a design model, cross sections, area diagram and Brueckner curve.

    \b
    Examples:
      $ gistools runway survey.csv --code 4E --crs EPSG:3003 --out orio
      $ gistools runway survey.gpkg:POINTS --code 4E --template dissertation --spacing 10m --out orio_diss
    """
    from ..products.runway import RunwaySettings, runway_earthworks
    from ..runway.survey import SurveyChecks

    for name in ("spacing", "free_haul"):
        settings[name] = _metres(name, settings[name])
    checks = SurveyChecks(z_max=z_max, max_offset=_metres("max_offset", max_offset),
                          min_offset=_metres("min_offset", min_offset))
    settings = RunwaySettings(checks=checks, **settings)
    fields = parse_fields(fields, "id,type,x,y,z", "type=KIND,z=ELEV")
    free_haul = settings.free_haul
    with progress_bar(quiet) as progress:
        rep = runway_earthworks(survey, out, settings, crs=crs, overwrite=overwrite, progress=progress, fields=fields)
    click.echo(f"{rep['code']} {rep['runway_type']} ({rep['template']} template): {rep['stations']} stations every "
               f"{rep['spacing']:.2f} m over {rep['length']:.1f} m, bearing {rep['bearing']:.2f} deg")
    click.echo(f"cut {rep['cut']:,.1f} m3, fill {rep['fill']:,.1f} m3, net {rep['net']:,.1f} m3; balance points "
               + (", ".join(f"{b:.1f}" for b in rep["balance_points"]) or "none"))
    t = rep.get("totals", {})
    if "overhaul" in t:
        click.echo(f"haul moment {t['haul_moment']:,.0f} m3 x m, mean haul distance {t['mean_haul_distance']:,.1f} m; "
                   f"overhaul beyond the free haul of {free_haul:g} m: {t['overhaul']:,.0f} m3 x m")
    r = rep["removed"]
    click.echo(f"removed: {r['duplicates']} duplicates, {r['outliers']} outliers; {r['renumbered']} renumbered; "
               f"report: {out}/report.json")
    kept_note(rep)
