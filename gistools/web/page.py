"""The offline web map: one self-contained HTML page (Leaflet and the data inlined), as text.

Pure: the GeoJSON, the styles and Leaflet's own files come in, the page's text goes out (tasks.webmap reads and
writes). Nothing on the page asks the network for anything unless a basemap URL is given.
"""

from __future__ import annotations

import html
import json

__all__ = ["web_map_html", "script_json"]

_STYLE = """
html, body, #map { height: 100%; margin: 0; }
body { font: 14px/1.35 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; }
.gt-box { background: rgba(255, 255, 255, 0.92); padding: 6px 9px; border-radius: 4px;
          box-shadow: 0 1px 4px rgba(0, 0, 0, 0.35); max-width: 22em; }
.gt-box h3 { margin: 0 0 4px; font-size: 15px; }
.gt-swatch { display: inline-block; width: 14px; height: 14px; margin-right: 6px; vertical-align: -2px;
             border: 1px solid #555; }
.gt-box table { border-collapse: collapse; }
.gt-box td { padding: 0 6px 0 0; vertical-align: top; }
details.gt-box summary { cursor: pointer; font-weight: 600; }
.gt-pages a { display: block; }
"""

_SCRIPT = """
(function () {
  var data = %(data)s, classes = %(classes)s, options = %(options)s;
  var map = L.map("map", {zoomSnap: 0.25, preferCanvas: true});  // canvas: thousands of polygons stay fluid on a tablet
  if (options.basemap) {
    L.tileLayer(options.basemap, {maxZoom: 22, attribution: options.basemap_attribution || ""}).addTo(map);
  }
  var colour = {};
  classes.forEach(function (c) { colour[c.code] = c.colour; });
  function fmt(v, d) { return Number(v).toLocaleString(undefined, {maximumFractionDigits: d}); }
  var layer = L.geoJSON(data, {
    style: function (f) {
      return {color: "#333333", weight: 0.6, fillColor: colour[f.properties.class_code] || "#000000",
              fillOpacity: options.fill_opacity};
    },
    onEachFeature: function (f, l) {
      var p = f.properties;
      l.bindPopup("<b>" + p["class"] + "</b><br>" + fmt(p.area_acres, 2) + " acres, " + fmt(p.area_ha, 2) +
                  " ha<br>tile " + p.tile);
    }
  }).addTo(map);
  function fit() {
    if (layer.getLayers().length) { map.fitBounds(layer.getBounds(), {padding: [8, 8], animate: false}); }
    else { map.setView([0, 0], 2); }
  }
  fit();
  // a window resized (a tablet turned) before the user moved the map: fit the polygons again
  var moved = false;
  ["mousedown", "touchstart", "wheel", "keydown"].forEach(function (type) {
    map.getContainer().addEventListener(type, function () { moved = true; }, {passive: true});
  });
  map.on("resize", function () { if (!moved) { fit(); } });
  L.control.scale({metric: true, imperial: true, maxWidth: 160}).addTo(map);
  var legend = L.control({position: "bottomright"});
  legend.onAdd = function () {
    var div = L.DomUtil.create("div", "gt-box");
    div.innerHTML = "<h3>" + options.legend_title + "</h3>" + classes.map(function (c) {
      return "<div><span class='gt-swatch' style='background:" + c.colour + "'></span>" + c.name + "</div>";
    }).join("");
    return div;
  };
  legend.addTo(map);
  var info = L.control({position: "topright"});
  info.onAdd = function () {
    var div = L.DomUtil.create("details", "gt-box");
    div.innerHTML = options.parameters_html;
    L.DomEvent.disableClickPropagation(div);
    return div;
  };
  info.addTo(map);
  // for checks (tests/test_webmap.py): where a longitude / latitude is drawn, in the page's pixels
  window.gistoolsMap = map;
  window.gistoolsPixel = function (lon, lat) {
    var p = map.latLngToContainerPoint([lat, lon]);
    return [p.x, p.y];
  };
  var probe = /[#&]probe=([^&]+)/.exec(location.hash);  // #probe=lon,lat;lon,lat: their pixels into the page
  if (probe) {
    window.setTimeout(function () {  // once the page has settled (its size and view final)
      var pre = document.createElement("pre"), size = map.getSize();
      pre.id = "gistools-probe";
      pre.textContent = JSON.stringify({size: [size.x, size.y], zoom: map.getZoom(), pixels:
        decodeURIComponent(probe[1]).split(";").map(function (s) {
          var v = s.split(",").map(Number);
          return window.gistoolsPixel(v[0], v[1]);
        })});
      document.body.appendChild(pre);
    }, 1000);
  }
})();
"""


def script_json(value) -> str:
    """JSON to put inside a <script> element (no "</" can close it early)."""
    return json.dumps(value, separators=(",", ":")).replace("</", "<\\/")


def _parameters_html(title: str, parameters: dict, pages: list | None) -> str:
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>" for k, v in parameters.items())
    links = ""
    if pages:
        links = "<div class='gt-pages'><b>Parts of this map</b>" + "".join(
            f"<a href='{html.escape(href)}'>{html.escape(label)}</a>" for label, href in pages) + "</div>"
    return f"<summary>{html.escape(title)}</summary><table>{rows}</table>{links}"


def web_map_html(*, title: str, geojson: dict, classes: list, parameters: dict, leaflet_js: str, leaflet_css: str,
                 basemap: str | None = None, basemap_attribution: str | None = None, pages: list | None = None,
                 fill_opacity: float = 0.75, legend_title: str = "Shrub density") -> str:
    """The page's HTML. ``classes``: [{"code", "name", "colour"}] in legend order; ``parameters``: what made the
    map (shown in a panel); ``pages``: [(label, href)] of the other parts of a split map; ``basemap``: an XYZ tile
    URL template for users who are online (None: no request to any network address)."""
    options = {"basemap": basemap, "basemap_attribution": basemap_attribution, "fill_opacity": fill_opacity,
               "legend_title": html.escape(legend_title), "parameters_html": _parameters_html(title, parameters, pages)}
    script = _SCRIPT % {"data": script_json(geojson), "classes": script_json(classes), "options": script_json(options)}
    return (f"<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'>\n"
            f"<title>{html.escape(title)}</title>\n<style>\n{leaflet_css}\n{_STYLE}</style>\n"
            f"<script>\n{leaflet_js}\n</script>\n</head>\n<body>\n<div id='map'></div>\n"
            f"<script>\n{script}\n</script>\n</body>\n</html>\n")
