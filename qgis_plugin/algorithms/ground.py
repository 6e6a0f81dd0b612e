"""Ground and noise classification of LAS/LAZ tiles (gistools ground)."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
)

from .base import labels, GistoolsAlgorithm, GROUND, GROUND_METHODS, NOISE_METHODS, POINT_FORMATS
from ..compat import DOUBLE


class GroundAlgorithm(GistoolsAlgorithm):
    _name, _display = "ground", "Classify ground and noise"
    _readme_section = "ground-and-noise"
    _help = ("Ground (2) and noise (7 low, 18 high) classes of LAS/LAZ tiles (gistools ground): noise first (isolated "
             "voxels or a statistical rule, and points far below the ground surface), then ground by the Simple "
             "Morphological Filter (SMRF) or the Cloth Simulation Filter (CSF). Only the classification changes; every "
             "point, its order and every other attribute stay. Points of other classes (water, buildings) keep theirs. "
             "Neighbouring tiles' points are read within a buffer, so tiles equal one merged run. Writes one file per "
             "tile and a virtual point cloud (ground.vpc) indexing them; lengths take a unit (m, ft, ftUS).")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add(QgsProcessingParameterEnum("METHOD", "Ground filter", options=labels(GROUND_METHODS),
                                            defaultValue=GROUND_METHODS.index(GROUND.method)))
        self.add(QgsProcessingParameterEnum("NOISE", "Noise filter", options=labels(NOISE_METHODS),
                                            defaultValue=NOISE_METHODS.index(GROUND.noise)))
        self.add_length("CELL", "SMRF cell size", GROUND.cell, advanced=True)
        self.add(QgsProcessingParameterNumber("SLOPE", "SMRF slope (rise over run)", type=DOUBLE,
                                              defaultValue=GROUND.slope, minValue=0.0), advanced=True)
        self.add_length("WINDOW", "SMRF largest window radius", GROUND.window, advanced=True)
        self.add_length("THRESHOLD", "SMRF elevation threshold", GROUND.threshold, advanced=True)
        self.add_length("SCALAR", "SMRF elevation scalar (threshold per unit of slope)", GROUND.scalar, advanced=True)
        self.add_length("CSF_RESOLUTION", "CSF cloth resolution", GROUND.csf_resolution, advanced=True)
        self.add_length("CSF_THRESHOLD", "CSF class threshold", GROUND.csf_threshold, advanced=True)
        self.add_length("IVF_RES", "IVF voxel size", GROUND.ivf_res, advanced=True)
        self.add(QgsProcessingParameterNumber("IVF_N", "IVF: noise with at most this many other points in 27 voxels",
                                              defaultValue=GROUND.ivf_n, minValue=0), advanced=True)
        self.add(QgsProcessingParameterBoolean("KEEP_CLASSES", "Points no longer ground or noise keep their class (else 1)",
                                               defaultValue=GROUND.keep_classes), advanced=True)
        self.add(QgsProcessingParameterEnum("FORMAT", "Output format", options=labels(POINT_FORMATS),
                                            defaultValue=POINT_FORMATS.index(GROUND.format)), advanced=True)
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (classified tiles + ground.vpc)"))
        self.addOutput(QgsProcessingOutputFile("VPC", "Virtual point cloud of the classified tiles"))
        self.addOutput(QgsProcessingOutputNumber("CHANGED", "Points whose class changed"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.ground import GroundSettings, ground_from_tiles

        out = self.output_folder(parameters, context)
        settings = GroundSettings(
            method=GROUND_METHODS[self.parameterAsEnum(parameters, "METHOD", context)],
            noise=NOISE_METHODS[self.parameterAsEnum(parameters, "NOISE", context)],
            cell=self.text(parameters, "CELL", context), slope=self.parameterAsDouble(parameters, "SLOPE", context),
            window=self.text(parameters, "WINDOW", context), threshold=self.text(parameters, "THRESHOLD", context),
            scalar=self.text(parameters, "SCALAR", context),
            csf_resolution=self.text(parameters, "CSF_RESOLUTION", context),
            csf_threshold=self.text(parameters, "CSF_THRESHOLD", context),
            ivf_res=self.text(parameters, "IVF_RES", context), ivf_n=self.parameterAsInt(parameters, "IVF_N", context),
            keep_classes=self.parameterAsBool(parameters, "KEEP_CLASSES", context),
            format=POINT_FORMATS[self.parameterAsEnum(parameters, "FORMAT", context)], crs=self.crs_text(parameters, context))
        result = ground_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                   jobs=self.parameterAsInt(parameters, "JOBS", context),
                                   scheduler=self.text(parameters, "SCHEDULER", context), progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        changed = sum(t.get("changed") or 0 for t in result["tiles"])
        feedback.pushInfo(f"{changed:,} points changed class; virtual point cloud: {result['vpc']}")
        if result["vpc"]:
            self.load_on_completion(context, result["vpc"], "Classified tiles", "VPC")
        return {"OUTPUT_FOLDER": out, "VPC": result["vpc"], "CHANGED": changed}
