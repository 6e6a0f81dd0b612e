"""The command line's options, made from the parameters' one declaration (gistools.parameters).

``@spec_options("rasters")`` adds a command's options: the flag, its type or choices, the default (a length that
follows the data's unit says both), the help. The command function receives each value under the parameter's
Python name, already parsed (class lists as tuples of integers, number lists as tuples of floats).
"""

from __future__ import annotations

import click

from ..parameters import COMMANDS, PARAMETERS, ByUnits, Parameter
from ..parameters.core import COMMAND_DEFAULTS

__all__ = ["spec_options", "click_option", "DEPRECATED"]

DEPRECATED = "gistools: {flag} {old} is an old word for {new}; it still works, write {flag} {new}"


def _split(text: str) -> list[str]:
    return [v for v in str(text).replace(" ", "").split(",") if v != ""]


def _callback(p: Parameter):
    def parse(ctx, param, value):
        if value is None:
            return None
        if p.kind == "classes":
            try:
                classes = tuple(int(v) for v in _split(value))
            except ValueError:
                raise click.BadParameter(f"{value!r} is not a list of class codes; write e.g. {p.example or '1,2'}") from None
            if not classes or any(not 0 <= c <= 255 for c in classes):
                raise click.BadParameter(f"{value!r}: class codes are integers 0-255, e.g. {p.example or '1,2'}")
            return classes
        if p.kind == "numbers":
            try:
                return tuple(float(v) for v in _split(value))
            except ValueError:
                raise click.BadParameter(f"{value!r} is not a comma-separated list of numbers, e.g. {p.example}") from None
        if p.kind == "choices":
            kinds = {type(c) for c in p.choices}
            words = []
            for v in _split(value):
                v = p.aliases.get(v, v)
                if kinds == {int}:  # choices that are numbers (the height bands 1, 2, 3)
                    try:
                        v = int(v)
                    except ValueError:
                        pass
                words.append(v)
            bad = [str(w) for w in words if w not in p.choices]
            if bad or not words:
                raise click.BadParameter(f"{', '.join(bad) or '(none)'}: choose among {', '.join(map(str, p.choices))}")
            return tuple(words)
        if p.kind == "choice" and value in p.aliases:
            click.echo(DEPRECATED.format(flag=p.cli_flag, old=value, new=p.aliases[value]), err=True)
            return p.aliases[value]
        return value

    return parse


def _default_shown(p: Parameter, default=None):
    default = p.default if default is None else default
    if isinstance(default, (tuple, list)):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in default)
    return default


def _help(p: Parameter, default) -> str:
    """The option's help: the declaration's, and the default where --help cannot show it."""
    text = p.help_text("cli")
    if isinstance(default, ByUnits):
        return text + f" Default: {default.text()}" + (f" ({default.why})" if default.why else "") + "."
    if default is None and p.default_text:
        return text + f" Default: {p.default_help('cli')}."
    return text


class _NumberOrWord(click.ParamType):
    """A whole number of at least ``minimum``, or one of ``words`` (--jobs auto)."""

    def __init__(self, words, minimum):
        self.words, self.minimum, self.name = tuple(words), minimum, "|".join(words) + "|N"

    def convert(self, value, param, ctx):
        if isinstance(value, int) and not isinstance(value, bool):
            number = value
        elif str(value).strip().lower() in self.words:
            return str(value).strip().lower()
        else:
            try:
                number = int(str(value))
            except ValueError:
                self.fail(f"{value!r} is neither {' nor '.join(self.words)} nor a whole number", param, ctx)
        if self.minimum is not None and number < self.minimum:
            self.fail(f"{number} is below {self.minimum:g}", param, ctx)
        return number


def _click_type(p: Parameter):
    """The click type of a parameter's value (None: text)."""
    if p.kind == "int" and p.words:
        return _NumberOrWord(p.words, p.minimum)
    if p.kind == "int":
        return click.IntRange(None if p.minimum is None else int(p.minimum), None if p.maximum is None else int(p.maximum))
    if p.kind == "float":
        return float if p.minimum is None and p.maximum is None else click.FloatRange(p.minimum, p.maximum)
    if p.kind == "choice":
        return click.Choice(list(p.choices) + list(p.aliases))
    return None


def click_option(p: Parameter, *, default=None, help_extra: str = ""):
    """The click option of one parameter (``default`` replaces the declared one, e.g. a command's own)."""
    default = p.default if default is None else default
    names = [p.cli_flag] + ([p.short] if p.short else [])
    kwargs: dict = {"help": _help(p, default) + help_extra}
    if isinstance(default, ByUnits):
        default = None
    if p.kind == "flag":  # a setting on by default has a flag that turns it off (--no-map)
        return click.option(*names, p.name, is_flag=True, default=bool(default), flag_value=not bool(default), **kwargs)
    if _click_type(p) is not None:
        kwargs["type"] = _click_type(p)
    if p.kind in ("classes", "numbers", "choices", "choice"):
        kwargs["callback"] = _callback(p)
    if p.metavar:
        kwargs["metavar"] = p.metavar
    if default is not None:
        kwargs["default"] = _default_shown(p, default) if p.kind in ("classes", "numbers", "choices") else default
        kwargs["show_default"] = True
    return click.option(*names, p.name, required=p.required, **kwargs)


def spec_options(command: str, *, skip=(), defaults: dict | None = None):
    """A decorator adding command ``command``'s declared options (but ``skip``), in their declared order, with the
    command's own defaults (``COMMAND_DEFAULTS``, then ``defaults``)."""
    defaults = {**COMMAND_DEFAULTS.get(command, {}), **(defaults or {})}

    def apply(fn):
        for name in reversed([n for n in COMMANDS[command] if n not in skip]):
            fn = click_option(PARAMETERS[name], default=defaults.get(name))(fn)
        return fn

    return apply
