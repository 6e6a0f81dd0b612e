"""One declaration of each parameter of every command and Processing algorithm.

A :class:`Parameter` holds a setting's Python name, kind, default, choices with their readable labels, help, the
unit kind of a length and its default per unit system. The command line's options (``cli/spec.py``), the QGIS
algorithms' parameters (``qgis_plugin/algorithms/spec.py``), the checks of the settings objects, the resume
comparison and the documentation's option tables are all made from here; nothing else declares a parameter.

Messages name a parameter through :func:`option`: a library call raised from Python reads ``overwrite=True``, the
same error through the command line ``--overwrite`` and in QGIS the dialog's label. The name is rendered when the
message is shown (:func:`render`), in the way the process showing it speaks (:func:`speaking`).
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
from dataclasses import dataclass, field

__all__ = ["Parameter", "PARAMETERS", "COMMANDS", "LIBRARY", "DECLARED", "COMMAND_LINE", "COMMAND_DEFAULTS", "DEFAULT_TEXTS", "declare", "command", "option", "render", "speaking", "flag_of",
           "by_units", "ByUnits"]

_OPEN, _SEP, _CLOSE = "\ue000", "\ue001", "\ue002"  # private-use marks around a parameter's name in a message
_SPEAKING = contextvars.ContextVar("gistools_speaking", default=None)
ENV = "GISTOOLS_SPEAKS"  # set by the command line for the worker processes it starts


@dataclass(frozen=True)
class ByUnits:
    """A default length that reads naturally in the data's unit: ``ft`` on a CRS in feet, ``m`` on a metre CRS."""

    ft: str
    m: str
    why: str = ""

    def text(self) -> str:
        return f"{self.ft} on data in feet, {self.m} on data in metres"


def by_units(ft: str, m: str, why: str = "") -> ByUnits:
    return ByUnits(ft, m, why)


@dataclass(frozen=True)
class Parameter:
    """A setting, declared once.

    kind: length (text with a unit, "5ft", "1.5m"; a bare number in CRS units), int, float, text, choice, choices
    (several of the choices, "dsm,dem"), flag,
    classes (class codes, "1,2"), numbers (``count`` numbers, "0.3,0.7"), layer (a vector layer, ``geometry``
    point / line / polygon / any), raster, file, folder, crs, fields. ``default``: the Python value (a
    :class:`ByUnits` for lengths that follow the data's unit; None: ``default_text`` says what happens).
    ``choices``: {value: dialog label}, in the library's order (a text with choices: the dialog offers them as a list,
    the command line takes the text and the library checks it); ``aliases``: {old word: value} still taken.
    ``flag``: the command-line flag when it is not ``--`` + the name with dashes.
    """

    name: str
    kind: str
    help: str
    label: str
    default: object = None
    default_text: str = ""
    flag: str = ""
    short: str = ""
    choices: dict = field(default_factory=dict)
    aliases: dict = field(default_factory=dict)
    minimum: float | None = None
    maximum: float | None = None
    count: int | None = None
    geometry: str = "any"
    advanced: bool = False
    required: bool = False
    metavar: str = ""
    example: str = ""
    words: tuple = ()  # words a number also takes (jobs: "auto"); the dialog offers the first as 0
    qgis: str = ""  # the QGIS parameter's name when it is not the Python name in capitals
    # the library's keyword when it is not ``name`` (a name two commands would share with other meanings: the
    # ground filter's ``method`` is ``ground_method`` here); a dotted path reaches a settings' own settings
    # (``checks.z_max``). A Python caller's message names this keyword.
    keyword: str = ""
    # the value of the command's method that reads this option, when only one does (the ground filters' own
    # options: "smrf", "smrftin", "csf"); given to a run of another method it is refused, as it would change nothing
    read_by: str = ""

    @property
    def python_name(self) -> str:
        """What a Python caller writes: the keyword of the library function or settings field."""
        return (self.keyword or self.name).rsplit(".", 1)[-1]

    def library_value(self, value):
        """A front end's value as the library's keyword takes it: a ``no_...`` flag is its keyword negated."""
        return not value if self.kind == "flag" and self.name == f"no_{self.python_name}" else value

    @property
    def cli_flag(self) -> str:
        return self.flag or "--" + self.name.replace("_", "-")

    @property
    def qgis_name(self) -> str:
        return self.qgis or self.name.upper()

    def help_text(self, speaks: str = "python") -> str:
        """The help with other parameters' names rendered for ``speaks`` (cli, qgis, python)."""
        return render(self.help, speaks)

    def default_help(self, speaks: str = "python") -> str:
        if isinstance(self.default, ByUnits):
            return self.default.text()
        return render(self.default_text, speaks)


PARAMETERS: dict[str, Parameter] = {}
COMMANDS: dict[str, tuple[str, ...]] = {}
COMMAND_DEFAULTS: dict[str, dict] = {}  # a command's own default of a shared parameter (metrics: 5 m cells)
LIBRARY: dict[str, tuple] = {}  # command -> (its function, its settings class, its command-line-only parameters)
DECLARED: dict[str, dict] = {}  # command -> its inputs, summary, page, group: front ends made from the declaration
COMMAND_LINE: dict[str, str] = {}  # command -> its click command in gistools.cli (the commands not declared whole)
DEFAULT_TEXTS: dict[str, dict] = {}  # what a command's help says of a default it computes


def declare(*parameters: Parameter) -> None:
    """Add parameters to the one register; a name declared twice is a programming error."""
    for p in parameters:
        if p.name in PARAMETERS and PARAMETERS[p.name] != p:
            raise RuntimeError(f"parameter {p.name!r} is declared twice")
        if p.kind not in KINDS:
            raise RuntimeError(f"parameter {p.name!r}: unknown kind {p.kind!r}")
        PARAMETERS[p.name] = p


