"""``gistools aquifer``: layer contacts to a 3D aquifer model (``model``), and heights / thickness at a point (``query``)."""

from __future__ import annotations

import json

import click

from ..tasks.aquifer import AquiferSettings, aquifer_model, aquifer_query
from .options import fields_opt, overwrite_opt, progress_bar


@click.group()
def aquifer():
    """Aquifer model from borehole layer contacts (dissertation ch. 8)."""


@aquifer.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("--layers", required=True, help="Layer names top to bottom, e.g. LS,AU,AD,AQ.")
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--crs", default=None, help="CRS of the contacts (EPSG:3003 for the Milan data) when the file has none.")
@click.option("--swap-xy", is_flag=True, help="Swap x and y (the dissertation labels East as North).")
@click.option("--within", default=None, help="Polygon layer: volumes and thickness statistics inside it.")
@click.option("--clip", default=None, help="Polygon layer the surfaces are cut to (concave outline, holes).")
@click.option("--concave", "concave_ratio", type=float, default=None,
              help="Cut each surface to the concave hull of its points (shapely ratio 0-1); default convex.")
@click.option("--xy-tol", default="0.5m", show_default=True, help="Duplicates: same position within this.")
@click.option("--k", "k", default=12, show_default=True, help="Neighbours of the outlier plane fit.")
@click.option("--abs-thr", default="8m", show_default=True, help="Outliers: smallest residual threshold.")
@click.option("--c", "c", default=5.0, show_default=True, help="Outliers: threshold = max(abs-thr, c x 1.4826 MAD).")
@click.option("--f-nn", default=5.0, show_default=True, help="Outside the cloud: NN distance over f-nn x the median.")
@click.option("--order-tol", default="1m", show_default=True, help="Report points beyond a neighbour layer by more than this.")
@click.option("--n-per-edge", default=2, show_default=True, help="Densified points per TIN edge.")
@click.option("--densify", is_flag=True, help="Write the densified points (densified_<layer>.csv).")
@click.option("--cell-size", default=None, help="Thickness raster cell (default: about 500 cells across).")
@click.option("--matching", type=click.Choice(["3d", "2d"]), default="3d", show_default=True)
@click.option("--mesh", "mesh_format", type=click.Choice(["ply", "obj"]), default="ply", show_default=True)
@click.option("--no-figures", is_flag=True, help="Skip the PNG figures.")
@click.option("--order", type=click.Choice(["stratigraphic", "raw"]), default="stratigraphic", show_default=True,
              help="stratigraphic: a lower surface is never above the one above it (a unit that pinches out has thickness 0, "
                   "not negative); raw: the TINs as they are. The crossing's area and volume are reported either way.")
@fields_opt("id,x,y,z,layer,borehole_id", "z=ELEV,layer=FORMATION")
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True)
def model(inputs, layers, out, crs, swap_xy, within, clip, concave_ratio, xy_tol, k, abs_thr, c, f_nn, order_tol,
          n_per_edge, densify, cell_size, matching, mesh_format, no_figures, order, fields, overwrite, quiet):
    """Cleaned TIN surfaces, boundaries, walls, closed unit meshes, thickness and volumes.

    INPUTS is one table (CSV or point layer: id, x, y, z, layer[, borehole_id]) or one file per
    layer as LAYER=path (the dissertation's ID East North Height files).

    \b
    Examples:
      $ gistools aquifer model contacts.csv --layers LS,AU,AD,AQ --crs EPSG:3003 --out milan
      $ gistools aquifer model LS=LSInput.txt AU=AUInput.txt AD=ADInput.txt AQ=AQInput.txt \\
          --layers LS,AU,AD,AQ --crs EPSG:3003 --swap-xy --out milan --within area.gpkg:AREA
    """
    names = [s.strip() for s in layers.split(",") if s.strip()]
    settings = AquiferSettings(xy_tol=xy_tol, k=k, abs_thr=abs_thr, c=c, f_nn=f_nn, order_tol=order_tol,
                               concave_ratio=concave_ratio, n_per_edge=n_per_edge, densify=densify, cell_size=cell_size,
                               matching=matching,
                               mesh_format=mesh_format, figures=not no_figures, order=order)
    source = list(inputs) if any("=" in i for i in inputs) else inputs[0]
    with progress_bar(quiet) as progress:
        rep = aquifer_model(source, names, out, crs=crs, swap_xy=swap_xy, settings=settings, within=within, clip=clip,
                            overwrite=overwrite, progress=progress, fields=fields)
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
                       + {"isopach": "the unit's thickness is its boreholes' (isopach), never below 0 (--order stratigraphic)",
                          "clipped": "thickness 0 there (--order stratigraphic)",
                          "raw": "counted negative (--order raw)"}[u["thickness_method"]])
    click.echo(f"report: {out}/report.json")


@aquifer.command()
@click.argument("out", type=click.Path(exists=True, file_okay=False))
@click.option("--x", "x", type=float, required=True)
@click.option("--y", "y", type=float, required=True)
@click.option("--method", type=click.Choice(["tin", "knn", "idw"]), default="tin", show_default=True)
@click.option("--k", "k", default=10, show_default=True, help="Neighbours for knn / idw.")
@click.option("--json", "as_json", is_flag=True)
def query(out, x, y, method, k, as_json):
    """Height of each surface and thickness of each unit at X, Y of the model in OUT.

    \b
    Example:
      $ gistools aquifer query milan --x 1517365 --y 5031638 --method knn --k 10
    """
    result = aquifer_query(out, x, y, method, k=k)
    if as_json:
        click.echo(json.dumps(result, indent=2))
        return
    for layer, h in result["heights"].items():
        z = "outside" if h["z"] is None else f"{h['z']:.3f}"
        click.echo(f"{layer}: {z}{'' if h['inside'] else ' (outside the boundary: extrapolated)' if h['z'] is not None else ''}")
    for name, t in result["thickness"].items():
        click.echo(f"{name}: thickness {'n/a' if t is None else f'{t:.3f}'}")
