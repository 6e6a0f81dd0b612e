"""QGIS layer styles written beside outputs (``<name>.qml``, which QGIS loads as the layer's default style)."""

from __future__ import annotations

import html
import logging
from pathlib import Path

from .atomic import atomic_path

log = logging.getLogger(__name__)

__all__ = ["categorized_fill_qml", "categorized_qml", "graduated_fill_qml", "line_qml", "outline_qml",
           "add_layer_styles", "write_polygon_style", "rgba", "MARK"]

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


_HEAD = "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + MARK + "\n" + \
    '<qgis version="3.22.0" styleCategories="Symbology|Labeling">\n'


def _symbol(name, kind: str, colour: str, *, width: float = 0.5, dash: bool = False, fill_alpha: int = 255) -> str:
    """A QGIS symbol: ``kind`` "fill" (a fill of ``colour`` at ``fill_alpha``, a dark outline) or "line"."""
    if kind == "line":
        return (f'      <symbol type="line" name="{name}" alpha="1" clip_to_extent="1" force_rhr="0">\n'
                '        <layer class="SimpleLine" enabled="1" pass="0" locked="0">\n'
                f'          <prop k="line_color" v="{_rgb(colour)}"/>\n'
                f'          <prop k="line_width" v="{width:g}"/>\n'
                f'          <prop k="line_style" v="{"dash" if dash else "solid"}"/>\n'
                '        </layer>\n      </symbol>')
    r, g, b, _ = rgba(colour)
    return (f'      <symbol type="fill" name="{name}" alpha="1" clip_to_extent="1" force_rhr="0">\n'
            '        <layer class="SimpleFill" enabled="1" pass="0" locked="0">\n'
            f'          <prop k="color" v="{r},{g},{b},{fill_alpha}"/>\n'
            '          <prop k="style" v="solid"/>\n'
            '          <prop k="outline_color" v="35,35,35,255"/>\n'
            f'          <prop k="outline_width" v="{width:g}"/>\n'
            '        </layer>\n      </symbol>')


def categorized_qml(field: str, categories: dict, kind: str = "fill") -> str:
    """A QGIS style (QML) drawing features by the value of ``field``: ``categories`` {value: (label, "#rrggbb")},
    fills (``kind`` "fill") or lines ("line")."""
    cats, symbols = [], []
    for i, (value, (label, colour)) in enumerate(categories.items()):
        cats.append(f'      <category value="{html.escape(str(value))}" label="{html.escape(label)}" symbol="{i}" '
                    'render="true"/>')
        symbols.append(_symbol(i, kind, colour, width=0.6 if kind == "line" else 0.2, fill_alpha=200))
    return (_HEAD + f'  <renderer-v2 type="categorizedSymbol" attr="{html.escape(field)}" symbollevels="0" '
            'enableorderby="0" forceraster="0">\n    <categories>\n' + "\n".join(cats)
            + "\n    </categories>\n    <symbols>\n" + "\n".join(symbols) + "\n    </symbols>\n  </renderer-v2>\n"
            "</qgis>\n")


def graduated_fill_qml(field: str, breaks, ramp, *, label_field: str | None = None, digits: int = 4) -> str:
    """A QGIS style (QML) filling polygons by classes of ``field`` between ``breaks`` (increasing, n + 1 values for
    n classes, ``ramp``'s colours in turn), outlined dark, labelled with ``label_field``."""
    ranges, symbols = [], []
    for i, (low, high) in enumerate(zip(breaks, breaks[1:])):
        ranges.append(f'      <range lower="{low:.12g}" upper="{high:.12g}" symbol="{i}" '
                      f'label="{low:.{digits}f} - {high:.{digits}f}" render="true"/>')
        symbols.append(_symbol(i, "fill", ramp[min(i, len(ramp) - 1)], width=0.4, fill_alpha=170))
    labels = ""
    if label_field:
        labels = ('  <labeling type="simple">\n    <settings calloutType="simple">\n'
                  f'      <text-style fieldName="{html.escape(label_field)}" fontSize="10" textColor="0,0,0,255" '
                  'isExpression="0" fontWeight="75"/>\n'
                  '      <text-buffer bufferDraw="1" bufferSize="1" bufferColor="255,255,255,255"/>\n'
                  '      <placement placement="0"/>\n    </settings>\n  </labeling>\n')
    return (_HEAD + f'  <renderer-v2 type="graduatedSymbol" attr="{html.escape(field)}" graduatedMethod="GraduatedColor" '
            'symbollevels="0" enableorderby="0" forceraster="0">\n    <ranges>\n' + "\n".join(ranges)
            + "\n    </ranges>\n    <symbols>\n" + "\n".join(symbols) + "\n    </symbols>\n  </renderer-v2>\n"
            + labels + "</qgis>\n")


