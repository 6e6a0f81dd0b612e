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


class GistoolsGroup(click.Group):
    def invoke(self, ctx):
        with speaks("cli"):  # library messages name parameters by their flags (gistools.parameters)
            return self._invoke(ctx)

    def _invoke(self, ctx):
        try:
            value = super().invoke(ctx)
        except Cancelled as err:
            click.echo(f"gistools: {err}", err=True)
            sys.exit(_status())
        except GistoolsError as err:
            if _INTERRUPTS["n"]:
                click.echo(INTERRUPTED, err=True)
                sys.exit(_status())
            click.echo(f"gistools: error: {err}", err=True)
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


def _version_line() -> str:
    """What ``gistools --version`` prints: the version and the engine that runs (a failed kernel build shows)."""
    from .. import kernel

    return f"%(prog)s, version %(version)s\nengine: {kernel.engine()}"


VERSION_LINE = _version_line()


@click.group(cls=GistoolsGroup)
@click.version_option(__version__, prog_name="gistools", message=VERSION_LINE)
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
def cli(verbose):
    """Open tools for LiDAR (ground and noise classes, DSM / DEM / nDSM, the shrub density chain), aquifer models,
    runway earthworks and structure reconstruction."""
    logging.basicConfig(level=[logging.WARNING, logging.INFO, logging.DEBUG][min(verbose, 2)],
                        format="%(levelname)s %(name)s: %(message)s")
    if verbose < 2:  # laspy logs a broken file's decoding error before raising it; gistools reports it, once
        logging.getLogger("laspy").setLevel(logging.CRITICAL)


from . import ground as _ground  # noqa: E402
from . import chm as _chm  # noqa: E402
from . import deliver as _deliver  # noqa: E402
from . import info as _info  # noqa: E402
from . import metrics as _metrics  # noqa: E402
from . import fuels as _fuels  # noqa: E402
from . import normalize as _normalize  # noqa: E402
from . import rasters as _rasters  # noqa: E402
from . import points as _points  # noqa: E402
from . import shrub as _shrub  # noqa: E402
from . import aquifer as _aquifer  # noqa: E402
from . import runway as _runway  # noqa: E402
from . import structure as _structure  # noqa: E402
from . import examples as _examples  # noqa: E402

cli.add_command(_info.info)
cli.add_command(_ground.ground)
cli.add_command(_rasters.rasters)
cli.add_command(_normalize.normalize)
cli.add_command(_metrics.metrics)
cli.add_command(_chm.chm)
cli.add_command(_fuels.fuels)
cli.add_command(_deliver.webmap)
cli.add_command(_deliver.scene)
cli.add_command(_deliver.mapbook)
cli.add_command(_aquifer.aquifer)
cli.add_command(_runway.runway)
cli.add_command(_structure.structure)
cli.add_command(_examples.examples)
for _command in (_shrub.shrub, _points.points, _shrub.bands, _shrub.clip, _shrub.density, _shrub.classify, _shrub.map_):
    cli.add_command(_command)


def main():  # console_scripts entry point
    from ..engine.batch import keep_freed_memory, worker_thread_environment

    os.environ.setdefault(ENV, "cli")  # the workers this process starts name parameters by their flags too
    keep_freed_memory()  # tile after tile in this process: reuse the freed arrays (engine/batch.py)
    worker_thread_environment()  # the workers this process spawns start with one BLAS thread
    if threading.current_thread() is threading.main_thread():
        for signum in STOP_SIGNALS:  # each cleans up as Ctrl-C does: the folder as it was, the lock and scratch gone
            signal.signal(signum, _on_sigint)
    try:
        cli(prog_name="gistools")
    except KeyboardInterrupt:  # outside a command (start-up, argument parsing)
        click.echo(INTERRUPTED, err=True)
        sys.exit(_status())
    finally:
        from ..engine.batch import join_workers

        join_workers()  # no worker of the command outlives it (a script or a scheduler waits for the group)


if __name__ == "__main__":
    main()
