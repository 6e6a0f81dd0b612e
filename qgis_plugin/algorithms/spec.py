"""The Processing parameters, made from the parameters' one declaration (gistools.parameters), and their values read
back as the library takes them: the same names, defaults, choices and help as the command line's options.

Lengths are text with a unit ("5ft", "1.5m"; a bare number is in the data's CRS units), as on the command line:
QGIS distance widgets hold a number in the layer's units, and a default such as 25 ft must not become 25 m on
metre data.
"""

from __future__ import annotations

import contextlib

from qgis.core import (
    QgsProcessingException,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterExtent,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorLayer,
)

from gistools.parameters import ByUnits, Parameter

from ..compat import DOUBLE, FOLDER, INTEGER, VECTOR_LINE, VECTOR_POINT, VECTOR_POLYGON

__all__ = ["qgis_parameter", "qgis_help", "read_value", "flag_parameters", "method_labelled", "own_default_text"]

GEOMETRIES = {"point": [VECTOR_POINT], "line": [VECTOR_LINE], "polygon": [VECTOR_POLYGON], "any": []}
LENGTH_UNITS = " (with unit: m, ft, ftUS)"
LENGTH_RULE = " A length with its unit (m; ft, the CRS's own foot; ftUS); a bare number is in the CRS's unit."


def qgis_help(p: Parameter, default=None) -> str:
    """The parameter's help in the dialog: the declared help, its default where the dialog cannot show it."""
    text = p.help_text("qgis")
    default = p.default if default is None else default
    if isinstance(default, ByUnits):
        text += f" Empty: {default.text()}" + (f" ({default.why})" if default.why else "") + "."
    elif default is None and p.default_text:
        text += f" Empty: {p.default_help('qgis')}."
    if p.kind == "length":
        text += LENGTH_RULE
    return text


def _text_default(p: Parameter, default):
    if isinstance(default, (tuple, list)):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in default)
    return default


def _number(p, name, label, default, optional):
    if p.words:  # a number that also takes a word (jobs: auto): the dialog's 0 is the first word
        default = 0 if default in p.words else default
    kwargs = {"type": INTEGER if p.kind == "int" else DOUBLE, "defaultValue": default, "optional": optional}
    if p.minimum is not None:
        kwargs["minValue"] = 0 if p.words else p.minimum
    if p.maximum is not None:
        kwargs["maxValue"] = p.maximum
    return QgsProcessingParameterNumber(name, label, **kwargs)


def _enum(p, name, label, default, optional, order=None):
    values, many = list(order or p.choices), p.kind == "choices"
    if default is None:
        index = None
    else:
        index = [values.index(v) for v in default] if many else values.index(default)
    return QgsProcessingParameterEnum(name, label, options=[p.choices[v] for v in values], allowMultiple=many,
                                      defaultValue=index, optional=default is None)


def _text(p, name, label, default, optional):
    suffix = LENGTH_UNITS if p.kind == "length" else ""
    return QgsProcessingParameterString(name, label + suffix, defaultValue=_text_default(p, default), optional=optional)


_BY_KIND = {
    "flag": lambda p, n, label, d, o: QgsProcessingParameterBoolean(n, label, defaultValue=bool(d)),
    "int": _number, "float": _number, "choice": _enum, "choices": _enum,
    "layer": lambda p, n, label, d, o: QgsProcessingParameterVectorLayer(n, label, GEOMETRIES[p.geometry],
                                                                         optional=not p.required),
    "raster": lambda p, n, label, d, o: QgsProcessingParameterRasterLayer(n, label, optional=not p.required),
    "crs": lambda p, n, label, d, o: QgsProcessingParameterCrs(n, label, optional=True),
    "file": lambda p, n, label, d, o: QgsProcessingParameterFile(n, label, optional=o),
    "folder": lambda p, n, label, d, o: QgsProcessingParameterFile(n, label, behavior=FOLDER, optional=o),
    "area": lambda p, n, label, d, o: QgsProcessingParameterExtent(n, label, optional=True),
}


def qgis_parameter(p: Parameter, default=None, *, label: str | None = None, order=None):
    """The QGIS parameter definition of ``p`` (``default`` replaces the declared one, e.g. an algorithm's own;
    ``order``: a choice's values in the order this algorithm numbers them)."""
    default = p.default if default is None else default
    optional = _optional(p, default)
    default = None if isinstance(default, ByUnits) else default
    if order is not None or (p.kind == "text" and p.choices):  # a text with choices: a list in the dialog
        return _enum(p, p.qgis_name, label or p.label, default, optional, order)
    return _BY_KIND.get(p.kind, _text)(p, p.qgis_name, label or p.label, default, optional)