def line_qml(colour: str, width: float = 0.6, dash: bool = False) -> str:
    """A QGIS style (QML) of one line symbol (or the outline of polygons, unfilled, when used on them)."""
    return (_HEAD + '  <renderer-v2 type="singleSymbol" symbollevels="0" enableorderby="0" forceraster="0">\n'
            '    <symbols>\n' + _symbol(0, "line", colour, width=width, dash=dash) + "\n    </symbols>\n"
            "  </renderer-v2>\n</qgis>\n")


def outline_qml(colour: str, width: float = 0.5) -> str:
    """A QGIS style (QML) of polygons drawn as outlines only."""
    r, g, b, _ = rgba(colour)
    return (_HEAD + '  <renderer-v2 type="singleSymbol" symbollevels="0" enableorderby="0" forceraster="0">\n'
            '    <symbols>\n      <symbol type="fill" name="0" alpha="1" clip_to_extent="1" force_rhr="0">\n'
            '        <layer class="SimpleFill" enabled="1" pass="0" locked="0">\n'
            '          <prop k="style" v="no"/>\n'
            f'          <prop k="outline_color" v="{r},{g},{b},255"/>\n'
            f'          <prop k="outline_width" v="{width:g}"/>\n'
            '        </layer>\n      </symbol>\n    </symbols>\n  </renderer-v2>\n</qgis>\n')


def add_layer_styles(gpkg, styles: dict) -> None:
    """Store ``styles`` ({layer: QML}) in a GeoPackage's ``layer_styles`` table as each layer's default style, as
    QGIS saves them (Layer Properties > Style > Save to Database): QGIS applies them when it opens the layers."""
    import sqlite3

    con = sqlite3.connect(str(gpkg))
    try:
        con.execute("CREATE TABLE IF NOT EXISTS layer_styles (id INTEGER PRIMARY KEY AUTOINCREMENT, "
                    "f_table_catalog TEXT(256), f_table_schema TEXT(256), f_table_name TEXT(256), "
                    "f_geometry_column TEXT(256), styleName TEXT(30), styleQML TEXT, styleSLD TEXT, "
                    "useAsDefault BOOLEAN, description TEXT, owner TEXT(30), ui TEXT(30), "
                    "update_time DATETIME DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')))")  # GeoPackage's form
        con.execute("INSERT OR IGNORE INTO gpkg_contents (table_name, data_type, identifier) "
                    "VALUES ('layer_styles', 'attributes', 'layer_styles')")
        for layer, qml in styles.items():
            column = con.execute("SELECT column_name FROM gpkg_geometry_columns WHERE table_name = ?",
                                 (layer,)).fetchone()
            con.execute("INSERT INTO layer_styles (f_table_catalog, f_table_schema, f_table_name, f_geometry_column, "
                        "styleName, styleQML, styleSLD, useAsDefault, description, owner, ui) "
                        "VALUES ('', '', ?, ?, ?, ?, '', 1, 'gistools', '', '')",
                        (layer, column[0] if column else "geom", f"{layer} (gistools)", qml))
        con.commit()
    finally:
        con.close()
