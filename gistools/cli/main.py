"""``gistools``: the command group and its error handling.

Expected failures (bad input, missing CRS, existing outputs) print one line that
names the file, the problem and the fix, and exit with status 1; no traceback.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading

import click

from .. import __version__
from ..errors import Cancelled, GistoolsError
from ..parameters import ENV, speaks
from ..progress import request_interrupt


_INTERRUPTS = {"n": 0, "signal": signal.SIGINT}
INTERRUPTED = "gistools: interrupted; complete outputs are kept, no partial file is left under a final name (rerun to resume)"


def _on_sigint(signum, frame):
    """Ctrl-C: the first one stops the run (KeyboardInterrupt); a second one while it cleans up is counted, not
    raised, so the clean-up completes; a third one raises again. The count makes sure the run ends with 130 even
    when a library swallowed the KeyboardInterrupt."""
    _INTERRUPTS["n"] += 1
    _INTERRUPTS["signal"] = signum or signal.SIGINT
    request_interrupt()
    if _INTERRUPTS["n"] != 2:
        raise KeyboardInterrupt


def _status() -> int:
    """The exit status of an interrupted run: 128 + the signal (130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP)."""
    return 128 + int(_INTERRUPTS["signal"])


# what ends a run besides Ctrl-C: a scheduler or `timeout` (SIGTERM), a closed terminal (SIGHUP); Windows has neither
STOP_SIGNALS = [getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)]
# seconds a stopped run has to end by itself (KeyboardInterrupt, its clean-up) before the watchdog ends it: a run
# inside one long call of compiled code (the kernel, GDAL, a numpy operation) meets Python's handler only after it
GRACE = 3.0
_ENDED = threading.Event()


def arm_stop_watchdog() -> None:
    """End the process at most GRACE seconds after a stop signal, whatever it is doing: the signal is also written
    to a socket (``signal.set_wakeup_fd``, by the interpreter's own C handler, while the main thread may be inside
    compiled code); a thread waiting on it gives the run GRACE seconds, then prints the one line, puts the folders
    of this process back (gistools.io.outdir.abandon: step reruns restored, partial files and the lock removed)
    and exits with 128 + the signal. Compiled code that holds the interpreter's lock throughout delays it until
    that call returns."""
    import socket

    if threading.current_thread() is not threading.main_thread():
        return
    try:
        reader, writer = socket.socketpair()
        writer.setblocking(False)
        signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
    except (OSError, ValueError):  # no socket pair here: the handlers alone stop the run
        return
    stops = {int(s) for s in STOP_SIGNALS}

    def watch():
        while True:
            try:
                data = reader.recv(64)
            except OSError:
                return
            signum = next((b for b in data if b in stops), None)
            if signum is None:
                continue
            if _ENDED.wait(GRACE):
                return
            _hard_stop(signum)

    threading.Thread(target=watch, name="gistools-stop-watchdog", daemon=True).start()
    _WATCH["socks"] = (reader, writer)


_WATCH: dict = {}


def _hard_stop(signum: int) -> None:
    from ..io.outdir import abandon

    try:
        sys.stderr.write(INTERRUPTED + "\n")
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    try:
        abandon()
    finally:
        os._exit(128 + int(signum))


def one_line(text: str, longest: int = 160) -> str:
    """An error as one line of bounded length: line breaks as spaces, and a word longer than ``longest`` characters
    (a pasted value, a path of thousands of characters) cut to its ends with the count of what was left out."""
    import re

    def cut(m):
        word = m.group(0)
        return f"{word[:longest // 2]}...({len(word) - longest:,} characters)...{word[-longest // 2:]}"

    return re.sub(r"\S{%d,}" % (longest + 40), cut, " ".join(str(text).split()))


class GistoolsGroup(click.Group):
    def list_commands(self, ctx):
        from ..parameters import DECLARED

        return sorted({*self.commands, *COMMANDS, *DECLARED})

    def get_command(self, ctx, name):
        from ..parameters import DECLARED

        if name not in self.commands and name in COMMANDS:
            import importlib

            module, attr = COMMANDS[name]
            self.add_command(getattr(importlib.import_module(f"{__package__}.{module}"), attr), name)
        elif name not in self.commands and name in DECLARED:  # made from its declaration (cli/declared.py)
            from .declared import declared_command

            self.add_command(declared_command(name), name)
        return self.commands.get(name)

    def invoke(self, ctx):
        with speaks("cli"):  # library messages name parameters by their flags (gistools.parameters)
            return self._invoke(ctx)

    def _invoke(self, ctx):
        try:
            from ..projdata import ensure_proj_data

            words = [*(getattr(ctx, "_protected_args", None) or getattr(ctx, "protected_args", [])), *ctx.args]
            if not {"--help", "-h"} & set(words):  # a help page reads nothing (and starts without PROJ)
                ensure_proj_data()  # once, before a command reads anything: a missing PROJ is one line
            value = super().invoke(ctx)
        except Cancelled as err:
            click.echo(f"gistools: {err}", err=True)
            sys.exit(_status())
        except GistoolsError as err:
            if _INTERRUPTS["n"]:
                click.echo(INTERRUPTED, err=True)
                sys.exit(_status())
            click.echo(f"gistools: error: {one_line(str(err))}", err=True)
            sys.exit(1)
        except KeyboardInterrupt:
            click.echo(INTERRUPTED, err=True)
            sys.exit(_status())
        except SystemExit:
            if _INTERRUPTS["n"]:
                click.echo(INTERRUPTED, err=True)
                sys.exit(_status())
            raise
        except MemoryError as err:  # outside a tile loop (which names the tile): the machine's error, in one line
            if isinstance(err, GistoolsError):
                raise
            from ..engine.batch import out_of_memory

            error = out_of_memory(f"in gistools {ctx.invoked_subcommand}",
                                  fix="Raise the limit (ulimit -v) or run on a machine with more memory")
            click.echo(f"gistools: error: {error}", err=True)
            sys.exit(1)
        except OSError as err:  # an output that cannot be written, met outside the checked writes
            from ..io.atomic import output_error

            known = output_error(err, getattr(err, "filename", None) or ".")
            if known is None:
                raise
            click.echo(f"gistools: error: {known}", err=True)
            sys.exit(1)
        if _INTERRUPTS["n"]:  # a Ctrl-C some library swallowed ("Exception ignored ..."): still an interrupt
            click.echo(INTERRUPTED, err=True)
            sys.exit(_status())
        return value


def _print_version(ctx, _param, value) -> None:
    """``gistools --version``: the version and the engine that runs (a failed kernel build shows). The kernel (and
    numpy) is imported only here, not for every command's start."""
    if not value or ctx.resilient_parsing:
        return
    from .. import kernel

    click.echo(f"gistools, version {__version__}\nengine: {kernel.engine()}")
    ctx.exit()


