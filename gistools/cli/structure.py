"""``gistools structure``: a building's point cloud to levels, loops, matched walls and a closed mesh."""

from __future__ import annotations

import click

from ..tasks.structure import structure_model
from .options import overwrite_opt, progress_bar


def _triple(ctx, param, value):
    try:
        parts = tuple(float(v) for v in value.split(","))
    except ValueError:
        parts = ()
    if len(parts) != 3:
        raise click.BadParameter(f"{value!r} is not three comma-separated numbers")
    return parts


@click.command()
@click.argument("source")
@click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--height-interval", "h", type=float, default=None, help="Largest height step between consecutive levels, m (default: estimated).")
@click.option("--distance", "d", type=float, default=None, help="Planimetric distance joining points into a cluster, m (default: estimated).")
@click.option("--tolerance", "t", type=float, default=None, help="Planimetric tolerance of matching and of the chain / sown split, m (default 4).")
@click.option("--columns", default="123", show_default=True, help="Which input columns are x, y, z (213 swaps x and y).")
@click.option("--scales", callback=_triple, default="1,1,1", show_default=True, help="Signed scale per axis.")
@click.option("--rotations", callback=_triple, default="0,0,0", show_default=True, help="Degrees about x, y, z.")
@click.option("--loop-mode", type=click.Choice(["classic", "catmull-rom"]), default="classic", show_default=True,
              help="catmull-rom: also write the dissertation's Catmull-Rom loops (new points and lines).")
@overwrite_opt
@click.option("--quiet", "-q", is_flag=True)
def structure(source, out, h, d, t, columns, scales, rotations, loop_mode, overwrite, quiet):
    """Closed 3D mesh of a structure from SOURCE, "ID X Y Z" rows (text / CSV) or a LAS/LAZ file:
    levels by height, clusters by distance, floor plates ("sown") and outlines ("chain"), loops with
    holes, matched walls, and the watertight envelope (PLY, OBJ), with the loops as a GeoPackage.

    \b
    Examples:
      $ gistools structure cctv.txt --out cctv
      $ gistools structure cctv.txt --out cctv --height-interval 8 --distance 15 --tolerance 4
    """
    with progress_bar(quiet) as progress:
        rep = structure_model(source, out, h=h, d=d, t=t, columns=columns, scales=scales, rotations=rotations,
                              loop_mode=loop_mode, overwrite=overwrite, progress=progress)
    p = rep["parameters"]
    click.echo(f"{rep['levels']} levels, {rep['clusters']} clusters ({rep['sowns']} sown, {rep['chains']} chain), "
               f"{rep['matched_pairs']} matched pairs; h {p['height_interval']:.3f}, d {p['distance']:.3f}, t {p['tolerance']:.3f} m")
    click.echo(f"mesh: {rep['triangles']} triangles, volume {rep['volume']:,.1f} m3, area {rep['surface_area']:,.1f} m2, "
               f"watertight {rep['watertight']}, Euler {rep['euler']}; report: {out}/report.json")
