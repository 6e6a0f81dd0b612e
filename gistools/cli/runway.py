"""``gistools runway``: a runway survey and the ICAO reference code to sections, areas and mass haul."""

from __future__ import annotations

import click

from ..errors import GistoolsError
from ..runway.icao import RUNWAY_TYPES, TEMPLATES
from ..runway.survey import SurveyChecks
from ..tasks.runway import RunwaySettings, runway_earthworks
from .options import fields_opt, overwrite_opt, progress_bar


def _metres(ctx, param, value):
    """A length with its unit ("10m", "30ft", "32.8ftUS", or a bare number in metres) in metres, through units.py
    (the ICAO template and the survey's CRS are in metres)."""
    if value is None:
        return None
    from ..units import METRE, LinearUnit, length_to_crs_units

    try:
        return length_to_crs_units(value, LinearUnit("metre", METRE), name=f"--{param.name.replace('_', '-')}")
    except GistoolsError as err:
        raise click.BadParameter(str(err)) from None


@click.command()
@click.argument("survey")
@click.option("--code", default="4E", show_default=True, help="Aerodrome reference code (1A ... 4F).")
@click.option("--runway-type", type=click.Choice(RUNWAY_TYPES), default="precision", show_default=True)
@click.option("--template", "template_kind", type=click.Choice(TEMPLATES), default="icao", show_default=True,
              help="icao: Annex 14 half-widths; dissertation: its widths read as offsets (45 / 52.5 / 75 / 150 m).")
@click.option("--spacing", callback=_metres, default=None, help="Station and lateral spacing, e.g. 10m (default: sqrt(area / points)).")
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--crs", default=None, help="CRS of the survey when the file has none (Orio al Serio: EPSG:3003).")
@click.option("--origin", type=click.Choice(["low", "high", "first"]), default="low", show_default=True,
              help="Chainage 0 at the low end, the high end, or the first light of the file.")
@click.option("--profile-window", default=1, show_default=True, help="Design grade: running mean of this many light heights (1: the lights themselves, the spec).")
@click.option("--swell", "f_cut", default=1.0, show_default=True, help="Factor on cut volumes (swell of dug material).")
@click.option("--compaction", "f_fill", default=1.0, show_default=True, help="Factor on fill volumes (compaction).")
@click.option("--free-haul", callback=_metres, default=None, help="Free-haul distance, e.g. 150m: reports the overhaul.")
@click.option("--areas", "area_method", type=click.Choice(["exact", "dissertation"]), default="exact", show_default=True,
              help="exact: signed, split where ground crosses design; dissertation: unsigned hull + Heron.")
@click.option("--max-offset", callback=_metres, default="1.0", show_default=True, help="Lights farther off the axis are anomalies.")
@click.option("--min-offset", callback=_metres, default="0.1", show_default=True,
              help="Lights closer to the axis are never anomalies, however high their robust z-score.")
@click.option("--z-max", default=3.5, show_default=True, help="Robust z-score limit of the checks.")
@fields_opt("id,type,x,y,z", "type=KIND,z=ELEV")
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True)
def runway(survey, code, runway_type, template_kind, spacing, out, crs, origin, profile_window, f_cut, f_fill, free_haul,
           area_method, max_offset, min_offset, z_max, fields, overwrite, quiet):
    """Cut and fill of a runway: SURVEY (id, type, x, y, z; type 1 = centre-line light, 2 = other) and the
    aerodrome reference code to a design model, cross sections, area diagram and Brueckner curve.

    \b
    Examples:
      $ gistools runway survey.csv --code 4E --crs EPSG:3003 --out orio
      $ gistools runway survey.gpkg:POINTS --code 4E --template dissertation --spacing 10m --out orio_diss
    """
    settings = RunwaySettings(code=code, runway_type=runway_type, template=template_kind, spacing=spacing, origin=origin,
                              profile_window=profile_window, f_cut=f_cut, f_fill=f_fill, free_haul=free_haul,
                              area_method=area_method, checks=SurveyChecks(z_max=z_max, max_offset=max_offset, min_offset=min_offset))
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
