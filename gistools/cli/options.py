"""Options shared by several commands, defined once."""

import click

overwrite_opt = click.option("--overwrite", is_flag=True, help="Replace existing outputs (default: keep them and skip the tile).")
jobs_opt = click.option("--jobs", "-j", type=click.IntRange(1), default=1, show_default=True,
                        help="Tiles processed in parallel (local processes).")
crs_opt = click.option("--crs", default=None, help="CRS of the tiles (EPSG:2882, WKT): required when a header has none; overrides the header's otherwise.")
chunk_opt = click.option("--chunk-size", type=click.IntRange(1), default=2_000_000, show_default=True,
                         help="Points read at a time; memory grows with it (about 60 bytes per point).")


def parse_classes(ctx, param, value):
    """'1,2' -> (1, 2); None stays None."""
    if value is None:
        return None
    try:
        classes = tuple(int(v) for v in str(value).replace(" ", "").split(",") if v != "")
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a list of class codes; write e.g. 1,2") from None
    if not classes or any(not 0 <= c <= 255 for c in classes):
        raise click.BadParameter(f"{value!r}: class codes are integers 0-255, e.g. 1,2")
    return classes
