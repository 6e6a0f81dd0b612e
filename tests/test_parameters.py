"""One declaration of each parameter (gistools.parameters): the command line's options are made from it, and a
library error names the Python argument, the command line the flag (the QGIS side: tests/test_qgis.py)."""

from __future__ import annotations

import click
import pytest

from gistools.cli.main import cli
from gistools.errors import InputError
from gistools.parameters import COMMANDS, PARAMETERS, ByUnits, option, render, speaks
from gistools.parameters.core import COMMAND_DEFAULTS

# what a command's line has beside its settings: where the tiles and outputs are, how it runs in a terminal
STRUCTURAL = {"out", "quiet", "resume", "overwrite", "help", "inputs", "json"}


def _click_command(name):
    """The click command of a declared command ("aquifer model": a command of a group)."""
    command = cli
    for part in name.split():
        command = command.get_command(None, part)
    return command


def _click_params(name):
    command = _click_command(name)
    return {p.name: p for p in command.params if isinstance(p, click.Option)}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_option_of_a_command_comes_from_its_declaration(name):
    options = _click_params(name)
    declared = [n for n in COMMANDS[name] if n != "overwrite"]
    undeclared = sorted(set(options) - set(declared) - STRUCTURAL)
    assert not undeclared, f"gistools {name}: options declared outside gistools.parameters: {undeclared}"
    for n in declared:
        p, o = PARAMETERS[n], options[n]
        assert p.cli_flag in o.opts
        assert o.help.startswith(p.help_text("cli")), n
        if p.kind == "choice":
            assert list(o.type.choices) == list(p.choices) + list(p.aliases)
        default = COMMAND_DEFAULTS.get(name, {}).get(n, p.default)
        if default is not None and not isinstance(default, ByUnits):
            shown = default if not isinstance(default, tuple) else ",".join(map(str, default))
            assert o.default == shown, n
        if isinstance(default, ByUnits):  # no click default: the data's unit decides, as the help says
            assert (o.default is None or "UNSET" in repr(o.default)) and default.text() in o.help, n


def test_a_message_names_the_parameter_as_its_reader_speaks():
    text = f"{option('cell_size')} 'x' is not a length. Give e.g. {option('cell_size', '5ft')}; or {option('overwrite')}"
    assert render(text, "python") == "cell_size 'x' is not a length. Give e.g. cell_size='5ft'; or overwrite=True"
    assert render(text, "cli") == "--cell-size 'x' is not a length. Give e.g. --cell-size 5ft; or --overwrite"
    with speaks("qgis", {"cell_size": "Cell size (with unit: m, ft, ftUS)"}):
        assert str(InputError(text)).startswith("'Cell size (with unit: m, ft, ftUS)' 'x' is not a length")


def test_a_library_error_names_the_python_argument_and_the_command_line_the_flag(tmp_path):
    from click.testing import CliRunner

    from gistools.products.rasters import RasterSettings

    with pytest.raises(InputError) as err:
        RasterSettings(cell_size="-5ft").validate()
    assert "cell_size" in str(err.value) and "--" not in str(err.value)
    run = CliRunner().invoke(cli, ["rasters", "sample_tiles", "--out", str(tmp_path / "o"), "--cell-size", "-5ft"])
    assert run.exit_code != 0 and "--cell-size '-5ft' must be a finite length" in run.output
