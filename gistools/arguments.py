"""A library call's arguments checked before it runs: an unknown or misnamed keyword is refused in one line that
names the closest real one and every argument the function takes (``gistools.errors.ArgumentError``, also a
TypeError, as Python's own refusal is). The functions and settings classes exported by ``gistools`` are checked."""

from __future__ import annotations

import dataclasses
import difflib
import functools
import inspect

from .errors import ArgumentError


def _refusal(label: str, signature: inspect.Signature, given: dict, err: TypeError, settings=None) -> TypeError:
    takes = [name for name, p in signature.parameters.items()
             if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and name != "self"]
    unknown = [name for name in given if name not in signature.parameters]
    if not unknown:  # a missing argument, or too many positional ones: Python's own TypeError, with the real names
        return TypeError(f"{label}: {err}; it takes {', '.join(takes)}")
    name = unknown[0]
    fields = [f.name for f in dataclasses.fields(settings)] if settings is not None else []
    if name in fields:
        return ArgumentError(f"{label} has no argument {name!r}: it is a field of {settings.__name__}",
                             hint=f"Pass {settings.__name__}({name}=...) as the settings")
    close = difflib.get_close_matches(name, takes + fields, n=1)
    guess = ""
    if close:
        guess = (f"did you mean {settings.__name__}({close[0]}=...)? " if close[0] in fields
                 else f"did you mean {close[0]!r}? ")
    return ArgumentError(f"{label} has no argument {name!r}: {guess}it takes {', '.join(takes)}")


def checked(function, settings=None, exported_as: tuple[str, str] | None = None):
    """``function`` with its arguments checked at each call (a dataclass: its constructor). ``settings``: the
    settings class whose fields a caller may give by mistake to the function; ``exported_as``: (module, name) where
    the checked function is found, so that pickle finds it by name there (the original keeps its own)."""
    if inspect.isclass(function):
        init = function.__init__
        if getattr(init, "__checked__", False):
            return function
        signature = inspect.signature(init)

        @functools.wraps(init)
        def checked_init(self, *args, **kwargs):
            try:
                signature.bind(self, *args, **kwargs)
            except TypeError as err:
                raise _refusal(function.__name__ + "()", signature, kwargs, err) from None
            init(self, *args, **kwargs)

        checked_init.__checked__ = True
        function.__init__ = checked_init
        return function
    signature = inspect.signature(function)

    @functools.wraps(function)
    def call(*args, **kwargs):
        try:
            signature.bind(*args, **kwargs)
        except TypeError as err:
            raise _refusal(function.__name__ + "()", signature, kwargs, err, settings) from None
        return function(*args, **kwargs)

    if exported_as:
        call.__module__, call.__qualname__ = exported_as
    return call