@click.group(cls=GistoolsGroup)
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the version and the engine that runs, and exit.")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose):
    """Open tools for LiDAR (ground and noise classes, DSM / DEM / nDSM, the shrub density chain), aquifer models,
    runway earthworks and structure reconstruction."""
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(verbose, 2)]
    # the handler itself has the level asked for: a library that sets its own loggers' level (distributed sets
    # INFO when imported) prints at -v, as gistools' own messages do, not on every run
    handler = logging.StreamHandler()
    handler.setLevel(level)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logging.basicConfig(level=level, handlers=[handler])
    if verbose < 2:  # laspy logs a broken file's decoding error before raising it; gistools reports it, once
        logging.getLogger("laspy").setLevel(logging.CRITICAL)


def _commands() -> dict:
    """{command: (its module in gistools.cli, its function)} from the declarations (``command(..., cli=...)``; a
    sub-command names its group), and ``examples``, which takes no option. A command's module (and the libraries it
    needs) is imported only when that command runs, or when --help lists them all, so `gistools rasters` does not
    wait for geopandas."""
    from ..parameters import COMMAND_LINE

    found = {name.split()[0]: tuple(where.split(":")) for name, where in COMMAND_LINE.items()}
    return {**found, "examples": ("examples", "examples")}


COMMANDS = _commands()


def all_commands() -> dict:
    """{name: click command} of every command of ``gistools`` (each module imported)."""
    return {name: cli.get_command(None, name) for name in cli.list_commands(None)}


def main():  # console_scripts entry point
    from ..engine.batch import keep_freed_memory, worker_thread_environment

    os.environ.setdefault(ENV, "cli")  # the workers this process starts name parameters by their flags too
    keep_freed_memory()  # tile after tile in this process: reuse the freed arrays (engine/batch.py)
    worker_thread_environment()  # the workers this process spawns start with one BLAS thread
    if threading.current_thread() is threading.main_thread():
        for signum in STOP_SIGNALS:  # each cleans up as Ctrl-C does: the folder as it was, the lock and scratch gone
            signal.signal(signum, _on_sigint)
        arm_stop_watchdog()
    try:
        cli(prog_name="gistools")
    except KeyboardInterrupt:  # outside a command (start-up, argument parsing)
        click.echo(INTERRUPTED, err=True)
        sys.exit(_status())
    finally:
        from ..engine.batch import join_workers

        try:
            join_workers()  # no worker of the command outlives it (a script or a scheduler waits for the group)
        except KeyboardInterrupt:  # the interrupt was reported: the exit status stays 128 + the signal
            if not _INTERRUPTS["n"]:
                raise
        finally:
            _ENDED.set()


if __name__ == "__main__":
    main()
