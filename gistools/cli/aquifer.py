"""``gistools aquifer``: layer contacts to a 3D aquifer model (``model``), and heights / thickness at a point (``query``)."""

from __future__ import annotations

from json import dumps

import click

from ..parameters import option, render
from .options import folder_command, kept_note, progress_bar
from .spec import spec_options


def parse_fields(value, names: str, example: str) -> dict | None:
    """``--fields`` (field=column pairs, declared once as gistools.parameters' ``fields``) as the library takes it:
    {field: column}, the fields among ``names``."""
    if not value:
        return None
    pairs = [p.split("=", 1) for p in value.split(",") if p.strip()]
    if any(len(p) != 2 or not p[1].strip() for p in pairs):
        raise click.BadParameter(f"{value!r}: write field=column pairs, e.g. {example}", param_hint="'--fields'")
    wrong = sorted({k.strip() for k, _ in pairs} - set(names.split(",")))
    if wrong:
        raise click.BadParameter(f"{', '.join(wrong)}: the fields are {names}", param_hint="'--fields'")
    return {k.strip(): v.strip() for k, v in pairs}


@click.group()
def aquifer():
    """Aquifer model from borehole layer contacts (dissertation ch. 8)."""


def _print_model(rep: dict) -> None:
    """The model's summary: each layer's points and surface, each unit's volume and thickness."""
    for layer, info in rep["layers"].items():
        click.echo(f"{layer}: {info['points']} points ({info['flagged']} flagged), {info['triangles']} triangles, "
                   f"boundary {info['boundary_vertices']} vertices, area {info['boundary_area']:,.0f} square "
                   f"{rep['length_unit']}")
    for name, u in rep["units"].items():
        click.echo(f"{name}: volume {u['volume']:,.0f} (+{u['volume_positive']:,.0f} / {u['volume_negative']:,.0f}) "
                   f"{rep['volume_unit']}; thickness min / mean / max {u['thickness_min']:.2f} / {u['thickness_mean']:.2f} / "
                   f"{u['thickness_max']:.2f} {rep['length_unit']}")
        if u["crossing_area"] > 0 or u["crossing_volume"] > 0:
            click.echo(f"  the {u['lower']} surface is above {u['upper']} on {u['crossing_area']:,.0f} square "
                       f"{rep['length_unit']} ({u['crossing_volume']:,.0f} {rep['volume_unit']}): "
                       + {"isopach": "the unit's thickness is its boreholes' (isopach), never below 0 "
                                     f"({render(option('order', 'stratigraphic'))})",
                          "clipped": f"thickness 0 there ({render(option('order', 'stratigraphic'))})",
                          "raw": f"counted negative ({render(option('order', 'raw'))})"}[u["thickness_method"]])


@folder_command("aquifer model", click.argument("inputs", nargs=-1, required=True), group=aquifer)
def model(inputs, out, overwrite, quiet, layers, crs, swap_xy, within, clip, fields, no_figures, **settings):
    """Cleaned TIN surfaces, boundaries, walls, closed unit meshes, thickness and volumes.

    INPUTS is one table (CSV or point layer: id, x, y, z, layer[, borehole_id]) or one file per
    layer as LAYER=path (the dissertation's ID East North Height files).

    \b
    Examples:
      $ gistools aquifer model contacts.csv --layers LS,AU,AD,AQ --crs EPSG:3003 --out milan
      $ gistools aquifer model LS=LSInput.txt AU=AUInput.txt AD=ADInput.txt AQ=AQInput.txt \\
          --layers LS,AU,AD,AQ --crs EPSG:3003 --swap-xy --out milan --within area.gpkg:AREA
    """
    from ..io.contacts import is_layer_file
    from ..products.aquifer import AquiferSettings, aquifer_model

    names = [s.strip() for s in layers.split(",") if s.strip()]
    settings["cell_size"] = settings.pop("thickness_cell_size")
    settings = AquiferSettings(figures=not no_figures, **{k: v for k, v in settings.items() if v is not None})
    fields = parse_fields(fields, "id,x,y,z,layer,borehole_id", "z=ELEV,layer=FORMATION")
    source = list(inputs) if any(is_layer_file(i) for i in inputs) else inputs[0]
    with progress_bar(quiet) as progress:
        rep = aquifer_model(source, names, out, crs=crs, swap_xy=swap_xy, settings=settings, within=within, clip=clip,
                            overwrite=overwrite, progress=progress, fields=fields)
    _print_model(rep)
    click.echo(f"report: {out}/report.json")
    kept_note(rep)


@aquifer.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@spec_options("aquifer query")
@click.option("--json", is_flag=True, help="The answer as JSON.")
def query(out, x, y, height_method, k, json):
    """Height of each surface and thickness of each unit at X, Y of the model in OUT.

    \b
    Example:
      $ gistools aquifer query milan --x 1517365 --y 5031638 --method knn --k 10
    """
    from ..products.aquifer import aquifer_query

    result = aquifer_query(out, x, y, height_method, **({} if k is None else {"k": k}))
    if json:
        click.echo(dumps(result, indent=2))
        return
    for layer, h in result["heights"].items():
        z = "outside" if h["z"] is None else f"{h['z']:.3f}"
        click.echo(f"{layer}: {z}{'' if h['inside'] else ' (outside the boundary: extrapolated)' if h['z'] is not None else ''}")
    for name, t in result["thickness"].items():
        click.echo(f"{name}: thickness {'n/a' if t is None else f'{t:.3f}'}")
