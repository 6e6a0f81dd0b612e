"""One declaration of each parameter (gistools.parameters): the command line's options are made from it, and a
library error names the Python argument, the command line the flag (the QGIS side: tests/test_qgis.py)."""

from __future__ import annotations

import click
import pytest

from gistools.cli.main import cli
from gistools.errors import InputError
from gistools.parameters import COMMANDS, PARAMETERS, ByUnits, option, render, speaks
from gistools.parameters.core import COMMAND_DEFAULTS, DEFAULT_TEXTS

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
            shown = default if not isinstance(default, tuple) else ",".join(
                f"{v:g}" if isinstance(v, float) else str(v) for v in default)
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


# ---------------------------------------------------------------------------------------------- the library's side
def _library(command: str):
    """(the function, the settings class or None, the command-line-only names) declared for ``command``."""
    import importlib

    from gistools.parameters import LIBRARY

    function, settings, command_line = LIBRARY[command]

    def load(spec):
        module, name = spec.split(":")
        return getattr(importlib.import_module(f"gistools.{module}"), name)

    return load(function), (load(settings) if settings else None), set(command_line)


def _fields(cls) -> dict:
    """{field: default} of a settings dataclass and of the settings it holds (a shrub run's raster settings, a
    runway's survey checks), one level down."""
    import dataclasses

    found = {}
    for f in dataclasses.fields(cls):
        default = (f.default if f.default is not dataclasses.MISSING else
                   f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        found[f.name] = default
        if dataclasses.is_dataclass(default):
            for sub, value in _fields(type(default)).items():
                found.setdefault(sub, value)
    return found


def _same_default(declared, library) -> bool:
    """The declaration's default and the library's are one value (a tuple for a list of choices, text for a
    length; None in the library where the declaration's default follows the data's unit)."""
    if isinstance(declared, ByUnits):
        return library is None or library in (declared.ft, declared.m)
    if isinstance(declared, (list, tuple)) and isinstance(library, (list, tuple)):
        return len(declared) == len(library) and all(_same_default(a, b) for a, b in zip(declared, library))
    if isinstance(declared, (int, float)) and isinstance(library, (int, float)) and not isinstance(declared, bool):
        return float(declared) == float(library)
    if isinstance(declared, str) and isinstance(library, float) and declared.endswith("m") and declared[:-1]:
        return float(declared[:-1]) == library  # a length the library holds in metres (the runway's checks)
    if isinstance(declared, str) and isinstance(library, (list, tuple)):
        return declared.split(",") == [str(v) for v in library]
    return declared == library or str(declared) == str(library)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_declared_parameter_is_a_keyword_of_the_library_with_the_same_default(name):
    """Each parameter of a command is a keyword of its library function or a field of its settings (its declared
    ``keyword`` where the name is taken), with the default the command line shows (the command's own, where it
    has one); a required parameter has no default in the library either. Only the declared command-line-only
    parameters are not the library's (what the command line composes around the call)."""
    import inspect

    function, settings, command_line = _library(name)
    keywords = {k: p.default for k, p in inspect.signature(function).parameters.items()}
    fields = _fields(settings) if settings else {}
    own = COMMAND_DEFAULTS.get(name, {})
    for pname in COMMANDS[name]:
        if pname in command_line:
            assert pname not in keywords and pname not in fields, f"{pname} is the library's: not command-line-only"
            continue
        p = PARAMETERS[pname]
        keyword = p.python_name
        assert keyword in keywords or keyword in fields, (
            f"gistools {name} --{pname}: {keyword!r} is neither a keyword of {function.__name__} nor a field of "
            f"{settings.__name__ if settings else 'its settings'}")
        library = fields[keyword] if keyword in fields else keywords[keyword]
        declared = own.get(pname, p.default)
        if p.kind == "flag" and pname == f"no_{keyword}":  # --no-figures: the library's figures=True
            declared = not declared
        if library is inspect.Parameter.empty:
            assert p.required or declared is None, f"{name} {pname}: the library requires it, the command does not"
            continue
        assert _same_kind(p, library), f"gistools {name} --{pname}: a {p.kind}, the library's {library!r}"
        if declared is None and (p.default_text or pname in DEFAULT_TEXTS.get(name, {})):
            continue  # a default the run computes (its help says how), which the library holds as a value or None
        assert _same_default(declared, library), f"gistools {name} --{pname}: {declared!r}, the library {library!r}"


def _same_kind(p, library) -> bool:
    """The library's default is of the declared kind (None: given by the run, or optional)."""
    kind = p.kind
    if library is None or (kind == "choice" and str(library) in {str(c) for c in p.choices}):
        return True
    if kind == "text" and isinstance(library, tuple):  # a comma list (the CHM's thresholds), parsed
        return True
    if kind == "flag":
        return isinstance(library, bool)
    if kind == "int":
        return isinstance(library, int) and not isinstance(library, bool) or library == "auto"
    if kind == "float":
        return isinstance(library, (int, float)) and not isinstance(library, bool)
    if kind in ("choice", "text", "crs", "layer", "raster", "file", "folder"):
        return isinstance(library, str)
    if kind == "length":
        return isinstance(library, (str, int, float)) and not isinstance(library, bool)
    return isinstance(library, (str, tuple, list))  # choices, classes, numbers, fields: several values


def test_a_python_message_names_the_librarys_keyword_where_the_declared_name_differs():
    """gistools ground's --method is ``ground_method`` in the register, ``method`` of GroundSettings: a Python
    caller reads ``method``; --no-figures is ``figures=False`` of AquiferSettings."""
    text = f"{option('ground_method', 'csf')}, {option('no_figures')}, {option('dem_z_unit')}"
    assert render(text, "python") == "method='csf', figures=False, z_unit"
    assert render(text, "cli") == "--method csf, --no-figures, --z-unit"


def test_a_no_flag_reaches_the_library_as_its_keyword_negated():
    assert PARAMETERS["no_figures"].library_value(True) is False and PARAMETERS["no_figures"].python_name == "figures"
    assert PARAMETERS["overwrite"].library_value(True) is True


@pytest.mark.parametrize("name", sorted(n for n, module in __import__("gistools")._LAZY.items()
                                        if module.startswith(("products", "deliver"))))
def test_a_misnamed_argument_of_a_library_function_is_refused_naming_the_real_ones(name):
    """Every exported product function refuses a keyword it does not take before it runs (nothing read or written), with
    ArgumentError (a TypeError, as Python's own refusal) naming every argument it takes."""
    import inspect

    import gistools
    from gistools.errors import ArgumentError

    function = getattr(gistools, name)
    takes = [p for p in inspect.signature(function).parameters]
    with pytest.raises(ArgumentError) as err:
        function(no_such_argument=1)
    assert isinstance(err.value, TypeError)
    message = str(err.value)
    assert "'no_such_argument'" in message and message.startswith(f"{name}()")
    assert message.split("it takes ")[1].split(", ") == takes


def test_a_misnamed_argument_names_the_closest_one_and_a_settings_field_says_where_it_goes(tmp_path):
    import gistools
    from gistools.errors import ArgumentError

    with pytest.raises(ArgumentError, match=r"no argument 'dem_z_unit': did you mean 'z_unit'\?"):
        gistools.slope_classes_from_dem("dem.tif", tmp_path / "out", dem_z_unit="m")
    with pytest.raises(ArgumentError, match=r"no argument 'cell_size': it is a field of ChmSettings. "
                                            r"Pass ChmSettings\(cell_size=...\) as the settings"):
        gistools.chm_from_tiles("sample_tiles", tmp_path / "out", cell_size="1m")
    with pytest.raises(ArgumentError, match=r"did you mean ChmSettings\(cell_size=...\)\?"):
        gistools.chm_from_tiles("sample_tiles", tmp_path / "out", cel_size="1m")
    with pytest.raises(ArgumentError, match=r"ChmSettings\(\) has no argument 'cel_size': did you mean 'cell_size'"):
        gistools.ChmSettings(cel_size="1m")
    with pytest.raises(TypeError, match="missing a required argument: 'height'") as err:  # not a user's input error
        gistools.Grid(1, 2)
    assert not isinstance(err.value, ArgumentError)
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_an_exported_function_still_pickles_by_name():
    """The checked functions stay picklable (a process pool or a cluster sends them by name)."""
    import pickle

    import gistools

    for name in ("rasters_from_tiles", "terrain_from_dem", "ChmSettings", "dsm_from_points", "travel_minutes"):
        value = getattr(gistools, name)
        assert pickle.loads(pickle.dumps(value)) is value
    from gistools.lidar.gridding import dem_from_ground_points
    from gistools.products.rasters import rasters_from_tiles

    gistools.dem_from_ground_points, gistools.rasters_from_tiles  # noqa: B018 - exported (checked) first
    for original in (dem_from_ground_points, rasters_from_tiles):  # the originals keep pickling by their own names
        assert pickle.loads(pickle.dumps(original)) is original
    settings = gistools.ChmSettings(cell_size="1m")
    assert pickle.loads(pickle.dumps(settings)) == settings


def test_every_read_by_names_a_method_of_its_command():
    """An option read by one method only (the ground filters' own) names a value of that command's --method."""
    owned = {name: PARAMETERS[name].read_by for name in PARAMETERS if PARAMETERS[name].read_by}
    assert len(owned) == 18
    for name, method in owned.items():
        commands = [c for c, names in COMMANDS.items() if name in names]
        assert commands == ["ground"], name
        assert method in PARAMETERS["ground_method"].choices, (name, method)


@pytest.mark.parametrize("args,refused", [
    (["--method", "smrf", "--csf-rigidness", "2"], "--csf-rigidness 2"),
    (["--csf-rigidness", "2"], "--csf-rigidness 2"),  # the default, adaptive, reads smrftin's
    (["--method", "csf", "--smrftin-patch", "30m"], "--smrftin-patch 30m"),
    (["--method", "smrftin", "--threshold", "0.3m"], "--threshold 0.3m"),
])
def test_an_option_of_another_ground_filter_is_refused_before_anything_is_written(tmp_path, args, refused):
    from click.testing import CliRunner

    from conftest import SAMPLE

    out = tmp_path / "g"
    result = CliRunner().invoke(cli, ["ground", str(SAMPLE), "--out", str(out), "-q", *args])
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 1 and len(lines) == 1, result.output
    assert lines[0].startswith(f"gistools: error: {refused} is read by --method ") and "Traceback" not in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("settings", [
    dict(method="adaptive", smrftin_patch="30m"),  # adaptive reads smrftin's options
    dict(method="smrf", threshold="0.3m"),
    dict(method="csf", csf_rigidness=2, smrftin_cell="1.5m"),  # another filter's, at its default
])
def test_a_ground_filters_own_options_are_taken(settings):
    from gistools.products.ground import GroundSettings

    GroundSettings(**settings).validate()


BAD_VALUE = {"length": "-3 furlongs", "int": "many", "float": "much", "choice": "no-such-choice", "flag": "yes"}


@pytest.mark.parametrize("settings_class", ["products.ground.GroundSettings", "products.settings.ShrubSettings",
                                            "products.rasters.RasterSettings", "products.chm.ChmSettings"])
def test_every_declared_field_of_a_settings_class_is_checked_without_a_list(settings_class):
    """A settings class checks each of its fields that has a declaration of its name: an invalid value of each
    (by its declared kind) is refused, in the one-line form that names its option, before anything is read."""
    import dataclasses
    import importlib

    module, name = settings_class.rsplit(".", 1)
    cls = getattr(importlib.import_module(f"gistools.{module}"), name)
    fields = [f.name for f in dataclasses.fields(cls) if f.name in PARAMETERS and PARAMETERS[f.name].kind in BAD_VALUE]
    assert len(fields) >= 4
    for field in fields:
        settings = cls(**{field: BAD_VALUE[PARAMETERS[field].kind]})
        with pytest.raises(InputError) as refused:
            settings.validate()
        assert render(str(refused.value)).count("\n") == 0
        assert field in str(refused.value), (field, str(refused.value))
        if PARAMETERS[field].kind == "flag":  # the value given, as a Python caller wrote it
            assert render(str(refused.value), "python").startswith(f"{PARAMETERS[field].python_name}='yes' ")
