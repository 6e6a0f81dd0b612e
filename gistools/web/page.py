"""The offline web map: one self-contained HTML page (Leaflet and the data inlined), as text.

Pure: the GeoJSON, the styles and Leaflet's own files come in, the page's text goes out (deliver.webmap reads and
writes). Nothing on the page asks the network for anything unless a basemap URL is given.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import re
from urllib.parse import urlsplit

__all__ = ["web_map_html", "script_json", "content_security_policy"]

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
  var data = %(data)s, classes = %(classes)s, options = %(options)s, extra = %(extra)s;
  var map = L.map("map", {zoomSnap: 0.25, preferCanvas: true});  // canvas: thousands of polygons stay fluid on a tablet
  if (options.basemap) {
    L.tileLayer(options.basemap, {maxZoom: 22, attribution: options.basemap_attribution || ""}).addTo(map);
  }
  var colour = {};
  classes.forEach(function (c) { colour[c.code] = c.colour; });
  function fmt(v, d) { return Number(v).toLocaleString(undefined, {maximumFractionDigits: d}); }
  // every value from the data reaches the page as text nodes, never as markup
  function el(tag, text, cls) {
    var e = document.createElement(tag);
    if (text !== undefined) { e.textContent = String(text); }
    if (cls) { e.className = cls; }
    return e;
  }
  function popup(p) {
    var div = el("div");
    div.appendChild(el("b", p["class"]));
    div.appendChild(el("br"));
    div.appendChild(document.createTextNode(fmt(p.area_acres, 2) + " acres, " + fmt(p.area_ha, 2) + " ha"));
    div.appendChild(el("br"));
    div.appendChild(document.createTextNode("tile " + p.tile));
    return div;
  }
  var layer = L.geoJSON(data, {
    style: function (f) {
      return {color: "#333333", weight: 0.6, fillColor: colour[f.properties.class_code] || "#000000",
              fillOpacity: options.fill_opacity};
    },
    onEachFeature: function (f, l) {
      l.bindPopup(function () { return popup(f.properties); });
    }
  }).addTo(map);
  var overlays = {}, hex = /^#[0-9a-fA-F]{6}$/;
  function safe(c) { return hex.test(c) ? c : "#000000"; }
  if (extra.viewshed) {  // the cells seen: an inlined PNG in Web Mercator, its corners in latitude / longitude
    overlays["Viewshed (cells seen)"] = L.imageOverlay(extra.viewshed.url, extra.viewshed.bounds,
                                                       {opacity: 1, interactive: false}).addTo(map);
  }
  if (extra.cbh) {
    overlays["Canopy base height"] = L.geoJSON(extra.cbh, {
      style: function (f) {
        var c = extra.cbh_legend[f.properties.class_code - 1];
        return {color: "#333333", weight: 0.4, fillColor: safe(c ? c.colour : ""), fillOpacity: 0.6};
      },
      onEachFeature: function (f, l) { l.bindPopup(function () { return el("b", f.properties["class"]); }); }
    }).addTo(map);
  }
  if (extra.isochrones) {
    overlays["Isochrones"] = L.geoJSON(extra.isochrones, {
      style: function (f) {
        var c = safe(f.properties.colour);
        return {color: c, weight: 1.5, fillColor: c, fillOpacity: options.isochrone_opacity};
      },
      onEachFeature: function (f, l) {
        l.bindPopup(function () {
          var div = el("div");
          div.appendChild(el("b", f.properties.name));
          div.appendChild(el("br"));
          div.appendChild(document.createTextNode("within " + fmt(f.properties.minutes, 1) + " min: " +
            fmt(f.properties.acres, 1) + " acres, " + fmt(f.properties.hectares, 1) + " ha"));
          return div;
        });
      }
    }).addTo(map);
  }
  if (extra.segments) {  // the search plan's segments: shaded by POA, their figures under the cursor
    overlays["Search segments"] = L.geoJSON(extra.segments, {
      style: function (f) {
        return {color: "#08306b", weight: 1.2, fillColor: "#e31a1c",
                fillOpacity: 0.05 + 0.5 * Math.max(0, Math.min(1, Number(f.properties.share) || 0))};
      },
      onEachFeature: function (f, l) {
        var p = f.properties, div = el("div");
        div.appendChild(el("b", "Segment " + p.segment + " (rank " + p.rank + ")"));
        div.appendChild(el("br"));
        div.appendChild(document.createTextNode("POA " + fmt(100 * p.poa, 2) + " %%, POD " + fmt(100 * p.pod, 1) +
          " %% (" + fmt(p.hours, 1) + " searcher-hours), " + fmt(p.area_ha, 2) + " ha, " + p.vegetation +
          (p.minutes_from_staging === null ? "" : ", " + fmt(p.minutes_from_staging, 1) + " min from staging")));
        l.bindTooltip(div, {sticky: true});
      }
    }).addTo(map);
  }
  if (extra.routes) {
    overlays["Routes"] = L.geoJSON(extra.routes, {
      style: function (f) {
        return f.properties.litter ? {color: "#b2182b", weight: 3, dashArray: "8 6"} : {color: "#e08214", weight: 2};
      },
      onEachFeature: function (f, l) {
        var p = f.properties;
        l.bindTooltip(el("span", (p.litter ? "Litter carry to " : "Route to " + p.kind + " ") + p.target + ": " +
          fmt(p.minutes, 1) + " min, " + fmt(p.length_m, 0) + " m"), {sticky: true});  // text, never HTML
      }
    }).addTo(map);
  }
  if (extra.last_seen) {
    var seen = L.layerGroup();
    extra.last_seen.forEach(function (p) {
      L.circleMarker([p.lat, p.lon], {radius: 7, color: "#000000", weight: 2, fillColor: options.last_seen_colour,
                                      fillOpacity: 1}).bindPopup(function () {
        var div = el("div");
        div.appendChild(el("b", "Last seen"));
        div.appendChild(el("br"));
        div.appendChild(document.createTextNode(p.label));
        return div;
      }).addTo(seen);
    });
    overlays["Points last seen"] = seen.addTo(map);
  }
  if (Object.keys(overlays).length) {
    L.control.layers(null, overlays, {collapsed: false, position: "topleft"}).addTo(map);
  }
  if (extra.minutes) {  // the travel time under the cursor, from the grid of minutes (tenths) in Web Mercator
    var g = extra.minutes, readout = L.control({position: "bottomleft"}), box;
    readout.onAdd = function () {
      box = L.DomUtil.create("div", "gt-box");
      box.id = "gt-travel";
      box.textContent = "travel time: move the cursor over the map";
      return box;
    };
    readout.addTo(map);
    map.on("mousemove", function (e) {
      var m = L.CRS.EPSG3857.project(e.latlng), col = Math.floor((m.x - g.west) / g.dx),
          row = Math.floor((g.north - m.y) / g.dy), v = -1;
      if (col >= 0 && row >= 0 && col < g.cols && row < g.rows) { v = g.values[row * g.cols + col]; }
      box.textContent = v < 0 ? "travel time: not reached" :
        "travel time: " + (v < 100 ? (v / 10).toFixed(1) : Math.round(v / 10)) + " min";
    });
  }
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
    div.appendChild(el("h3", options.legend_title));
    classes.forEach(function (c) {
      var row = el("div"), swatch = el("span", undefined, "gt-swatch");
      swatch.style.background = /^#[0-9a-fA-F]{6}$/.test(c.colour) ? c.colour : "#000000";
      row.appendChild(swatch);
      row.appendChild(document.createTextNode(c.name));
      div.appendChild(row);
    });
    return div;
  };
  legend.addTo(map);
  [["Travel time", extra.legend], ["Canopy base height", extra.cbh_legend]].forEach(function (pair) {
    if (!pair[1]) { return; }
    var more = L.control({position: "bottomright"});
    more.onAdd = function () {
      var div = L.DomUtil.create("div", "gt-box");
      div.appendChild(el("h3", pair[0]));
      pair[1].forEach(function (c) {
        var row = el("div"), swatch = el("span", undefined, "gt-swatch");
        swatch.style.background = safe(c.colour);
        row.appendChild(swatch);
        row.appendChild(document.createTextNode(c.name));
        div.appendChild(row);
      });
      if (pair[0] === "Travel time" && extra.last_seen) {
        var row = el("div"), dot = el("span", undefined, "gt-swatch");
        dot.style.background = options.last_seen_colour;
        dot.style.borderRadius = "50%%";
        row.appendChild(dot);
        row.appendChild(document.createTextNode("point last seen"));
        div.appendChild(row);
      }
      return div;
    };
    more.addTo(map);
  });
  var info = L.control({position: "topright"});
  info.onAdd = function () {
    var div = L.DomUtil.create("details", "gt-box"), table = el("table");
    div.appendChild(el("summary", options.title));
    options.parameters.forEach(function (kv) {
      var tr = el("tr");
      tr.appendChild(el("td", kv[0]));
      tr.appendChild(el("td", kv[1]));
      table.appendChild(tr);
    });
    div.appendChild(table);
    if (options.pages.length) {
      var links = el("div", undefined, "gt-pages");
      links.appendChild(el("b", "Parts of this map"));
      options.pages.forEach(function (page) {
        var a = el("a", page[0]);
        a.href = page[1];
        links.appendChild(a);
      });
      div.appendChild(links);
    }
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
  if (/[#&]popups(&|$)/.test(location.hash)) {  // #popups: open every polygon's popup (the injection test)
    layer.eachLayer(function (l) { l.openPopup(); });
    Object.keys(overlays).forEach(function (k) {  // then the overlays' (the points last seen last)
      if (overlays[k].eachLayer) {
        overlays[k].eachLayer(function (l) {
          if (l.getPopup()) { l.openPopup(); }
          if (l.getTooltip && l.getTooltip()) { l.openTooltip(); }  // the segments' and routes' figures
        });
      }
    });
  }
  var cursor = /[#&]cursor=([-0-9.]+),([-0-9.]+)/.exec(location.hash);  // #cursor=lon,lat: the mouse moved there
  if (cursor) {
    window.setTimeout(function () {
      var p = map.latLngToContainerPoint([Number(cursor[2]), Number(cursor[1])]),
          r = map.getContainer().getBoundingClientRect();
      map.getContainer().dispatchEvent(new MouseEvent("mousemove", {clientX: r.left + p.x, clientY: r.top + p.y,
                                                                    bubbles: true}));
    }, 1000);
  }
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
    """JSON to put inside a <script> element (no "</" can close it early, no "<!--" can open a comment)."""
    return (json.dumps(value, separators=(",", ":")).replace("</", "<\\/").replace("<!--", "<\\u0021--")
            .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029"))


def _source(url: str | None) -> str:
    """The Content-Security-Policy source of an XYZ tile URL's host ({s}.tile.openstreetmap.org: *.tile.openstreetmap.org);
    its scheme alone where a placeholder sits elsewhere in the host."""
    if not url:
        return ""
    parts = urlsplit(url)
    host = parts.netloc
    head, _, rest = host.partition(".")
    if re.fullmatch(r"\{[a-z]+\}", head) and rest and "{" not in rest:
        host = "*." + rest
    if "{" in host or not re.fullmatch(r"[A-Za-z0-9.*:\[\]-]+", host):
        return f" {parts.scheme}:"
    return f" {parts.scheme}://{host}"


def content_security_policy(scripts: list[str], basemap: str | None = None) -> str:
    """The page's policy: no script but its own inline ones (by their sha256, so no inline handler or injected
    script runs), nothing fetched but data: images and the basemap's tiles, no plug-ins, forms or base URL."""
    hashes = " ".join("'sha256-" + base64.b64encode(hashlib.sha256(s.encode("utf-8")).digest()).decode() + "'"
                      for s in scripts)
    return (f"default-src 'none'; script-src {hashes}; style-src 'unsafe-inline'; img-src data:{_source(basemap)}; "
            "base-uri 'none'; form-action 'none'; object-src 'none'")


