"""Options shared by several commands, and the progress bar, defined once."""

import contextlib
import os
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


def quiet_opt(fn):
    """--quiet / -q: no progress bar."""
    return click.option("--quiet", "-q", is_flag=True, help="No progress bar.")(fn)


def folder_command(name: str, *arguments, options=None, group=None):
    """A command that writes a folder, its front matter once: its ``arguments`` (click arguments), ``--out``, its
    declared options (``options``: ``spec_options`` or a wrapper of it, called with the command's name), ``--overwrite``
    / ``--resume`` and ``--quiet``; a command of ``group`` (a click group) when given."""

    def apply(fn):
        from .spec import spec_options

        fn = quiet_opt(fn)
        fn = overwrite_opt(fn)
        fn = (options or spec_options)(name, skip=("overwrite",))(fn)
        fn = out_opt()(fn)
        for argument in reversed(arguments):
            fn = argument(fn)
        return (group.command() if group else click.command())(fn)

    return apply


def tiles_command(name: str, options=None):
    """``folder_command`` of a command of tiles: INPUTS are files, folders, globs or a .vpc, or point cloud services
    (URLs of EPT datasets and COPC files) and local copies of them; with ``--aoi`` the command runs on the area's
    points (``gistools.Area``), fetched into ``--cache`` as tiles."""

    def apply(fn):
        return folder_command(name, click.argument("inputs", nargs=-1, required=True), options=options)(takes_area(fn))

    return apply


def takes_area(fn):
    """A command of tiles given the area of its INPUTS (``area_inputs``) where --aoi is given."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args, inputs, out, aoi=None, resolution=None, tile_size=None, cache=None, max_download=None,
                **keywords):
        inputs = area_inputs(inputs, out, keywords.get("quiet", False), aoi=aoi, resolution=resolution,
                             tile_size=tile_size, cache=cache, max_download=max_download,
                             margin=keywords.get("buffer") or ("30m" if "buffer" in keywords else 0))
        return fn(*args, inputs=inputs, out=out, **keywords)

    return wrapper


def area_inputs(inputs, out, quiet, *, aoi, margin=0, **area):
    """The command's INPUTS, or their area (``gistools.Area``, its cache OUT/fetched unless --cache says; ``margin``:
    what the command reads around a tile, its --buffer or 30 m) where --aoi is given; a service without --aoi, or an
    area's option without it, is refused."""
    from ..io.area import is_area_source

    if aoi is None:
        given = [k for k, v in area.items() if v is not None]
        if given:
            raise click.UsageError(f"--{given[0].replace('_', '-')} reads an area: give --aoi too")
        services = [i for i in inputs if is_area_source(i)]
        if services:
            raise click.UsageError(f"{services[0]} is a point cloud service read by area: give --aoi "
                                   "minx,miny,maxx,maxy (or a polygon layer)")
        return inputs
    from ..products.fetch import AREA_FOLDER, Area  # here: a run on files starts without the HTTP reader

    cache = area.pop("cache") or os.path.join(out, AREA_FOLDER)
    area_ = Area(tuple(inputs), aoi, cache, margin=margin, progress=fetch_progress(quiet), **area)
    area_.check()
    return area_


def fetch_progress(quiet: bool):
    """A progress callback drawing its own bar while an area's points are fetched (points and MB in its text)."""
    if quiet:
        return None
    bar = None

    def progress(fraction, message=""):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=100, unit="%", desc="fetching", bar_format=BAR_FORMAT, leave=False, disable=None)
        bar.n = round(100 * fraction, 1)
        bar.set_postfix_str(message[-70:], refresh=False)
        bar.refresh()
        if fraction >= 1:
            bar.close()
        return True

    return progress


def run_batch(quiet: bool, function, *args, **keywords) -> dict:
    """``function(*args, **keywords)`` of the library under a progress bar (``progress=`` added): its report, also
    when every tile failed (``batch_report``)."""
    with progress_bar(quiet) as progress:
        return batch_report(lambda: function(*args, **keywords, progress=progress))


def tiles_counted(report: dict, done: str = "done") -> str:
    """'4 tiles done, 0 skipped (outputs exist), 0 failed': the start of a batch command's summary line."""
    counts = report["counts"]
    return f"{counts['ok']} tiles {done}, {counts['skipped']} skipped (outputs exist), {counts['failed']} failed"


def kept_note(report: dict) -> None:
    """A line when a rerun kept the outputs of an earlier run with the same settings."""
    if report.get("kept"):
        click.echo("outputs kept: made before with these settings from the same inputs (--overwrite makes them again)")
