"""QGIS layer styles written beside outputs (``<name>.qml``, which QGIS loads as the layer's default style)."""

from __future__ import annotations

import html
from pathlib import Path

from .atomic import atomic_path

__all__ = ["categorized_fill_qml", "write_polygon_style"]


def _rgb(hex_colour: str) -> str:
    h = hex_colour.lstrip("#")
    return f"{int(h[0:2], 16)},{int(h[2:4], 16)},{int(h[4:6], 16)},255"


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
    return ("<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n"
            '<qgis version="3.22.0" styleCategories="Symbology">\n'
            f'  <renderer-v2 type="categorizedSymbol" attr="{html.escape(field)}" symbollevels="0" enableorderby="0" '
            'forceraster="0">\n    <categories>\n' + "\n".join(cats) + "\n    </categories>\n    <symbols>\n"
            + "\n".join(symbols) + "\n    </symbols>\n  </renderer-v2>\n</qgis>\n")


def write_polygon_style(layer_path, field: str, categories: dict) -> Path:
    """``<layer file stem>.qml`` beside a vector file, atomically; QGIS applies it when it opens the layer."""
    path = Path(layer_path).with_suffix(".qml")
    with atomic_path(path, overwrite=True) as tmp:
        tmp.write_text(categorized_fill_qml(field, categories))
    return path
