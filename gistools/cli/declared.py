"""The command-line command of a command declared whole (gistools.parameters.core.command with ``inputs``): its
arguments, its options and its help from the declaration, one call of its library function, one line of what
it wrote. A new command of this kind needs no module here."""

from __future__ import annotations

import importlib

import click

from ..parameters import DECLARED, LIBRARY, PARAMETERS
from .options import out_opt, progress_bar
from .spec import spec_options


def library_function(name: str):
    """The library function declared for command ``name``."""
    module, function = LIBRARY[name][0].split(":")
    return getattr(importlib.import_module(f"gistools.{module}"), function)


def declared_command(name: str) -> click.Command:
    """The click command of the declared command ``name``."""
    spec = DECLARED[name]
    inputs = [keyword for keyword, _kind, _label in spec["inputs"]]

    def run(quiet, out, **values):
        args = [values.pop(keyword) for keyword in inputs]
        given = {PARAMETERS[p].python_name: PARAMETERS[p].library_value(value) for p, value in values.items()
                 if value is not None}
        with progress_bar(quiet) as progress:
            report = library_function(name)(*args, out, **given, progress=progress)
        kept = report.get("kept") or []
        made = [k for k in report.get("outputs", {}) if k not in kept]
        parts = [f"{', '.join(made)} written"] if made else []
        if kept:
            parts.append(f"{', '.join(kept)} kept (made before with these settings; --overwrite remakes them)")
        click.echo("; ".join(parts + [f"report: {out}/report.json"]))
        for warning in report.get("warnings", []):
            click.echo(f"warning: {warning}", err=True)

    arguments = " ".join(k.upper() for k in inputs)
    run.__doc__ = (f"{spec['summary']}\n\n{arguments}: "
                   + "; ".join(f"{label}" for _k, _kind, label in spec["inputs"])
                   + f". Writes the outputs and OUT/report.json.\n\n\b\nExample:\n  $ gistools {name} "
                   + " ".join(f"{k}.tif" for k in inputs) + f" --out {name.replace('-', '_')}")
    command = click.option("--quiet", "-q", is_flag=True, help="No progress bar.")(run)
    command = spec_options(name)(command)
    command = out_opt("Output folder (the rasters and report.json).")(command)
    for keyword in reversed(inputs):
        command = click.argument(keyword, type=click.Path(exists=True))(command)
    return click.command(name=name, help=run.__doc__, short_help=spec["summary"])(command)
