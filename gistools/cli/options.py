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
