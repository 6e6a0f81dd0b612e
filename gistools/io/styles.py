"""QGIS layer styles written beside outputs (``<name>.qml``, which QGIS loads as the layer's default style)."""

from __future__ import annotations

import html
import logging
from pathlib import Path

from .atomic import atomic_path

log = logging.getLogger(__name__)

__all__ = ["categorized_fill_qml", "write_polygon_style", "rgba", "MARK"]

MARK = "<!-- gistools style: rewritten on each run; remove this line to keep your own edits -->"


def rgba(hex_colour: str) -> tuple[int, int, int, int]:
    """(r, g, b, 255) of "#rrggbb"."""
    h = hex_colour.lstrip("#")
    return int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16), 255


def _rgb(hex_colour: str) -> str:
    return ",".join(map(str, rgba(hex_colour)))


def categorized_fill_qml(field: str, categories: dict) -> str:
    """A QGIS style (QML) drawing polygons by the value of ``field``: ``categories`` {code: (name, "#rrggbb")},
    solid fills without outlines, as the shrub map draws them."""
    cats, symbols = [], []
    for i, (code, (name, colour)) in enumerate(sorted(categories.items())):
        cats.append(f'      <category value="{code}" label="{html.escape(name)}" symbol="{i}" render="true"/>')
        symbols.append(f'      <symbol type="fill" name="{i}" alpha="1" clip_to_extent="1" force_rhr="0">\n'
                       '        <layer class="SimpleFill" enabled="1" pass="0" locked="0">\n'
                       f'          <prop k="color" v="{_rgb(colour)}"/>\n'
                       '          <prop k="style" v="solid"/>\n'
                       '          <prop k="outline_style" v="no"/>\n'
                       '        </layer>\n'
                       '      </symbol>')
    return ("<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + MARK + "\n"
            '<qgis version="3.22.0" styleCategories="Symbology">\n'
            f'  <renderer-v2 type="categorizedSymbol" attr="{html.escape(field)}" symbollevels="0" enableorderby="0" '
            'forceraster="0">\n    <categories>\n' + "\n".join(cats) + "\n    </categories>\n    <symbols>\n"
            + "\n".join(symbols) + "\n    </symbols>\n  </renderer-v2>\n</qgis>\n")


def write_polygon_style(layer_path, field: str, categories: dict) -> Path | None:
    """``<layer file stem>.qml`` beside a vector file, atomically; QGIS applies it when it opens the layer. A .qml
    there that gistools did not write (no ``MARK`` line: the user's own style) is kept: None is returned."""
    path = Path(layer_path).with_suffix(".qml")
    if not style_is_ours(path):
        log.info("%s: kept (a style gistools did not write)", path)
        return None
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_text(categorized_fill_qml(field, categories), encoding="utf-8")
    return path


def style_is_ours(path) -> bool:
    """Whether the style ``path`` may be (re)written: missing, or written by gistools (its ``MARK`` line); a user's
    own style, or one that cannot be read, is kept."""
    path = Path(path)
    if not path.exists():
        return True
    try:
        return MARK in path.read_text(errors="replace", encoding="utf-8")[:4096]
    except OSError:
        return False


def pseudocolour_qml(breaks, maximum: float, ramp, unit: str) -> str:
    """A QGIS style (QML) of a single-band raster: a discrete pseudocolour ramp with a class at or below each of
    ``breaks`` (``ramp``'s colours in turn, the last for the values above the last break, up to ``maximum``),
    labelled in ``unit``."""
    edges = sorted(breaks)
    items = []
    for i, t in enumerate(edges):
        r, g, b, _ = rgba(ramp[min(i, len(ramp) - 2)])
        items.append(f'          <item alpha="255" value="{t:g}" label="&lt;= {t:g} {html.escape(unit)}" '
                     f'color="#{r:02x}{g:02x}{b:02x}"/>')
    r, g, b, _ = rgba(ramp[-1])
    top = max(maximum, edges[-1])
    items.append(f'          <item alpha="255" value="inf" label="&gt; {edges[-1]:g} {html.escape(unit)}" '
                 f'color="#{r:02x}{g:02x}{b:02x}"/>')
    return ("<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + MARK + "\n"
            '<qgis version="3.22.0" styleCategories="Symbology">\n  <pipe>\n'
            f'    <rasterrenderer type="singlebandpseudocolor" band="1" opacity="1" classificationMin="0" '
            f'classificationMax="{top:g}">\n      <rastershader>\n'
            '        <colorrampshader colorRampType="DISCRETE" classificationMode="1" clip="0">\n'
            + "\n".join(items) + "\n        </colorrampshader>\n      </rastershader>\n    </rasterrenderer>\n"
            "  </pipe>\n</qgis>\n")
