"""Ground and noise classification of LAS/LAZ tiles (gistools ground)."""

from __future__ import annotations


from .base import GistoolsAlgorithm
from .spec import method_labelled, own_default_text

class GroundAlgorithm(GistoolsAlgorithm):
    _name, _display = "ground", "Classify ground and noise"
    _page = "commands/ground"
    _tags = ("classification", "ground", "noise", "smrf", "smrftin", "adaptive", "tin", "csf", "copc", "dtm")

    def initAlgorithm(self, config=None):  # noqa: N802
        from gistools.parameters.lidar import COMMAND_DEFAULTS, DEFAULT_TEXTS

        self.add_tiles()
        self.add_spec(command="ground", defaults=COMMAND_DEFAULTS["ground"])
        own_default_text(self, DEFAULT_TEXTS["ground"])
        self.add_outputs(
            "Output folder (classified tiles + ground.vpc)",
            VPC=("file", "Virtual point cloud of the classified tiles"),
            CHANGED=("number", "Points whose class changed"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.ground import GroundSettings, ground_from_tiles

        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        values["method"] = values.pop("ground_method")
        settings = GroundSettings(**{k: v for k, v in values.items() if v is not None})
        with method_labelled(self, "ground_method"):
            result = ground_from_tiles(self.tiles(parameters, context, feedback), out, settings, overwrite=True,
                                       progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        changed = sum(t.get("changed") or 0 for t in result["tiles"])
        feedback.pushInfo(f"{changed:,} points changed class; virtual point cloud: {result['vpc']}")
        if result["vpc"]:
            self.load_on_completion(context, result["vpc"], "Classified tiles", "VPC", feedback)
        return {"OUTPUT_FOLDER": out, "VPC": result["vpc"], "CHANGED": changed}