def web_map_html(*, title: str, geojson: dict, classes: list, parameters: dict, leaflet_js: str, leaflet_css: str,
                 basemap: str | None = None, basemap_attribution: str | None = None, pages: list | None = None,
                 fill_opacity: float = 0.75, legend_title: str = "Shrub density", layers: dict | None = None) -> str:
    """The page's HTML. ``classes``: [{"code", "name", "colour"}] in legend order; ``parameters``: what made the
    map (shown in a panel); ``pages``: [(label, href)] of the other parts of a split map; ``basemap``: an XYZ tile
    URL template for users who are online (None: no request to any network address); ``layers``: the search-and-rescue
    and fire layers (gistools.deliver.layers: ``isochrones``, ``legend``, ``last_seen``, ``minutes``, ``viewshed``,
    ``cbh``, ``cbh_legend``, ``segments``, ``routes``), drawn over the polygons with a layer switcher.

    Every value from the data (class names, tile names, parameters, the title) reaches the page as DOM text, never
    as markup, and a Content-Security-Policy lets only the page's own two scripts run."""
    extra = dict(layers or {})
    if "viewshed" in extra and not str(extra["viewshed"].get("url", "")).startswith("data:image/png;base64,"):
        raise ValueError("the viewshed overlay must be an inlined PNG (a data: URL)")
    options = {"basemap": basemap, "fill_opacity": fill_opacity, "last_seen_colour": "#ff00ff", "isochrone_opacity": 0.35, "title": str(title), "legend_title": str(legend_title),
               # Leaflet shows the attribution as markup: given as text, it is escaped
               "basemap_attribution": html.escape(basemap_attribution) if basemap_attribution else None,
               "parameters": [[str(k), str(v)] for k, v in parameters.items()],
               "pages": [[str(label), str(href)] for label, href in (pages or [])]}
    script = _SCRIPT % {"data": script_json(geojson), "classes": script_json(classes), "options": script_json(options),
                       "extra": script_json(extra)}
    leaflet = f"\n{leaflet_js}\n"
    ours = f"\n{script}\n"
    policy = html.escape(content_security_policy([leaflet, ours], basemap))
    return (f"<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
            f"<meta http-equiv='Content-Security-Policy' content=\"{policy}\">\n"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'>\n"
            f"<title>{html.escape(str(title))}</title>\n<style>\n{leaflet_css}\n{_STYLE}</style>\n"
            f"<script>{leaflet}</script>\n</head>\n<body>\n<div id='map'></div>\n"
            f"<script>{ours}</script>\n</body>\n</html>\n")