def _optional(p: Parameter, default) -> bool:
    """A parameter the dialog may leave empty: not required, and without a default there (or a layer)."""
    return not p.required and (default is None or isinstance(default, ByUnits) or p.kind in ("layer", "raster"))


def _numbers(text: str, p: Parameter, cast):
    try:
        return tuple(cast(v) for v in text.replace(" ", "").split(",") if v != "")
    except ValueError:
        raise QgsProcessingException(f"{p.label}: {text!r} is not a comma-separated list of numbers, e.g. "
                                     f"{p.example or '1,2'}") from None


# how each kind's value is read back, as the library takes it (``v``: the algorithm's order of a choice's values)
_READERS = {
    "int": lambda alg, p, ps, ctx, fb, v: alg.parameterAsInt(ps, p.qgis_name, ctx) or (p.words[0] if p.words else 0),
    "float": lambda alg, p, ps, ctx, fb, v: alg.parameterAsDouble(ps, p.qgis_name, ctx),
    "choice": lambda alg, p, ps, ctx, fb, v: v[alg.parameterAsEnum(ps, p.qgis_name, ctx)],
    "choices": lambda alg, p, ps, ctx, fb, v: tuple(v[i] for i in alg.parameterAsEnums(ps, p.qgis_name, ctx)),
    "layer": lambda alg, p, ps, ctx, fb, v: alg.layer_spec(ps, p.qgis_name, ctx, fb),
    "raster": lambda alg, p, ps, ctx, fb, v: alg.raster_path(ps, p.qgis_name, ctx),
    "crs": lambda alg, p, ps, ctx, fb, v: alg.crs_text(ps, ctx, p.qgis_name),
    "area": lambda alg, p, ps, ctx, fb, v: alg.extent_text(ps, p.qgis_name, ctx),
}


def _read_text(alg, p: Parameter, parameters, context):
    text = alg.text(parameters, p.qgis_name, context)
    if text is None or p.kind not in ("classes", "numbers"):
        return text
    return _numbers(text, p, int if p.kind == "classes" else float)


def read_value(alg, p: Parameter, parameters, context, feedback, order=None):
    """The value of ``p`` in a run's ``parameters``, as the library takes it (None where left empty); ``order``: the
    choices in the order the algorithm numbers them."""
    name = p.qgis_name
    if p.kind == "flag":
        return alg.parameterAsBoolean(parameters, name, context)
    missing = parameters.get(name) is None or parameters.get(name) == ""
    if missing and alg.parameterDefinition(name).defaultValue() in (None, ""):
        return None  # left empty, no default in the dialog: the library's default applies
    kind = "choice" if p.kind == "text" and p.choices else p.kind  # a text with choices: a list in the dialog
    if kind in _READERS:
        return _READERS[kind](alg, p, parameters, context, feedback, list(order or p.choices))
    return _read_text(alg, p, parameters, context)


def flag_parameters(alg, flag, *names) -> None:
    """Add ``flag`` (ADVANCED, OPTIONAL) to parameters ``names`` where an algorithm differs from the declaration
    (e.g. a list an analyst may leave empty)."""
    for name in names:
        definition = alg.parameterDefinition(name)
        definition.setFlags(definition.flags() | flag)



@contextlib.contextmanager
def method_labelled(alg, name: str):
    """Library messages name the settings' field ``method`` (the flag --method is declared once per command:
    ground_method, chm_method): within the block they show the dialog's label of ``name`` for it."""
    from gistools.errors import Cancelled, GistoolsError
    from gistools.parameters import speaks

    labels = {n: alg.parameterDefinition(p.qgis_name).description() for n, p in alg._spec.items()}
    with speaks("qgis", {**labels, "method": labels[name]}):
        try:
            yield
        except Cancelled:
            raise
        except GistoolsError as err:  # rendered here, with the label of ``method``
            raise QgsProcessingException(alg.labelled(str(err))) from None


def own_default_text(alg, texts: dict) -> None:
    """The help of a shared parameter whose default this algorithm computes otherwise: what ``texts`` ({name:
    text}, gistools.parameters.lidar.DEFAULT_TEXTS) says of it in place of the declared default's text."""
    from gistools.parameters import PARAMETERS, render

    for name, text in texts.items():
        p = PARAMETERS[name]
        definition = alg.parameterDefinition(p.qgis_name)
        if definition is not None and hasattr(definition, "setHelp"):
            help_text = qgis_help(p).replace(f" Empty: {p.default_help('qgis')}.", f" Empty: {render(text, 'qgis')}.")
            definition.setHelp(help_text)
