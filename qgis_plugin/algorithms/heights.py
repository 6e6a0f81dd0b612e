"""Heights above ground and what is made of them: gistools normalize, gistools metrics, gistools chm and gistools
fuels."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputFolder,
    QgsProcessingOutputNumber,
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterFolderDestination,
)

from gistools.parameters.lidar import COMMAND_DEFAULTS
from gistools.products import chm as _chm
from gistools.products import fuels as _fuels
from gistools.products import metrics as _metrics
from gistools.products import normalize as _normalize

from .base import GistoolsAlgorithm
from ..compat import OPTIONAL
from .spec import flag_parameters, method_labelled
from ..compat import ADVANCED

BREAKLINES = ("roads", "hydro", "waterbodies")  # read only when vegetation is classified
METRICS_HELP = ("Names as lasR spells them: z_ (elevation), i_ (intensity) or hag_ (height above ground) followed by "
                "min, max, mean, median, sum, sd, cv, pNN (percentile) or aboveX (share of points above X); count, "
                "density (points per square metre), cover_aboveX (share of first returns above X over the ground), "
                "fhd and vci (layer diversity of the heights), fuel_A_B (share of the returns up to B above the "
                "ground that are above A: ladder fuels). Thresholds take a unit (2m, 6ft); a bare number is in the "
                "tiles' vertical unit.")


def _lengths(text) -> tuple:
    return tuple(v.strip() for v in (text or "").split(",") if v.strip())


class NormalizeAlgorithm(GistoolsAlgorithm):
    _renamed = {"BANDS": "PRESET"}  # the height band limits are PRESET in every algorithm
    _name, _display = "normalize", "Heights above ground (normalize)"
    _page = "commands/normalize"
    _tags = ("normalize", "height above ground", "hag", "canopy")
    _help = ("Height above ground of every point (gistools normalize): z minus the TIN of the ground points (classes 2 "
             "and 9) of the tile and its neighbours within the buffer, so tiles equal one TIN of all their ground "
             "(PDAL filters.hag_delaunay, lidR normalize_height(tin())). Written as a HeightAboveGround dimension "
             "(float32, in the tiles' vertical unit) or as z. Optionally sets vegetation classes 3 / 4 / 5 by the "
             "height bands, and road surface (11) and water (9) inside the breaklines' polygons. Writes one file per "
             "tile and normalized.vpc.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="normalize", defaults=COMMAND_DEFAULTS["normalize"])
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (tiles + normalized.vpc)"))
        self.addOutput(QgsProcessingOutputFile("VPC", "Virtual point cloud of the normalized tiles"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback, names=[n for n in self._spec if n not in BREAKLINES])
        classify = values["classify_vegetation"]
        layers = self.spec_values(parameters, context, feedback, names=BREAKLINES) if classify else {}
        run = {k: values.pop(k) for k in ("jobs", "scheduler", "reproject_vectors")}
        settings = _normalize.NormalizeSettings(**{k: v for k, v in values.items() if v is not None})
        result = _normalize.normalize_from_tiles(self.tiles(parameters, context), out, settings, **layers, overwrite=True,
                                                 progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        feedback.pushInfo(f"virtual point cloud: {result['vpc']}")
        if result["vpc"]:
            self.load_on_completion(context, result["vpc"], "Heights above ground", "VPC", feedback)
        return {"OUTPUT_FOLDER": out, "VPC": result["vpc"]}


class MetricsAlgorithm(GistoolsAlgorithm):
    _name, _display = "metrics", "Cell metrics of the points"
    _page = "commands/metrics"
    _tags = ("metrics", "canopy", "forest", "cover", "fuel", "density", "percentile")
    _help = ("Per-cell statistics of the points (gistools metrics; lasR rasterize / lidR pixel_metrics): one GeoTIFF "
             "per metric per tile on the snapped lattice of the rasters, and a VRT per metric (loaded). Cells without "
             "points are nodata. Neighbouring tiles' points are read, so tiles equal one merged run. " + METRICS_HELP)

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="metrics", defaults=COMMAND_DEFAULTS["metrics"],
                      labels={"classes": "ASPRS classes whose points count (comma-separated; empty: all but noise 7, 18)"},
                      orders={"returns": ("all", "first", "last")})  # the numbers saved models use
        flag_parameters(self, OPTIONAL, "METRICS")  # unchecked: only the names typed in MORE_METRICS
        flag_parameters(self, ADVANCED, "CLASSES", "RETURNS")
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (a folder and a VRT per metric)"))
        self.addOutput(QgsProcessingOutputFolder("METRICS_FOLDER", "Folder of the metric rasters"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        more = tuple(m.strip() for m in (values.pop("more_metrics") or "").split(",") if m.strip())
        values["metrics"] = tuple(dict.fromkeys(values["metrics"] + more))
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        settings = _metrics.MetricsSettings(**{k: v for k, v in values.items() if v is not None})
        result = _metrics.metrics_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                             progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        for name, vrt in result["mosaics"].items():
            self.load_on_completion(context, vrt, name, name)
        return {"OUTPUT_FOLDER": out, "METRICS_FOLDER": out}


class ChmAlgorithm(GistoolsAlgorithm):
    _name, _display = "chm", "Canopy height model (CHM)"
    _page = "commands/chm"
    _tags = ("chm", "canopy", "canopy height model", "trees", "forest", "pit-free")
    _help = ("Canopy height model of LAS/LAZ tiles (gistools chm; lidR rasterize_canopy): the first returns' heights "
             "above the TIN of the ground, gridded as the highest return per cell (p2r), a TIN of the returns, or "
             "pit-free (Khosravipour et al. 2014: TINs of the returns above a series of height thresholds, long "
             "triangles dropped, stacked by their maximum, so returns deep in a crown leave no pit). Neighbouring "
             "tiles' points are read, so tiles equal one merged run. Writes chm/<tile>.tif and chm.vrt (loaded); "
             "the log gives the pits left (cells more than 1 m below all 8 neighbours).")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="chm", defaults=COMMAND_DEFAULTS["chm"])
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (chm/ and chm.vrt)"))
        self.addOutput(QgsProcessingOutputRasterLayer("CHM", "Canopy height model"))
        self.addOutput(QgsProcessingOutputNumber("PITS", "Pits left (cells more than 1 m below all 8 neighbours)"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        values["thresholds"], values["max_edge"] = _lengths(values["thresholds"]), _lengths(values["max_edge"])
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        values["method"] = values.pop("chm_method")
        settings = _chm.ChmSettings(**{k: v for k, v in values.items() if v is not None})
        with method_labelled(self, "chm_method"):
            result = _chm.chm_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                         progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        feedback.pushInfo(f"{result['pits']:,} pits left")
        self.load_on_completion(context, result["mosaic"], "Canopy height model", "CHM")
        return {"OUTPUT_FOLDER": out, "CHM": result["mosaic"], "PITS": result["pits"]}


class FuelsAlgorithm(GistoolsAlgorithm):
    _name, _display = "fuels", "Canopy fuels, FlamMap landscape"
    _page = "commands/fuels"
    _tags = ("fuels", "fire", "canopy", "cbh", "cbd", "canopy base height", "canopy bulk density", "landfire", "flammap",
             "lcp", "landscape")
    _help = ("Canopy fuels of LAS/LAZ tiles (gistools fuels) on LANDFIRE's 30 m lattice (100 ft on data in feet): "
             "ground elevation, canopy cover (share of first returns above 2 m, percent), canopy height, canopy base "
             "height and canopy bulk density from the leaf area density profile of the returns (1 m layers, columns "
             "of 20 pulses, bias-corrected ratio estimator, bulk density = leaf area density x leaf mass per area, "
             "3 m running mean; base height where it first exceeds 0.012 kg/m3, as FVS and LANDFIRE), and the "
             "surface strata shares of the height bands. "
             "Writes a VRT per layer, landscape.tif (eight int16 bands in LANDFIRE's order and encodings) and "
             "landscape.lcp (FlamMap's landscape file, loaded). Neighbouring tiles' points are read, so tiles equal "
             "one merged run.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="fuels", defaults=COMMAND_DEFAULTS["fuels"])
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (a VRT per layer, landscape.tif "
                                                                          "and landscape.lcp)"))
        self.addOutput(QgsProcessingOutputRasterLayer("LANDSCAPE", "Landscape (8 bands, LANDFIRE encodings)"))
        self.addOutput(QgsProcessingOutputFile("LCP", "FlamMap landscape file (.lcp)"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        settings = _fuels.FuelsSettings(**{k: v for k, v in values.items() if v is not None})
        result = _fuels.fuels_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                         progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        land = result.get("landscape") or {}
        if land.get("tif"):
            self.load_on_completion(context, land["tif"], "Fuels landscape", "LANDSCAPE")
        return {"OUTPUT_FOLDER": out, "LANDSCAPE": land.get("tif"), "LCP": land.get("lcp")}
