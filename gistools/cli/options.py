"""Options shared by several commands, and the progress bar, defined once."""

import contextlib
import threading

import click
from tqdm import tqdm

# The bars are drawn by this process only (workers report through it): a thread lock is enough, and tqdm's default
# (a multiprocessing lock, a named semaphore) would keep multiprocessing's resource tracker alive past the command
tqdm.set_lock(threading.RLock())

BAR_FORMAT = "{l_bar}{bar}| {n:.0f}% [{elapsed}<{remaining}{postfix}]"


def tqdm_progress(bar: tqdm):
    """A progress callback driving a tqdm bar (0..1 -> 0..100 %)."""

    def progress(fraction, message=""):
        bar.n = round(100 * fraction, 1)
        bar.set_postfix_str(message[-70:], refresh=False)
        bar.refresh()
        return True

    return progress


@contextlib.contextmanager
def progress_bar(quiet: bool):
    """A tqdm bar for the block; yields the library's progress callback (None with --quiet or no terminal)."""
    with tqdm(total=100, unit="%", disable=True if quiet else None, bar_format=BAR_FORMAT) as bar:
        yield None if bar.disable else tqdm_progress(bar)

def _resume_or_overwrite(fn):
    fn = click.option("--resume", is_flag=True,
                      help="Keep complete outputs of an earlier (or killed) run and do the rest; this is the default.")(fn)
    return click.option("--overwrite", is_flag=True, help="Replace existing outputs (default: keep them, i.e. --resume).")(fn)


def overwrite_opt(fn):
    """--overwrite and --resume (the default); the command receives ``overwrite`` only."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, resume=False, **kwargs):
        if resume and kwargs.get("overwrite"):
            raise click.UsageError("--resume and --overwrite exclude each other")
        return fn(*args, **kwargs)

    return _resume_or_overwrite(wrapper)
def _folder(ctx, param, value):
    if value is not None and not str(value).strip():  # an unset variable ($OUT): never the current folder
        raise click.BadParameter("is empty: give the output folder, e.g. --out out")
    return value


def out_opt(help: str = "Output folder."):  # noqa: A002 - click's word
    """--out / -o: the output folder (an empty value is refused, not taken as the current folder)."""
    return click.option("--out", "-o", required=True, type=click.Path(file_okay=False), callback=_folder, help=help)




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


def batch_report(call):
    """The report of a batch call (``call()``); when every tile failed, the report the library's TilesFailed carries:
    the command prints it, each tile's error, and exits 1."""
    from ..errors import TilesFailed

    try:
        return call()
    except TilesFailed as err:
        return err.report


def finish_batch(report: dict, summary: str) -> None:
    """The end of a batch command: its summary line, a line per failed tile (on stderr), exit status 1 when any
    tile failed."""
    click.echo(summary)
    for tile in report.get("tiles", []):
        if tile.get("status") == "failed":
            click.echo(f"  FAILED {tile['error']}", err=True)
    if (report.get("counts") or {}).get("failed"):
        raise SystemExit(1)


def _ground_methods():
    from ..lidar.ground import GROUND_METHODS

    return list(GROUND_METHODS)


classify_ground_opt = click.option(
    "--classify-ground", type=click.Choice(_ground_methods()), default=None,
    help="For tiles without ground classes: classify ground and noise first (gistools ground, with its defaults) "
         "into OUT/classified/ and make the rasters from those.")


def dem_options(defaults):
    """--dem-method and --dem-max-distance, the same words in gistools rasters and gistools shrub."""
    from ..lidar.gridding import DEM_METHODS

    def apply(fn):
        fn = click.option("--dem-max-distance", default=defaults.dem_max_distance, show_default=True,
                          help="DEM cells farther than this from every ground point stay nodata (tin, idw).")(fn)
        return click.option("--dem-method", type=click.Choice(DEM_METHODS), default=defaults.dem_method, show_default=True,
                            help="tin: Delaunay of the ground points, at cell centres (fills gaps); max / min / mean: the "
                                 "highest / lowest / mean ground point of each cell (max is the dissertation's Point To "
                                 "Raster MAXIMUM; empty cells stay nodata); idw: inverse-distance weighted ground points "
                                 "within --dem-max-distance.")(fn)
    return apply


def fields_opt(names: str, example: str):
    """--fields: the columns of some fields where a table does not name them as usual (QGIS's field pickers)."""
    def parse(ctx, param, value):
        if not value:
            return None
        pairs = [p.split("=", 1) for p in value.split(",") if p.strip()]
        if any(len(p) != 2 or not p[1].strip() for p in pairs):
            raise click.BadParameter(f"{value!r}: write field=column pairs, e.g. {example}")
        wrong = sorted({k.strip() for k, _ in pairs} - set(names.split(",")))
        if wrong:
            raise click.BadParameter(f"{', '.join(wrong)}: the fields are {names}")
        return {k.strip(): v.strip() for k, v in pairs}
    return click.option("--fields", callback=parse, default=None,
                        help=f"Columns of the fields ({names}) where the table names them otherwise, e.g. {example}.")
