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
    if path.exists():
        try:
            ours = MARK in path.read_text(errors="replace", encoding="utf-8")[:4096]
        except OSError:
            ours = False
        if not ours:
            log.info("%s: kept (a style gistools did not write)", path)
            return None
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_text(categorized_fill_qml(field, categories), encoding="utf-8")
    return path
