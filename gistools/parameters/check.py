"""The checks every parameter gets from its declaration (kind, bounds, choices), before anything is read or
written. Cross-parameter rules stay with the settings object that holds them."""

from __future__ import annotations

import dataclasses
import math

from .core import PARAMETERS, ByUnits, option

__all__ = ["check", "check_all", "choices", "default_for", "setting_default", "in_data_units"]


def choices(name: str) -> tuple:
    """The values a choice parameter takes, in the library's order."""
    return tuple(PARAMETERS[name].choices)


def default_for(name: str, unit_is_foot: bool | None = None):
    """A parameter's default; a length that follows the data's unit, in that unit (feet when ``unit_is_foot``)."""
    default = PARAMETERS[name].default
    if isinstance(default, ByUnits):
        return default.ft if unit_is_foot or unit_is_foot is None else default.m
    return default


def setting_default(name: str):
    """A settings field's default: the declared one, or None for a length that follows the data's unit (set once
    the data's unit is known: :func:`in_data_units`)."""
    default = PARAMETERS[name].default
    return None if isinstance(default, ByUnits) else default


def in_data_units(settings, unit_is_foot: bool):
    """``settings`` (a settings dataclass; nested ones too) with each length left to the data's unit (None where
    the declaration's default is :class:`ByUnits`) set to its default in that unit: 5ft on a CRS in feet, 1.5m
    on a metre CRS."""
    import dataclasses

    changes = {}
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            changes[f.name] = in_data_units(value, unit_is_foot)
        elif value is None and f.name in PARAMETERS and isinstance(PARAMETERS[f.name].default, ByUnits):
            changes[f.name] = default_for(f.name, unit_is_foot)
    return dataclasses.replace(settings, **changes) if changes else settings


def _error(*args, **kwargs):
    from ..errors import InputError

    return InputError(*args, **kwargs)


def _length(p, value):
    from ..validation import check_length

    return check_length(value, p.name, minimum=p.minimum or 0.0, allow_equal=p.minimum is not None,
                        example=p.example or None)


def _int(p, value):
    from ..validation import check_count

    if isinstance(value, str) and value.strip().lower() in p.words:
        return value.strip().lower()
    try:
        float(value)
    except (TypeError, ValueError):
        raise _error(f"{option(p.name)} {value!r} is not a whole number",
                     hint=f"Give e.g. {option(p.name, p.example or p.default)}") from None
    if p.maximum is not None and not isinstance(value, bool) and float(value) > p.maximum:
        raise _error(f"{option(p.name)} {value!r} must be at most {p.maximum:g}",
                     hint=f"Give e.g. {option(p.name, p.example or p.default)}")
    return check_count(value, p.name, minimum=int(p.minimum if p.minimum is not None else 0),
                       example=p.example or p.default)


def _float(p, value):
    from ..validation import check_number

    return check_number(value, p.name, low=p.minimum, high=p.maximum, example=p.example or p.default)


def _choice(p, value):
    if value not in p.choices:
        raise _error(f"{option(p.name)} {value!r} is not one of {', '.join(map(str, p.choices))}",
                     hint=f"Use {option(p.name, next(iter(p.choices)) if p.default is None else p.default)}")
    return value


def _choices(p, value):
    values = value if isinstance(value, (tuple, list)) else [value]
    bad = [v for v in values if v not in p.choices]
    if bad or not values:
        raise _error(f"{option(p.name)} {', '.join(map(str, bad)) or '(none)'}: choose among "
                     f"{', '.join(map(str, p.choices))}",
                     hint=f"e.g. {option(p.name, p.example or ','.join(map(str, list(p.choices)[:2])))}")
    return tuple(values)


def _classes(p, value):
    try:
        ok = len(value) > 0 and all(not isinstance(c, bool) and float(c).is_integer() and 0 <= int(c) <= 255
                                    for c in value)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise _error(f"{option(p.name)} {value!r}: class codes are integers 0-255",
                     hint=f"e.g. {option(p.name, p.example or '1,2')}")
    return tuple(int(c) for c in value)


def _numbers(p, value):
    from ..validation import check_breaks

    if not p.count:
        return value
    low = -math.inf if p.minimum is None else p.minimum
    high = math.inf if p.maximum is None else p.maximum
    return check_breaks(value, p.name, count=p.count, low=low, high=high, example=p.example or None)


def _flag(p, value):
    if not isinstance(value, bool):
        raise _error(f"{option(p.name, value)} must be True or False")
    return value


_BY_KIND = {"length": _length, "int": _int, "float": _float, "choice": _choice, "choices": _choices,
            "classes": _classes, "numbers": _numbers, "flag": _flag}


def check(name: str, value):
    """``value`` checked against parameter ``name``'s declaration; returns it (None passes: the default applies)."""
    p = PARAMETERS[name]
    if value is None:
        if p.required:
            raise _error(f"{option(name)} is required", hint=f"Give e.g. {option(name, p.example or '...')}")
        return value
    kind = _BY_KIND.get(p.kind)
    return value if kind is None else kind(p, value)


def check_all(settings, names=None) -> None:
    """Check the fields of a settings object against their declarations: ``names``, or (None) every dataclass
    field that has a declaration of its name (a field added with a declaration is checked without a list)."""
    if names is None:
        names = [f.name for f in dataclasses.fields(settings) if f.name in PARAMETERS]
    for name in names:
        check(name, getattr(settings, name))
