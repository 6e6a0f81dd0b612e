"""Heights above ground and what is made of them: gistools normalize, gistools metrics and gistools chm."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputFolder,
    QgsProcessingOutputNumber,
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorLayer,
)

from gistools.tasks import chm as _chm
from gistools.tasks import metrics as _metrics
from gistools.tasks import normalize as _normalize

from .base import POINT_FORMATS, PRESET_LABEL, PRESETS, GistoolsAlgorithm, int_list, labels
from ..compat import VECTOR_LINE, VECTOR_POLYGON

NORMALIZE = _normalize.NormalizeSettings()
METRICS = _metrics.MetricsSettings()
CHM = _chm.ChmSettings()
CHM_METHODS = list(_chm.CHM_METHODS)
CHM_LABELS = {"p2r": "Highest first return per cell (p2r)", "pitfree": "Pit-free (Khosravipour et al. 2014)",
              "tin": "TIN of the first returns"}
METRIC_RETURNS = list(_metrics.RETURNS)
# the metrics offered as a checklist (any other name goes in "More metrics")
COMMON_METRICS = ["count", "density", "z_min", "z_max", "z_mean", "z_median", "z_sd", "z_cv", "z_p25", "z_p50", "z_p75",
                  "z_p95", "i_mean", "i_max", "hag_p95", "cover_above2m", "fhd", "vci", "fuel_0_1m", "fuel_1_3m",
                  "fuel_3_6m"]
METRICS_HELP = ("Names as lasR spells them: z_ (elevation), i_ (intensity) or hag_ (height above ground) followed by "
                "min, max, mean, median, sum, sd, cv, pNN (percentile) or aboveX (share of points above X); count, "
                "density (points per square metre), cover_aboveX (share of first returns above X over the ground), "
                "fhd and vci (layer diversity of the heights), fuel_A_B (share of the returns up to B above the "
                "ground that are above A: ladder fuels). Thresholds take a unit (2m, 6ft); a bare number is in the "
                "tiles' vertical unit.")


class NormalizeAlgorithm(GistoolsAlgorithm):
    _name, _display = "normalize", "Heights above ground (normalize)"
    _readme_section = "heights-above-ground"
    _help = ("Height above ground of every point (gistools normalize): z minus the TIN of the ground points (classes 2 "
             "and 9) of the tile and its neighbours within the buffer, so tiles equal one TIN of all their ground "
             "(PDAL filters.hag_delaunay, lidR normalize_height(tin())). Written as a HeightAboveGround dimension "
             "(float32, in the tiles' vertical unit) or as z. Optionally sets vegetation classes 3 / 4 / 5 by the "
             "height bands, and road surface (11) and water (9) inside the breaklines' polygons. Writes one file per "
             "tile and normalized.vpc.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add(QgsProcessingParameterBoolean("REPLACE_Z", "Write the heights as z (no extra dimension)",
                                               defaultValue=NORMALIZE.replace_z))
        self.add(QgsProcessingParameterBoolean("CLASSIFY_VEGETATION", "Classify vegetation 3 / 4 / 5 by height (and "
                                               "roads 11, water 9)", defaultValue=NORMALIZE.classify_vegetation),
                 help="Unclassified points (0, 1) become low (up to band B1's top, 1 m), medium (to B3's top, 6 m) or "
                      "high vegetation; with breaklines, points of classes 0-2 at the ground inside roads become road "
                      "surface (11) and inside water water (9).")
        self.add(QgsProcessingParameterEnum("BANDS", PRESET_LABEL, options=labels(PRESETS),
                                            defaultValue=PRESETS.index(NORMALIZE.bands)), advanced=True)
        self.add_length("NOISE_FLOOR", "Height above ground that is still ground", NORMALIZE.noise_floor, advanced=True)
        self.add(QgsProcessingParameterVectorLayer("ROADS", "Road breaklines (edge of pavement)", [VECTOR_LINE],
                                                   optional=True))
        self.add(QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", [VECTOR_LINE], optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", [VECTOR_POLYGON], optional=True))
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add_length("BUFFER", "Neighbours' ground read within", NORMALIZE.buffer, advanced=True)
        self.add(QgsProcessingParameterEnum("FORMAT", "Output format", options=labels(POINT_FORMATS),
                                            defaultValue=POINT_FORMATS.index(NORMALIZE.format)), advanced=True)
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (tiles + normalized.vpc)"))
        self.addOutput(QgsProcessingOutputFile("VPC", "Virtual point cloud of the normalized tiles"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        classify = self.parameterAsBool(parameters, "CLASSIFY_VEGETATION", context)
        settings = _normalize.NormalizeSettings(
            buffer=self.text(parameters, "BUFFER", context), replace_z=self.parameterAsBool(parameters, "REPLACE_Z", context),
            classify_vegetation=classify, bands=PRESETS[self.parameterAsEnum(parameters, "BANDS", context)],
            noise_floor=self.text(parameters, "NOISE_FLOOR", context),
            format=POINT_FORMATS[self.parameterAsEnum(parameters, "FORMAT", context)], crs=self.crs_text(parameters, context))
        layers = {k.lower(): self.layer_spec(parameters, k, context, feedback) if classify else None
                  for k in ("ROADS", "HYDRO", "WATERBODIES")}
        result = _normalize.normalize_from_tiles(
            self.tiles(parameters, context), out, settings, **layers,
            reproject_vectors=self.parameterAsBool(parameters, "REPROJECT", context),
            jobs=self.parameterAsInt(parameters, "JOBS", context), scheduler=self.text(parameters, "SCHEDULER", context),
            overwrite=True, progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        feedback.pushInfo(f"virtual point cloud: {result['vpc']}")
        if result["vpc"]:
            self.load_on_completion(context, result["vpc"], "Heights above ground", "VPC")
        return {"OUTPUT_FOLDER": out, "VPC": result["vpc"]}


class MetricsAlgorithm(GistoolsAlgorithm):
    _name, _display = "metrics", "Cell metrics of the points"
    _readme_section = "cell-metrics"
    _help = ("Per-cell statistics of the points (gistools metrics; lasR rasterize / lidR pixel_metrics): one GeoTIFF "
             "per metric per tile on the snapped lattice of the rasters, and a VRT per metric (loaded). Cells without "
             "points are nodata. Neighbouring tiles' points are read, so tiles equal one merged run. " + METRICS_HELP)

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_length("CELL_SIZE", "Cell size", METRICS.cell_size)
        self.add(QgsProcessingParameterEnum("METRICS", "Metrics", options=COMMON_METRICS, allowMultiple=True,
                                            defaultValue=[COMMON_METRICS.index(m) for m in METRICS.metrics],
                                            optional=True), help=METRICS_HELP)
        self.add(QgsProcessingParameterString("MORE_METRICS", "More metrics (comma-separated names, e.g. z_p99,"
                                              "hag_above6ft,cover_above5m)", optional=True), help=METRICS_HELP)
        self.add(QgsProcessingParameterBoolean("NORMALIZED", "z metrics on heights above ground (hag_*)",
                                               defaultValue=METRICS.normalized))
        self.add(QgsProcessingParameterString("CLASSES", "Classes whose points count (comma-separated; empty: all but "
                                              "noise 7, 18)", optional=True), advanced=True)
        self.add(QgsProcessingParameterEnum("RETURNS", "Returns", options=labels(METRIC_RETURNS, all="Every return"),
                                            defaultValue=METRIC_RETURNS.index(METRICS.returns)), advanced=True)
        self.add_length("BUFFER", "Neighbours' ground read within (heights above ground)", METRICS.buffer, advanced=True)
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (a folder and a VRT per metric)"))
        self.addOutput(QgsProcessingOutputFolder("METRICS_FOLDER", "Folder of the metric rasters"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        chosen = [COMMON_METRICS[i] for i in self.parameterAsEnums(parameters, "METRICS", context)]
        more = [m.strip() for m in (self.text(parameters, "MORE_METRICS", context) or "").split(",") if m.strip()]
        settings = _metrics.MetricsSettings(
            cell_size=self.text(parameters, "CELL_SIZE", context), metrics=tuple(dict.fromkeys(chosen + more)),
            normalized=self.parameterAsBool(parameters, "NORMALIZED", context),
            classes=int_list(self.text(parameters, "CLASSES", context), "Classes"),
            returns=METRIC_RETURNS[self.parameterAsEnum(parameters, "RETURNS", context)],
            buffer=self.text(parameters, "BUFFER", context), crs=self.crs_text(parameters, context))
        result = _metrics.metrics_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                             jobs=self.parameterAsInt(parameters, "JOBS", context),
                                             scheduler=self.text(parameters, "SCHEDULER", context),
                                             progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        for name, vrt in result["mosaics"].items():
            self.load_on_completion(context, vrt, name, name)
        return {"OUTPUT_FOLDER": out, "METRICS_FOLDER": out}


class ChmAlgorithm(GistoolsAlgorithm):
    _name, _display = "chm", "Canopy height model (CHM)"
    _readme_section = "canopy-height-models"
    _help = ("Canopy height model of LAS/LAZ tiles (gistools chm; lidR rasterize_canopy): the first returns' heights "
             "above the TIN of the ground, gridded as the highest return per cell (p2r), a TIN of the returns, or "
             "pit-free (Khosravipour et al. 2014: TINs of the returns above a series of height thresholds, long "
             "triangles dropped, stacked by their maximum, so returns deep in a crown leave no pit). Neighbouring "
             "tiles' points are read, so tiles equal one merged run. Writes chm/<tile>.tif and chm.vrt (loaded); "
             "the log gives the pits left (cells more than 1 m below all 8 neighbours).")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add(QgsProcessingParameterEnum("METHOD", "Method", options=[CHM_LABELS[m] for m in CHM_METHODS],
                                            defaultValue=CHM_METHODS.index(CHM.method)))
        self.add_length("CELL_SIZE", "Cell size", CHM.cell_size)
        self.add(QgsProcessingParameterString("THRESHOLDS", "Pit-free height thresholds (comma-separated, with unit)",
                                              defaultValue=",".join(CHM.thresholds)), advanced=True)
        self.add_length("THRESHOLD_STEP", "Pit-free: a threshold every (0: only those given)", CHM.threshold_step,
                        advanced=True)
        self.add(QgsProcessingParameterString("MAX_EDGE", "Pit-free longest triangle edge: first layer, upper layers "
                                              "(0: no limit)", defaultValue=",".join(CHM.max_edge)), advanced=True)
        self.add_length("TIN_MAX_EDGE", "TIN longest triangle edge (0: no limit)", CHM.tin_max_edge, advanced=True)
        self.add_length("BUFFER", "Neighbours' points read within", CHM.buffer, advanced=True)
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (chm/ and chm.vrt)"))
        self.addOutput(QgsProcessingOutputRasterLayer("CHM", "Canopy height model"))
        self.addOutput(QgsProcessingOutputNumber("PITS", "Pits left (cells more than 1 m below all 8 neighbours)"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)

        def lengths(name):
            return tuple(v.strip() for v in (self.text(parameters, name, context) or "").split(",") if v.strip())

        settings = _chm.ChmSettings(
            cell_size=self.text(parameters, "CELL_SIZE", context),
            method=CHM_METHODS[self.parameterAsEnum(parameters, "METHOD", context)], thresholds=lengths("THRESHOLDS"),
            threshold_step=self.text(parameters, "THRESHOLD_STEP", context), max_edge=lengths("MAX_EDGE"),
            tin_max_edge=self.text(parameters, "TIN_MAX_EDGE", context), buffer=self.text(parameters, "BUFFER", context),
            crs=self.crs_text(parameters, context))
        result = _chm.chm_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                     jobs=self.parameterAsInt(parameters, "JOBS", context),
                                     scheduler=self.text(parameters, "SCHEDULER", context), progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        feedback.pushInfo(f"{result['pits']:,} pits left")
        self.load_on_completion(context, result["mosaic"], "Canopy height model", "CHM")
        return {"OUTPUT_FOLDER": out, "CHM": result["mosaic"], "PITS": result["pits"]}