def command(name: str, *parameters: str, library: str = "", settings: str = "",
            command_line: tuple = (), cli: str = "", inputs: tuple = (), summary: str = "", page: str = "",
            group: str = "", outputs: tuple = ()) -> tuple[str, ...]:
    """Declare which parameters command ``name`` takes (in its help's order), and what runs it: ``library`` the
    function (``module:function`` under gistools), ``settings`` its settings class (``module:Class``, or ""). Each
    parameter is a keyword of the function or a field of the settings (tests/test_parameters.py walks them) but
    those of ``command_line``: what the command line composes around the call (a web map after the chain).
    ``cli``: its click command (``module:function`` under gistools.cli; a sub-command names its group), which
    ``gistools`` lists and imports when the command runs.

    A command declared whole also gives ``inputs`` ((keyword, kind, label), ...: the function's first arguments,
    before its output folder ``out``), a one-line ``summary``, its documentation ``page``, its QGIS ``group`` and
    its rasters' names (``outputs``: the keys of the report's ``outputs``, loaded into QGIS):
    its command-line command (gistools.cli.declared), its QGIS algorithm (qgis_plugin/algorithms/declared.py), its
    export from ``gistools`` and its reference page are then made from this declaration alone."""
    missing = [p for p in parameters if p not in PARAMETERS]
    if missing:
        raise RuntimeError(f"command {name!r} takes undeclared parameters {missing}")
    COMMANDS[name] = tuple(parameters)
    if cli:
        COMMAND_LINE[name] = cli
    if library:
        LIBRARY[name] = (library, settings, tuple(command_line))
    if inputs:
        if not (library and summary and page and group):
            raise RuntimeError(f"command {name!r}: a command declared whole needs its library, summary, page, group")
        DECLARED[name] = {"inputs": tuple(inputs), "summary": summary, "page": page, "group": group,
                          "outputs": tuple(outputs)}
    return COMMANDS[name]


KINDS = ("length", "int", "float", "text", "choice", "choices", "flag", "classes", "numbers", "layer", "raster", "file",
         "folder", "crs", "fields", "area")


# --- naming a parameter in a message ------------------------------------------------------------------------------
def option(name: str, value=None) -> str:
    """A parameter (and an example value) as a message names it: ``--cell-size 5ft`` on the command line,
    ``cell_size='5ft'`` from Python, the dialog's label in QGIS. Rendered when the message is shown."""
    if value is None:
        return f"{_OPEN}{name}{_CLOSE}"
    return f"{_OPEN}{name}{_SEP}{value!r}{_CLOSE}"


def speaking() -> str:
    """How this process names parameters: python (a library call), cli, or qgis."""
    return _SPEAKING.get() or os.environ.get(ENV) or "python"


@contextlib.contextmanager
def speaks(how: str, labels: dict | None = None):
    """Within the block, messages name parameters as ``how`` does (``labels``: {name: QGIS label})."""
    token = _SPEAKING.set(how)
    label_token = _LABELS.set(labels or {})
    try:
        yield
    finally:
        _SPEAKING.reset(token)
        _LABELS.reset(label_token)


_LABELS = contextvars.ContextVar("gistools_labels", default={})


def flag_of(name: str) -> str:
    p = PARAMETERS.get(name)
    return p.cli_flag if p else "--" + name.replace("_", "-")


def _cli_value(value) -> str:
    if isinstance(value, (tuple, list)):
        if all(isinstance(v, (str, int)) and not isinstance(v, bool) for v in value):
            return ",".join(map(str, value))
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return str(value)


def _python_value(p, value):
    """An example written as on the command line ("1,2", "2000000"), as a Python caller passes it."""
    if p is None or not isinstance(value, str):
        return value
    try:
        if p.kind == "int":
            return int(value)
        if p.kind == "float":
            return float(value)
        if p.kind == "classes":
            return tuple(int(v) for v in value.split(","))
        if p.kind == "numbers":
            return tuple(float(v) for v in value.split(","))
    except ValueError:
        pass
    return value


_MARK = re.compile(f"{_OPEN}([A-Za-z_][A-Za-z0-9_]*)(?:{_SEP}(.*?))?{_CLOSE}", re.S)


def render(text: str, speaks: str | None = None) -> str:
    """``text`` with its parameter marks written as ``speaks`` (default: this process's way) names them."""
    if _OPEN not in text:
        return text
    speaks = speaks or speaking()
    labels = _LABELS.get()

    def one(m):
        name, raw = m.group(1), m.group(2)
        import ast

        value = None
        if raw is not None:
            try:
                value = ast.literal_eval(raw)
            except (ValueError, SyntaxError):
                value = raw
        p = PARAMETERS.get(name)
        is_flag = p is not None and p.kind == "flag"
        if speaks == "cli":
            if is_flag or value is None:
                return flag_of(name)
            text = _cli_value(value)
            plain = re.fullmatch(r"[\w.,:/+-]+", text)
            return f"{flag_of(name)} {text if plain else repr(text)}"
        if speaks == "qgis":
            label = labels.get(name) or (p.label if p else name)
            return f"'{label}'" + ("" if value is None or is_flag else f" = {_cli_value(value)}")
        keyword = p.python_name if p is not None else name
        if is_flag and value is not None and not isinstance(value, bool):  # a value given that is not a flag's
            return f"{keyword}={value!r}"
        if is_flag:  # a --no-... flag is its keyword set False (no_figures: figures=False)
            return f"{keyword}={name != 'no_' + keyword}"
        if value is None:
            return keyword
        return f"{keyword}={_python_value(p, value)!r}"

    return _MARK.sub(one, text)
