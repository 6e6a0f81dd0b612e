"""Ground and noise classification of LAS/LAZ tiles (gistools ground)."""

from __future__ import annotations

from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputNumber,
                       QgsProcessingParameterFolderDestination)

from .base import GistoolsAlgorithm
from .spec import method_labelled, own_default_text

class GroundAlgorithm(GistoolsAlgorithm):
    _name, _display = "ground", "Classify ground and noise"
    _page = "commands/ground"
    _tags = ("classification", "ground", "noise", "smrf", "smrftin", "tin", "csf", "copc", "dtm")
    _help = ("Ground (2) and noise (7 low, 18 high) classes of LAS/LAZ tiles (gistools ground): noise first (isolated "
             "voxels or a statistical rule, and points far below the ground surface), then ground by the Simple "
             "Morphological Filter (SMRF) or the Cloth Simulation Filter (CSF). Only the classification changes; every "
             "point, its order and every other attribute stay. Points of other classes (water, buildings) keep theirs. "
             "Neighbouring tiles' points are read within a buffer, so tiles equal one merged run. Writes one file per "
             "tile and a virtual point cloud (ground.vpc) indexing them; lengths take a unit (m, ft, ftUS).")

    def initAlgorithm(self, config=None):  # noqa: N802
        from gistools.parameters.lidar import COMMAND_DEFAULTS, DEFAULT_TEXTS

        self.add_tiles()
        self.add_spec(command="ground", defaults=COMMAND_DEFAULTS["ground"])
        own_default_text(self, DEFAULT_TEXTS["ground"])
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (classified tiles + ground.vpc)"))
        self.addOutput(QgsProcessingOutputFile("VPC", "Virtual point cloud of the classified tiles"))
        self.addOutput(QgsProcessingOutputNumber("CHANGED", "Points whose class changed"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.ground import GroundSettings, ground_from_tiles

        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        values["method"] = values.pop("ground_method")
        settings = GroundSettings(**{k: v for k, v in values.items() if v is not None})
        with method_labelled(self, "ground_method"):
            result = ground_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                       progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        changed = sum(t.get("changed") or 0 for t in result["tiles"])
        feedback.pushInfo(f"{changed:,} points changed class; virtual point cloud: {result['vpc']}")
        if result["vpc"]:
            self.load_on_completion(context, result["vpc"], "Classified tiles", "VPC", feedback)
        return {"OUTPUT_FOLDER": out, "VPC": result["vpc"], "CHANGED": changed}
