"""Heights above ground and what is made of them: gistools normalize, gistools metrics, gistools chm and gistools
fuels."""

from __future__ import annotations


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

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="normalize", defaults=COMMAND_DEFAULTS["normalize"])
        self.add_outputs(
            "Output folder (tiles + normalized.vpc)", VPC=("file", "Virtual point cloud of the normalized tiles"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback, names=[n for n in self._spec if n not in BREAKLINES])
        classify = values["classify_vegetation"]
        layers = self.spec_values(parameters, context, feedback, names=BREAKLINES) if classify else {}
        run = {k: values.pop(k) for k in ("jobs", "scheduler", "reproject_vectors")}
        settings = _normalize.NormalizeSettings(**{k: v for k, v in values.items() if v is not None})
        result = _normalize.normalize_from_tiles(self.tiles(parameters, context, feedback), out, settings, **layers, overwrite=True,
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
        self.add_outputs(
            "Output folder (a folder and a VRT per metric)", METRICS_FOLDER=("folder", "Folder of the metric rasters"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        more = tuple(m.strip() for m in (values.pop("more_metrics") or "").split(",") if m.strip())
        values["metrics"] = tuple(dict.fromkeys(values["metrics"] + more))
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        settings = _metrics.MetricsSettings(**{k: v for k, v in values.items() if v is not None})
        result = _metrics.metrics_from_tiles(self.tiles(parameters, context, feedback), out, settings, overwrite=True,
                                             progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        for name, vrt in result["mosaics"].items():
            self.load_on_completion(context, vrt, name, name)
        return {"OUTPUT_FOLDER": out, "METRICS_FOLDER": out}


class ChmAlgorithm(GistoolsAlgorithm):
    _name, _display = "chm", "Canopy height model (CHM)"
    _page = "commands/chm"
    _tags = ("chm", "canopy", "canopy height model", "trees", "forest", "pit-free")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="chm", defaults=COMMAND_DEFAULTS["chm"])
        self.add_outputs(
            "Output folder (chm/ and chm.vrt)", CHM=("raster", "Canopy height model"),
            PITS=("number", "Pits left (cells more than 1 m below all 8 neighbours)"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        values["thresholds"], values["max_edge"] = _lengths(values["thresholds"]), _lengths(values["max_edge"])
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        values["method"] = values.pop("chm_method")
        settings = _chm.ChmSettings(**{k: v for k, v in values.items() if v is not None})
        with method_labelled(self, "chm_method"):
            result = _chm.chm_from_tiles(self.tiles(parameters, context, feedback), out, settings, overwrite=True,
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

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(command="fuels", defaults=COMMAND_DEFAULTS["fuels"])
        self.add_outputs(
            "Output folder (a VRT per layer, landscape.tif and landscape.lcp)",
            LANDSCAPE=("raster", "Landscape (8 bands, LANDFIRE encodings)"), LCP=("file", "FlamMap landscape file (.lcp)"))

    def run_gistools(self, parameters, context, feedback):
        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        settings = _fuels.FuelsSettings(**{k: v for k, v in values.items() if v is not None})
        result = _fuels.fuels_from_tiles(self.tiles(parameters, context, feedback), out, settings, overwrite=True,
                                         progress=self.progress(feedback), **run)
        self.report_tiles(result, feedback)
        land = result.get("landscape") or {}
        if land.get("tif"):
            self.load_on_completion(context, land["tif"], "Fuels landscape", "LANDSCAPE")
        return {"OUTPUT_FOLDER": out, "LANDSCAPE": land.get("tif"), "LCP": land.get("lcp")}
