"""``gistools examples DIR``: the example inputs of the README's commands."""

from __future__ import annotations

import click


@click.command()
@click.argument("folder", type=click.Path(file_okay=False))
def examples(folder):
    """Write example inputs for every command the README shows into FOLDER (made if missing; files already
    there are kept): sample_tiles/ (LAS/LAZ tiles and breaklines.gpkg), tiles/ (LAZ), contacts.csv and
    LSInput.txt ... AQInput.txt (aquifer), area.gpkg, survey.csv (runway), cctv.txt and scan.txt (structures).

    \b
    Example:
      $ gistools examples try && cd try && gistools info sample_tiles
    """
    from ..datasets.examples import write_examples

    written = write_examples(folder)
    click.echo(f"example inputs in {folder}: {', '.join(written)}")
