"""Deliverables for field teams from a shrub chain's output folder: gistools webmap, gistools scene, gistools mapbook."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputHtml,
    QgsProcessingOutputNumber,
    QgsProcessingParameterFile,
)

from .base import GROUP_DELIVER, GistoolsAlgorithm
from ..compat import FOLDER


class _DeliverableAlgorithm(GistoolsAlgorithm):
    """An algorithm that makes a deliverable from a shrub chain's output folder."""

    _group = GROUP_DELIVER
    _page = "commands/deliverables"

    def add_folder(self, needs: str):
        self.add(QgsProcessingParameterFile("FOLDER", f"Shrub chain output folder (with {needs})", behavior=FOLDER),
                 help="The folder gistools shrub (or the Shrub map algorithm) wrote.")


class WebMapAlgorithm(_DeliverableAlgorithm):
    _name, _display = "webmap", "Offline web map (HTML)"
    _help = ("One self-contained HTML page of a shrub chain's output folder (gistools webmap): the class polygons "
             "(simplified within half a cell, in WGS84) with Leaflet inlined, a legend, a scale bar, the parameters "
             "that made the map and a popup per polygon (class, area in acres and hectares, tile). It asks the network "
             "for nothing unless a basemap URL is given, so it works from a USB stick or a tablet in the field. A "
             "county past the size limit is split by tile into parts, the first page linking them. Given the output "
             "folders of gistools travel, viewshed or fuels, the page also draws their layers (switchable): the "
             "isochrones with a legend in minutes and the points last seen, the travel time under the cursor, the "
             "cells seen (semi-transparent) and the canopy base height classes. The page is "
             "written into the folder (shrub_map.html) and listed in the Results Viewer, which opens it in the "
             "browser.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("shrub_classes.gpkg")
        self.add_spec(command="webmap")
        self.addOutput(QgsProcessingOutputHtml("HTML", "Offline web map"))
        self.addOutput(QgsProcessingOutputFile("HTML_FILE", "Offline web map (file)"))
        self.addOutput(QgsProcessingOutputNumber("MEGABYTES", "Size of the page (MB)"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.webmap import web_map

        result = web_map(self.text(parameters, "FOLDER", context), **self.spec_values(parameters, context, feedback))
        feedback.pushInfo(f"wrote {result['html']} ({result['bytes'] / 1e6:.1f} MB, {result['features']:,} polygons"
                          + (f", {len(result['parts'])} parts" if result["parts"] else "") + ")")
        return {"HTML": result["html"], "HTML_FILE": result["html"], "MEGABYTES": result["bytes"] / 1e6}


class SceneAlgorithm(_DeliverableAlgorithm):
    _name, _display = "scene", "3D scene (glTF .glb)"
    _help = ("The surface of a shrub chain's output folder as a glTF binary mesh (gistools scene): the DSM (the DEM "
             "where the DSM has no value) in metres with the shrub classes as vertex colours, x east, y up, z south "
             "from the mosaic's south-west corner (origin and CRS in the asset's extras; scene.prj and scene.wld "
             "beside it). QGIS 3D, Cesium and Blender open it. Decimated (every k-th cell) to stay under the size "
             "given; heights can be exaggerated.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("dsm.vrt, classes.vrt")
        self.add_spec("surface", "exaggeration", "max_mb")
        self.addOutput(QgsProcessingOutputFile("GLB", "3D scene (.glb)"))
        self.addOutput(QgsProcessingOutputNumber("STEP", "Decimation step (every k-th cell)"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.scene import scene_glb

        r = scene_glb(self.text(parameters, "FOLDER", context), **self.spec_values(parameters, context, feedback))
        feedback.pushInfo(f"wrote {r['glb']} ({r['bytes'] / 1e6:.1f} MB, {r['vertices']:,} vertices, every "
                          f"{r['step']} cell(s)); open it in QGIS 3D (a mesh or 3D model), Cesium or Blender")
        return {"GLB": r["glb"], "STEP": r["step"]}


class MapBookAlgorithm(_DeliverableAlgorithm):
    _name, _display = "mapbook", "Map book (PDF)"
    _help = ("A PDF of a shrub chain's output folder to print for field teams (gistools mapbook): a page per tile of "
             "the tile index (each fitted to the page), or per sheet of a grid at a scale, each with the classes, "
             "roads and water, a coordinate grid, a locator map, the legend, a scale bar, a north arrow and the "
             "parameters; with a gistools travel folder, the isochrones and points last seen on every page; with a "
             "gistools viewshed folder, the cells seen; with a "
             "gistools fuels folder, a last page of the canopy base height classes. The PDF opens from the Results "
             "Viewer.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("classes.vrt")
        self.add_spec(command="mapbook",
                      labels={"tile_index": "Tile index (footprints): a page per tile; empty: a grid of sheets"})
        self.addOutput(QgsProcessingOutputFile("PDF", "Map book (PDF)"))
        self.addOutput(QgsProcessingOutputNumber("PAGES", "Pages"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.mapbook import map_book

        values = self.spec_values(parameters, context, feedback)
        r = map_book(self.text(parameters, "FOLDER", context), **{k: v for k, v in values.items() if v is not None})
        feedback.pushInfo(f"wrote {r['pdf']} ({r['pages']} pages)")
        return {"PDF": r["pdf"], "PAGES": r["pages"]}
