"""Deliverables for field teams from a shrub chain's output folder: gistools webmap, gistools scene, gistools mapbook."""

from __future__ import annotations

from qgis.core import QgsProcessingParameterFile

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

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("shrub_classes.gpkg")
        self.add_spec(command="webmap")
        self.add_outputs(
            None, HTML=("html", "Offline web map"), HTML_FILE=("file", "Offline web map (file)"),
            MEGABYTES=("number", "Size of the page (MB)"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.webmap import web_map

        result = web_map(self.text(parameters, "FOLDER", context), **self.spec_values(parameters, context, feedback))
        feedback.pushInfo(f"wrote {result['html']} ({result['bytes'] / 1e6:.1f} MB, {result['features']:,} polygons"
                          + (f", {len(result['parts'])} parts" if result["parts"] else "") + ")")
        return {"HTML": result["html"], "HTML_FILE": result["html"], "MEGABYTES": result["bytes"] / 1e6}


class SceneAlgorithm(_DeliverableAlgorithm):
    _name, _display = "scene", "3D scene (glTF .glb)"

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("dsm.vrt, classes.vrt")
        self.add_spec("surface", "exaggeration", "max_mb")
        self.add_outputs(None, GLB=("file", "3D scene (.glb)"), STEP=("number", "Decimation step (every k-th cell)"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.scene import scene_glb

        r = scene_glb(self.text(parameters, "FOLDER", context), **self.spec_values(parameters, context, feedback))
        feedback.pushInfo(f"wrote {r['glb']} ({r['bytes'] / 1e6:.1f} MB, {r['vertices']:,} vertices, every "
                          f"{r['step']} cell(s)); open it in QGIS 3D (a mesh or 3D model), Cesium or Blender")
        return {"GLB": r["glb"], "STEP": r["step"]}


class MapBookAlgorithm(_DeliverableAlgorithm):
    _name, _display = "mapbook", "Map book (PDF)"

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_folder("classes.vrt")
        self.add_spec(command="mapbook",
                      labels={"tile_index": "Tile index (footprints): a page per tile; empty: a grid of sheets"})
        self.add_outputs(None, PDF=("file", "Map book (PDF)"), PAGES=("number", "Pages"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.deliver.mapbook import map_book

        values = self.spec_values(parameters, context, feedback)
        r = map_book(self.text(parameters, "FOLDER", context), **{k: v for k, v in values.items() if v is not None})
        feedback.pushInfo(f"wrote {r['pdf']} ({r['pages']} pages)")
        return {"PDF": r["pdf"], "PAGES": r["pages"]}
