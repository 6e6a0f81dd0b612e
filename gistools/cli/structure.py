"""``gistools structure``: a building's point cloud to levels, loops, matched walls and a closed mesh."""

from __future__ import annotations

import click

from .options import folder_command, kept_note, progress_bar


@folder_command("structure", click.argument("source"))
def structure(source, out, h, d, t, columns, scales, rotations, loop_mode, overwrite, quiet):
    """Closed 3D mesh of a structure from SOURCE, "ID X Y Z" rows (text / CSV) or a LAS/LAZ file:
    levels by height, clusters by distance, floor plates ("sown") and outlines ("chain"), loops with
    holes, matched walls, and the watertight envelope (PLY, OBJ), with the loops as a GeoPackage.

    \b
    Examples:
      $ gistools structure cctv.txt --out cctv
      $ gistools structure cctv.txt --out cctv --height-interval 8 --distance 15 --tolerance 4
    """
    from ..products.structure import structure_model

    with progress_bar(quiet) as progress:
        rep = structure_model(source, out, h=h, d=d, t=t, columns=columns, scales=scales, rotations=rotations,
                              loop_mode=loop_mode, overwrite=overwrite, progress=progress)
    p = rep["parameters"]
    click.echo(f"{rep['levels']} levels, {rep['clusters']} clusters ({rep['sowns']} sown, {rep['chains']} chain), "
               f"{rep['matched_pairs']} matched pairs; h {p['height_interval']:.3f}, d {p['distance']:.3f}, t {p['tolerance']:.3f} m")
    click.echo(f"mesh: {rep['triangles']} triangles, volume {rep['volume']:,.1f} m3, area {rep['surface_area']:,.1f} m2, "
               f"watertight {rep['watertight']}, Euler {rep['euler']}; report: {out}/report.json")
    kept_note(rep)
