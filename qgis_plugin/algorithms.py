"""The gistools Processing algorithms: parameter declarations, one gistools call, the output dict.

Lengths are text with a unit ("5ft", "0.1m"; a bare number is in the data's CRS units), as
in the CLI: QGIS distance widgets hold a number in the layer's units, and the dissertation's
defaults (25 ft, 0.2 ft, ...) must not turn into 25 m on metre data.
"""

from __future__ import annotations

from pathlib import Path

from qgis.core import (
    QgsProcessing,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingOutputFile,
    QgsProcessingOutputFolder,
    QgsProcessingOutputNumber,
    QgsProcessingOutputRasterLayer,
    QgsProcessingOutputString,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterEnum,
    QgsProcessingParameterField,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorDestination,
    QgsProcessingParameterVectorLayer,
)
from qgis.PyQt.QtGui import QIcon

from gistools.lidar import bands as _bands
from gistools.lidar import gridding as _gridding
from gistools.lidar import shrub as _shrub
from gistools.tasks import points as _points

HERE = Path(__file__).resolve().parent

GROUP_LIDAR = ("LiDAR", "lidar")
GROUP_SHRUB = ("Shrub chain", "shrub")

# choices are the library's own (the provider loads only once gistools imports)
DEM_METHODS = list(_gridding.DEM_METHODS)
RETURNS = list(_points.RETURNS)
PRESETS = list(_bands.PRESETS)
CLASSIFY = list(_shrub.CLASS_METHODS)
Z_UNITS = ["from the raster", "m", "ft", "ftUS"]
BANDS = ["B1 (0-1 m)", "B2 (1-2 m)", "B3 (2-6 m)"]


def _ints(text: str, name: str):
    text = (text or "").strip()
    if not text:
        return None
    try:
        return tuple(int(v) for v in text.split(","))
    except ValueError:
        raise QgsProcessingException(f"{name}: {text!r} is not a comma-separated list of integers, e.g. 1,2") from None


def _floats(text: str, name: str, count: int):
    text = (text or "").strip()
    if not text:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count:
        raise QgsProcessingException(f"{name}: {text!r} must be {count} comma-separated numbers")
    return values


class GistoolsAlgorithm(QgsProcessingAlgorithm):
    """Shared plumbing: progress and cancel through the feedback object, gistools errors as QgsProcessingException."""

    _name = ""
    _display = ""
    _group = GROUP_LIDAR
    _help = ""

    def name(self):
        return self._name

    def displayName(self):  # noqa: N802
        return self._display

    def group(self):
        return self._group[0]

    def groupId(self):  # noqa: N802
        return self._group[1]

    def shortHelpString(self):  # noqa: N802
        return self._help

    def icon(self):
        return QIcon(str(HERE / "icon.svg"))

    def createInstance(self):  # noqa: N802
        return type(self)()

    # --- parameter helpers
    def add(self, param, advanced: bool = False):
        if advanced:
            param.setFlags(param.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(param)
        return param

    def add_tiles(self):
        self.add(QgsProcessingParameterFile("INPUT", "LAS/LAZ tiles (a folder, or one file)",
                                            behavior=QgsProcessingParameterFile.Folder, optional=True))
        self.add(QgsProcessingParameterMultipleLayers("POINT_CLOUDS", "Or point cloud layers (LAS/LAZ files)",
                                                      layerType=QgsProcessing.TypePointCloud, optional=True))

    def tiles(self, parameters, context):
        """The tile folder and / or the files of the chosen point cloud layers, as gistools inputs."""
        inputs = []
        folder = self.text(parameters, "INPUT", context)
        if folder:
            inputs.append(folder)
        if parameters.get("POINT_CLOUDS"):
            for layer in self.parameterAsLayerList(parameters, "POINT_CLOUDS", context):
                inputs.append(layer.source().split("|")[0])
        if not inputs:
            raise QgsProcessingException("no tiles: give a folder of LAS/LAZ tiles (INPUT) or point cloud layers "
                                         "(POINT_CLOUDS)")
        return inputs

    def add_crs(self):
        self.add(QgsProcessingParameterCrs("CRS", "Input CRS (overrides the tiles' own; needed for tiles that carry none)",
                                           optional=True), advanced=True)

    def add_parallel(self):
        self.add(QgsProcessingParameterNumber("JOBS", "Tiles in parallel (local processes)", defaultValue=1, minValue=1),
                 advanced=True)
        self.add(QgsProcessingParameterString("SCHEDULER", "Dask scheduler address (tcp://host:8786), or 'local'",
                                              optional=True), advanced=True)

    def add_length(self, name, description, default, optional=False, advanced=False):
        self.add(QgsProcessingParameterString(name, f"{description} (with unit: m, ft, ftUS)", defaultValue=default,
                                              optional=optional), advanced=advanced)

    # --- parameter readers
    def text(self, parameters, name, context):
        value = self.parameterAsString(parameters, name, context)
        return value.strip() if value else None

    def crs_text(self, parameters, context):
        if not parameters.get("CRS"):
            return None
        crs = self.parameterAsCrs(parameters, "CRS", context)
        if not crs.isValid():
            return None
        return crs.authid() or crs.toWkt()

    def layer_spec(self, parameters, name, context, feedback):
        """A vector input as gistools reads it (``file.gpkg:LAYER``); memory or filtered layers are exported first."""
        if parameters.get(name) in (None, ""):
            return None
        path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, name, context, ["gpkg", "shp"], "gpkg", feedback)
        if not path:
            return None
        return f"{path}:{layer}" if layer and path.lower().endswith(".gpkg") else path

    def output_path(self, parameters, name, context, optional=False):
        """A destination's file; None for an optional one left out; a temporary file when a model leaves it empty."""
        if optional and parameters.get(name) in (None, ""):
            return None
        path = self.parameterAsOutputLayer(parameters, name, context)
        if not path:
            path = self.parameterDefinition(name).generateTemporaryDestination()
        return path

    def output_folder(self, parameters, context, name="OUTPUT_FOLDER"):
        path = self.parameterAsString(parameters, name, context)
        if not path or path == "TEMPORARY_OUTPUT":
            path = self.parameterDefinition(name).generateTemporaryDestination()
        return path

    def layer_crs(self, parameters, name, context):
        """The CRS of a vector layer parameter as gistools takes it (authority id, else WKT), None if it has none."""
        layer = self.parameterAsVectorLayer(parameters, name, context)
        if layer is None or not layer.crs().isValid():
            return None
        return layer.crs().authid() or layer.crs().toWkt()

    def raster_path(self, parameters, name, context):
        if parameters.get(name) in (None, ""):
            return None
        layer = self.parameterAsRasterLayer(parameters, name, context)
        if layer is None:
            raise QgsProcessingException(f"{name}: not a raster layer or file: {parameters.get(name)!r}")
        return layer.source()

    # --- run
    def progress(self, feedback):
        state = {"text": None}

        def callback(fraction, message=""):
            feedback.setProgress(100.0 * fraction)
            if message and message != state["text"]:
                state["text"] = message
                feedback.setProgressText(message)
            return not feedback.isCanceled()

        return callback

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        from gistools.errors import Cancelled, GistoolsError

        try:
            return self.run_gistools(parameters, context, feedback)
        except Cancelled:
            feedback.reportError("gistools: cancelled; no partial output was written")
            raise QgsProcessingException("cancelled by the user; no partial output was written") from None
        except GistoolsError as err:
            raise QgsProcessingException(str(err)) from None

    def run_gistools(self, parameters, context, feedback):  # pragma: no cover - every algorithm overrides it
        raise NotImplementedError(f"{type(self).__name__} declares no gistools call")

    def report_tiles(self, result, feedback, what="tiles"):
        """Failed tiles are reported (the batch goes on); a run where every tile failed is an error."""
        tiles = result.get("tiles", [])
        failed = [t for t in tiles if t.get("status") == "failed"]
        for t in failed:
            feedback.reportError(f"FAILED {t.get('error')}")
        for t in tiles:
            for w in t.get("warnings") or []:
                feedback.pushWarning(f"WARNING {w}") if hasattr(feedback, "pushWarning") else feedback.reportError(f"WARNING {w}")
        feedback.pushInfo(f"{len(tiles) - len(failed)} {what} ok, {len(failed)} failed")
        if tiles and len(failed) == len(tiles):
            raise QgsProcessingException(failed[0].get("error") or "every tile failed")
        return len(failed)

    def load_on_completion(self, context, path, name, output):
        if path and Path(path).exists():
            context.addLayerToLoadOnCompletion(str(path), QgsProcessingContext.LayerDetails(name, context.project(), output))


# ------------------------------------------------------------------ tiles in

class InfoAlgorithm(GistoolsAlgorithm):
    _name, _display = "info", "Tile info"
    _help = ("Header, CRS, horizontal and vertical units and point counts by class and return of LAS/LAZ tiles "
             "(gistools info). A tile that cannot be read is reported, the others are still listed.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_crs()
        self.add(QgsProcessingParameterFileDestination("OUTPUT", "Summary (JSON)", "JSON files (*.json)", optional=True,
                                                       createByDefault=False))
        self.addOutput(QgsProcessingOutputNumber("POINTS", "Points"))
        self.addOutput(QgsProcessingOutputNumber("TILES", "Tiles read"))
        self.addOutput(QgsProcessingOutputString("CRS_NAME", "CRS"))

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.io.raster import atomic_path
        from gistools.tasks.info import tiles_summary

        result = tiles_summary(self.tiles(parameters, context), crs=self.crs_text(parameters, context),
                               progress=self.progress(feedback))
        for t in result["tiles"]:
            if t["status"] == "ok":
                feedback.pushInfo(f"{t['file']}: LAS {t['las_version']} PF {t['point_format']}, {t['points']:,} points, "
                                  f"{t['crs']}, x/y {t['horizontal_unit']}, z {t['vertical_unit']}, "
                                  f"classes {t['points_by_class']}")
        self.report_tiles(result, feedback)
        out = {"POINTS": result["points"], "TILES": result["counts"]["ok"], "CRS_NAME": "; ".join(result["crs"])}
        path = self.parameterAsFileOutput(parameters, "OUTPUT", context) if parameters.get("OUTPUT") else None
        if path:
            with atomic_path(path, overwrite=True) as tmp:
                tmp.write_text(json.dumps(result, indent=2, default=str))
            out["OUTPUT"] = path
        return out


class PointsAlgorithm(GistoolsAlgorithm):
    _name, _display = "points", "LAS to points (ground / non-ground)"
    _help = ("The dissertation's LAS To Multipoint: per tile, a point layer (GeoPackage, or GeoParquet) with x, y, z, "
             "class, return number and intensity of the chosen classes and returns, streamed in chunks. "
             "Non-ground: classes 1,2 first returns; ground: class 2, any return.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add(QgsProcessingParameterString("CLASSES", "ASPRS classes (comma-separated; empty = all)", defaultValue="1,2",
                                              optional=True))
        self.add(QgsProcessingParameterEnum("RETURNS", "Returns", options=RETURNS, defaultValue=2))
        self.add(QgsProcessingParameterEnum("FORMAT", "Format", options=["gpkg", "parquet"], defaultValue=0), advanced=True)
        self.add_crs()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Point layers folder"))
        self.addOutput(QgsProcessingOutputNumber("POINTS", "Points written"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.points import points_from_tiles

        out = self.output_folder(parameters, context)
        result = points_from_tiles(self.tiles(parameters, context), out,
                                   classes=_ints(self.parameterAsString(parameters, "CLASSES", context), "Classes"),
                                   returns=RETURNS[self.parameterAsEnum(parameters, "RETURNS", context)],
                                   fmt=["gpkg", "parquet"][self.parameterAsEnum(parameters, "FORMAT", context)],
                                   crs=self.crs_text(parameters, context), overwrite=True, progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        return {"OUTPUT_FOLDER": out, "POINTS": sum(t["points"] for t in result["tiles"])}


class _RastersBase(GistoolsAlgorithm):
    """Tile folder -> per-tile GeoTIFFs + VRT mosaics (gistools rasters)."""

    products: tuple = ()
    outputs = {}  # product -> (output name, description)

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_length("CELL_SIZE", "Cell size", "5ft")
        if "dsm" in self.products:
            self.add(QgsProcessingParameterString("DSM_CLASSES", "Classes in the DSM (empty = all but noise 7, 18)",
                                                  optional=True), advanced=True)
        if "dem" in self.products:
            self.add(QgsProcessingParameterEnum("DEM_METHOD", "DEM method", options=DEM_METHODS, defaultValue=0))
            self.add_length("DEM_MAX_DISTANCE", "DEM: leave cells farther than this from ground points empty", "15m",
                            advanced=True)
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (one GeoTIFF per tile + VRT)"))
        for product in self.products:
            name, description = self.outputs[product]
            self.addOutput(QgsProcessingOutputRasterLayer(name, description))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.rasters import RasterSettings, rasters_from_tiles

        out = self.output_folder(parameters, context)
        kwargs = {"cell_size": self.text(parameters, "CELL_SIZE", context), "crs": self.crs_text(parameters, context),
                  "products": self.products}
        if "dsm" in self.products:
            kwargs["dsm_classes"] = _ints(self.parameterAsString(parameters, "DSM_CLASSES", context), "DSM classes")
        if "dem" in self.products:
            kwargs["dem_method"] = DEM_METHODS[self.parameterAsEnum(parameters, "DEM_METHOD", context)]
            kwargs["dem_max_distance"] = self.text(parameters, "DEM_MAX_DISTANCE", context)
        settings = RasterSettings(**kwargs)
        result = rasters_from_tiles(self.tiles(parameters, context), out, settings, overwrite=True,
                                    jobs=self.parameterAsInt(parameters, "JOBS", context),
                                    scheduler=self.text(parameters, "SCHEDULER", context),
                                    progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        outputs = {"OUTPUT_FOLDER": out}
        for product in self.products:
            name, description = self.outputs[product]
            path = result.get("mosaics", {}).get(product)
            outputs[name] = str(path) if path else None
            self.load_on_completion(context, path, description, name)
        return outputs


class DsmAlgorithm(_RastersBase):
    _name, _display = "dsm", "DSM (max of first returns)"
    _help = ("Digital surface model: the highest first return in each cell, on a lattice snapped to multiples of the "
             "cell size so tiles mosaic without seams. Also the class of that return (TOP_CLASS), which the height "
             "bands use to keep bare ground out of the low shrub band.")
    products = ("dsm", "topclass")
    outputs = {"dsm": ("OUTPUT", "DSM"), "topclass": ("TOP_CLASS", "Class of the highest first return")}


class DemAlgorithm(_RastersBase):
    _name, _display = "dem", "DEM (ground TIN)"
    _help = ("Digital elevation model from ground points (class 2): a Delaunay TIN evaluated at cell centres, reading "
             "ground points of neighbouring tiles so tile edges do not show; water (class 9) cells stay empty.")
    products = ("dem",)
    outputs = {"dem": ("OUTPUT", "DEM")}


class RastersAlgorithm(_RastersBase):
    _name, _display = "rasters", "DSM, DEM and nDSM of a tile folder"
    _help = "DSM, DEM and nDSM (= DSM - DEM) of every tile, each tile decoded once (gistools rasters)."
    products = ("dsm", "dem", "ndsm", "topclass")
    outputs = {"dsm": ("DSM", "DSM"), "dem": ("DEM", "DEM"), "ndsm": ("NDSM", "nDSM"),
               "topclass": ("TOP_CLASS", "Class of the highest first return")}


# ------------------------------------------------------------------ raster steps

class NdsmAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "ndsm", "nDSM (DSM - DEM)", GROUP_LIDAR
    _help = "Normalised DSM: heights above ground = DSM - DEM, cell by cell, on the DSM's grid (the DEM must share it)."

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("DSM", "DSM"))
        self.add(QgsProcessingParameterRasterLayer("DEM", "DEM"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "nDSM"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import ndsm_from_rasters

        out = self.output_path(parameters, "OUTPUT", context)
        ndsm_from_rasters(self.raster_path(parameters, "DSM", context), self.raster_path(parameters, "DEM", context), out,
                          progress=self.progress(feedback))
        return {"OUTPUT": out}


class BandsAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "bands", "Height bands", GROUP_SHRUB
    _help = ("Height bands of an nDSM: 0 = B0 ground (h <= noise floor, or topped by a ground / water return), "
             "1 = B1 0-1 m, 2 = B2 1-2 m, 3 = B3 2-6 m, 4 = above, 255 = nodata. Thresholds are in metres and converted "
             "to the nDSM's vertical unit (6 m = 19.685 ftUS); 'text_literal' uses the dissertation's printed feet.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("NDSM", "nDSM"))
        self.add(QgsProcessingParameterRasterLayer("TOP_CLASS", "Class of the highest first return (from the DSM step)",
                                                   optional=True))
        self.add(QgsProcessingParameterEnum("PRESET", "Band limits", options=PRESETS, defaultValue=0))
        self.add(QgsProcessingParameterString("BREAKS", "Or three band limits in metres (e.g. 1,2,6)", optional=True),
                 advanced=True)
        self.add_length("NOISE_FLOOR", "Heights up to this are bare ground", "0.1m")
        self.add(QgsProcessingParameterEnum("Z_UNIT", "Vertical unit of the nDSM", options=Z_UNITS, defaultValue=0),
                 advanced=True)
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Height bands"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POINTS", "Cell-centre points per band (Raster To Point)",
                                                         type=QgsProcessing.TypeVectorPoint, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import bands_from_ndsm

        out = self.output_path(parameters, "OUTPUT", context)
        points = self.output_path(parameters, "OUTPUT_POINTS", context, optional=True)
        z = self.parameterAsEnum(parameters, "Z_UNIT", context)
        result = bands_from_ndsm(self.raster_path(parameters, "NDSM", context), out,
                                 top_class=self.raster_path(parameters, "TOP_CLASS", context),
                                 preset=PRESETS[self.parameterAsEnum(parameters, "PRESET", context)],
                                 breaks_m=_floats(self.parameterAsString(parameters, "BREAKS", context), "Band limits", 3),
                                 noise_floor=self.text(parameters, "NOISE_FLOOR", context),
                                 z_unit=None if z == 0 else Z_UNITS[z], points_out=points, progress=self.progress(feedback))
        feedback.pushInfo(f"band limits T1, T2, T3 = {', '.join(f'{t:.4f}' for t in result['thresholds'])} "
                          f"{result['z_unit']}")
        return {"OUTPUT": out, **({"OUTPUT_POINTS": points} if points else {})}


class BreaklinesAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "breaklines", "Breaklines to road and water polygons", GROUP_SHRUB
    _help = ("The dissertation's Split (by the tile index) and Feature To Polygon: edge-of-pavement lines and "
             "hydrographic breaklines are split by each tile footprint, noded with a snapping tolerance and "
             "polygonised; faces wider than the maximum width are blocks between roads, not road. Water bodies "
             "(islands stay holes) and buffered single-line hydro features join the water polygons.")

    def initAlgorithm(self, config=None):  # noqa: N802
        line = [QgsProcessing.TypeVectorLine]
        poly = [QgsProcessing.TypeVectorPolygon]
        self.add(QgsProcessingParameterVectorLayer("ROADS", "Road breaklines (edge of pavement)", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("TILE_INDEX", "Tile index (footprints)", poly, optional=True))
        self.add(QgsProcessingParameterField("TILE_FIELD", "Tile number field", defaultValue="TILE_ID",
                                             parentLayerParameterName="TILE_INDEX", optional=True))
        self.add_length("SNAP", "Snapping tolerance", "0.2ft")
        self.add_length("MAX_ROAD_WIDTH", "Widest road face", "60ft")
        self.add_length("MAX_HYDRO_WIDTH", "Widest river face", "500ft", advanced=True)
        self.add_length("SINGLE_LINE_WIDTH", "Width given to single-line hydro features", "8ft", advanced=True)
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_ROADS", "Road polygons", type=QgsProcessing.TypeVectorPolygon))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_WATER", "Water polygons", type=QgsProcessing.TypeVectorPolygon))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import breakline_polygons

        roads_out = self.output_path(parameters, "OUTPUT_ROADS", context)
        water_out = self.output_path(parameters, "OUTPUT_WATER", context)
        result = breakline_polygons(
            roads=self.layer_spec(parameters, "ROADS", context, feedback),
            hydro=self.layer_spec(parameters, "HYDRO", context, feedback),
            waterbodies=self.layer_spec(parameters, "WATERBODIES", context, feedback),
            tile_index=self.layer_spec(parameters, "TILE_INDEX", context, feedback),
            tile_field=self.parameterAsString(parameters, "TILE_FIELD", context) or "TILE_ID",
            road_out=roads_out, water_out=water_out,
            reproject=self.parameterAsBool(parameters, "REPROJECT", context),
            snap=self.text(parameters, "SNAP", context), max_road_width=self.text(parameters, "MAX_ROAD_WIDTH", context),
            max_hydro_width=self.text(parameters, "MAX_HYDRO_WIDTH", context),
            single_line_width=self.text(parameters, "SINGLE_LINE_WIDTH", context), progress=self.progress(feedback))
        feedback.pushInfo(f"{result.get('road_count', 0)} road and {result.get('water_count', 0)} water polygons")
        return {"OUTPUT_ROADS": roads_out, "OUTPUT_WATER": water_out}


class ClipAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "clip", "Clip roads and water, select wetland vegetation", GROUP_SHRUB
    _help = ("Vegetation = height band minus road minus water, by cell centre (the dissertation's Clip and Select By "
             "Location on Raster To Point output). Codes: 0 none, 1-3 band of a vegetation cell, 4 road, 5 water, "
             "255 nodata. Vegetation inside wetland polygons is a second output.")

    def initAlgorithm(self, config=None):  # noqa: N802
        poly = [QgsProcessing.TypeVectorPolygon]
        self.add(QgsProcessingParameterRasterLayer("BANDS", "Height bands"))
        self.add(QgsProcessingParameterVectorLayer("ROAD_POLYGONS", "Road polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATER_POLYGONS", "Water polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WETLANDS", "Wetland polygons", poly, optional=True))
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Vegetation"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT_WETLAND", "Vegetation in wetlands", optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import clip_bands

        out = self.output_path(parameters, "OUTPUT", context)
        wet = self.output_path(parameters, "OUTPUT_WETLAND", context, optional=True)
        clip_bands(self.raster_path(parameters, "BANDS", context), out,
                   road_polygons=self.layer_spec(parameters, "ROAD_POLYGONS", context, feedback),
                   water_polygons=self.layer_spec(parameters, "WATER_POLYGONS", context, feedback),
                   wetlands=self.layer_spec(parameters, "WETLANDS", context, feedback), wetland_out=wet,
                   reproject=self.parameterAsBool(parameters, "REPROJECT", context), progress=self.progress(feedback))
        return {"OUTPUT": out, **({"OUTPUT_WETLAND": wet} if wet else {})}


class DensityAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "density", "Vegetation density and cover", GROUP_SHRUB
    _help = ("Point density of vegetation cells (each stands for one Raster To Point point) over a circle: cover = "
             "share of the cell centres within the radius that are vegetation (0-1); density = points per CRS area "
             "unit. Blocks read a halo of the radius, so block and tile edges do not show.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (from the clip step)"))
        self.add_length("RADIUS", "Neighbourhood radius", "25ft")
        self.add(QgsProcessingParameterEnum("DENSITY_BANDS", "Bands whose vegetation counts", options=BANDS,
                                            allowMultiple=True, defaultValue=[0, 1, 2]))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Cover (0-1)"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT_DENSITY", "Point density", optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import density_from_vegetation

        out = self.output_path(parameters, "OUTPUT", context)
        dens = self.output_path(parameters, "OUTPUT_DENSITY", context, optional=True)
        bands = tuple(i + 1 for i in self.parameterAsEnums(parameters, "DENSITY_BANDS", context)) or (1, 2, 3)
        result = density_from_vegetation(self.raster_path(parameters, "VEGETATION", context), out, density_out=dens,
                                         radius=self.text(parameters, "RADIUS", context), density_bands=bands,
                                         progress=self.progress(feedback))
        feedback.pushInfo(f"radius {result['radius']:.4f} CRS units, bands {bands}")
        return {"OUTPUT": out, **({"OUTPUT_DENSITY": dens} if dens else {})}


class ClassifyAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "classify", "Shrub density classes", GROUP_SHRUB
    _help = ("Light / medium / heavy shrub classes from cover: 0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water, "
             "255 nodata. 'breaks' uses the given cover breaks (default 0.3, 0.7), 'quantile' and 'jenks' compute them.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("COVER", "Cover (from the density step)"))
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (marks road and water)", optional=True))
        self.add(QgsProcessingParameterEnum("METHOD", "Class breaks", options=CLASSIFY, defaultValue=0))
        self.add(QgsProcessingParameterString("BREAKS", "Cover breaks light/medium, medium/heavy", defaultValue="0.3,0.7"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Shrub classes"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POLYGONS", "Shrub class polygons",
                                                         type=QgsProcessing.TypeVectorPolygon, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import classes_from_cover

        out = self.output_path(parameters, "OUTPUT", context)
        polys = self.output_path(parameters, "OUTPUT_POLYGONS", context, optional=True)
        result = classes_from_cover(self.raster_path(parameters, "COVER", context), out,
                                    veg=self.raster_path(parameters, "VEGETATION", context), polygons_out=polys,
                                    method=CLASSIFY[self.parameterAsEnum(parameters, "METHOD", context)],
                                    breaks=_floats(self.parameterAsString(parameters, "BREAKS", context), "Breaks", 2)
                                    or (0.3, 0.7), progress=self.progress(feedback))
        feedback.pushInfo(f"breaks {result['breaks']}; class area (CRS units squared): "
                          + ", ".join(f"{k} {v:,.0f}" for k, v in result["class_area"].items()))
        return {"OUTPUT": out, **({"OUTPUT_POLYGONS": polys} if polys else {})}


# ------------------------------------------------------------------ the whole chain

class ShrubChainAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "shrubchain", "Shrub density map (whole chain)", GROUP_SHRUB
    _help = ("The whole shrub chain on a tile folder (gistools shrub): DSM / DEM / nDSM, height bands, road and water "
             "clipping, vegetation density, light / medium / heavy classes, class polygons, a printable map and "
             "report.json, tile by tile (resumable, one bad tile is reported and the others go on).")

    def initAlgorithm(self, config=None):  # noqa: N802
        line = [QgsProcessing.TypeVectorLine]
        poly = [QgsProcessing.TypeVectorPolygon]
        self.add_tiles()
        self.add(QgsProcessingParameterVectorLayer("ROADS", "Road breaklines (edge of pavement)", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WETLANDS", "Wetland polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("TILE_INDEX", "Tile index (footprints)", poly, optional=True))
        self.add(QgsProcessingParameterField("TILE_FIELD", "Tile number field", defaultValue="TILE_ID",
                                             parentLayerParameterName="TILE_INDEX", optional=True))
        self.add_length("CELL_SIZE", "Cell size", "5ft")
        self.add(QgsProcessingParameterEnum("DEM_METHOD", "DEM method", options=DEM_METHODS, defaultValue=0), advanced=True)
        self.add(QgsProcessingParameterEnum("PRESET", "Band limits", options=PRESETS, defaultValue=0))
        self.add_length("NOISE_FLOOR", "Heights up to this are bare ground", "0.1m", advanced=True)
        self.add_length("RADIUS", "Density radius", "25ft")
        self.add(QgsProcessingParameterEnum("DENSITY_BANDS", "Bands whose vegetation counts", options=BANDS,
                                            allowMultiple=True, defaultValue=[0, 1, 2]))
        self.add(QgsProcessingParameterEnum("METHOD", "Class breaks", options=CLASSIFY, defaultValue=0))
        self.add(QgsProcessingParameterString("BREAKS", "Cover breaks light/medium, medium/heavy", defaultValue="0.3,0.7"))
        self.add_length("MAX_ROAD_WIDTH", "Widest road face", "60ft", advanced=True)
        self.add_length("SNAP", "Breakline snapping tolerance", "0.2ft", advanced=True)
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add(QgsProcessingParameterBoolean("MAP", "Draw the printable map (PNG and PDF)", defaultValue=True))
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("CLASSES", "Shrub classes"))
        self.addOutput(QgsProcessingOutputRasterLayer("COVER", "Vegetation cover"))
        self.addOutput(QgsProcessingOutputVectorLayer("POLYGONS", "Shrub class polygons", QgsProcessing.TypeVectorPolygon))
        self.addOutput(QgsProcessingOutputFile("MAP_PNG", "Shrub map (PNG)"))
        self.addOutput(QgsProcessingOutputFolder("FOLDER", "Output folder"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.rasters import RasterSettings
        from gistools.tasks.shrub import ShrubSettings, shrub_from_tiles

        out = Path(self.output_folder(parameters, context))
        bands = tuple(i + 1 for i in self.parameterAsEnums(parameters, "DENSITY_BANDS", context)) or (1, 2, 3)
        settings = ShrubSettings(
            raster=RasterSettings(cell_size=self.text(parameters, "CELL_SIZE", context),
                                  dem_method=DEM_METHODS[self.parameterAsEnum(parameters, "DEM_METHOD", context)],
                                  crs=self.crs_text(parameters, context)),
            bands=PRESETS[self.parameterAsEnum(parameters, "PRESET", context)],
            noise_floor=self.text(parameters, "NOISE_FLOOR", context), radius=self.text(parameters, "RADIUS", context),
            density_bands=bands, classify=CLASSIFY[self.parameterAsEnum(parameters, "METHOD", context)],
            class_breaks=_floats(self.parameterAsString(parameters, "BREAKS", context), "Breaks", 2) or (0.3, 0.7),
            max_road_width=self.text(parameters, "MAX_ROAD_WIDTH", context), snap=self.text(parameters, "SNAP", context),
            tile_field=self.parameterAsString(parameters, "TILE_FIELD", context) or "TILE_ID")
        result = shrub_from_tiles(
            self.tiles(parameters, context), out, settings,
            roads=self.layer_spec(parameters, "ROADS", context, feedback),
            hydro=self.layer_spec(parameters, "HYDRO", context, feedback),
            waterbodies=self.layer_spec(parameters, "WATERBODIES", context, feedback),
            wetlands=self.layer_spec(parameters, "WETLANDS", context, feedback),
            tile_index=self.layer_spec(parameters, "TILE_INDEX", context, feedback),
            reproject_vectors=self.parameterAsBool(parameters, "REPROJECT", context),
            jobs=self.parameterAsInt(parameters, "JOBS", context), scheduler=self.text(parameters, "SCHEDULER", context),
            overwrite=True, make_map=self.parameterAsBool(parameters, "MAP", context), progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        if "class_area" in result:
            feedback.pushInfo(f"class area ({result['area_unit']}): "
                              + ", ".join(f"{k} {v:,.0f}" for k, v in result["class_area"].items()))
        mosaics = result.get("mosaics", {})
        outputs = {"OUTPUT_FOLDER": str(out), "FOLDER": str(out), "CLASSES": mosaics.get("classes"),
                   "COVER": mosaics.get("cover"), "POLYGONS": str(out / "shrub_classes.gpkg"),
                   "MAP_PNG": str(out / "shrub_map.png") if (out / "shrub_map.png").exists() else None}
        self.load_on_completion(context, outputs["CLASSES"], "Shrub classes", "CLASSES")
        self.load_on_completion(context, outputs["POLYGONS"], "Shrub class polygons", "POLYGONS")
        return outputs


# ------------------------------------------------------------------ aquifer

GROUP_AQUIFER = ("Aquifer", "aquifer")


class AquiferModelAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "aquifer", "Aquifer model from layer contacts", GROUP_AQUIFER
    _help = ("Borehole layer contacts (points with x, y, z and a layer field) to a 3D aquifer model (gistools aquifer "
             "model): outliers flagged with their rule, one TIN per layer, boundaries, matched walls, a closed mesh "
             "per unit, thickness rasters and exact volumes (report.json). Layers are named top to bottom.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Layer contacts (points: id, z, layer fields)",
                                                   [QgsProcessing.TypeVectorPoint]))
        self.add(QgsProcessingParameterString("LAYERS", "Layer names, top to bottom (comma-separated)",
                                              defaultValue="LS,AU,AD,AQ"))
        self.add(QgsProcessingParameterVectorLayer("WITHIN", "Volumes inside this polygon (default: common footprint)",
                                                   [QgsProcessing.TypeVectorPolygon], optional=True))
        self.add(QgsProcessingParameterVectorLayer("CLIP", "Cut the surfaces to this polygon", [QgsProcessing.TypeVectorPolygon],
                                                   optional=True), advanced=True)
        self.add(QgsProcessingParameterBoolean("SWAP_XY", "Swap x and y", defaultValue=False), advanced=True)
        self.add_length("XY_TOL", "Duplicates: same position within", "0.5m", advanced=True)
        self.add_length("ABS_THR", "Outliers: smallest residual threshold", "8m", advanced=True)
        self.add(QgsProcessingParameterEnum("MESH", "Mesh format", options=["ply", "obj"], defaultValue=0), advanced=True)
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputVectorLayer("GPKG", "Aquifer GeoPackage"))
        self.addOutput(QgsProcessingOutputFile("REPORT", "report.json"))
        self.addOutput(QgsProcessingOutputString("VOLUMES", "Volumes per unit (JSON)"))

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.tasks.aquifer import AquiferSettings, aquifer_model

        out = Path(self.output_folder(parameters, context))
        layers = [x.strip() for x in self.parameterAsString(parameters, "LAYERS", context).split(",") if x.strip()]
        settings = AquiferSettings(xy_tol=self.text(parameters, "XY_TOL", context),
                                   abs_thr=self.text(parameters, "ABS_THR", context),
                                   mesh_format=["ply", "obj"][self.parameterAsEnum(parameters, "MESH", context)])
        source = self.layer_spec(parameters, "INPUT", context, feedback)
        crs = self.layer_crs(parameters, "INPUT", context)
        rep = aquifer_model(source, layers, out, crs=crs, swap_xy=self.parameterAsBool(parameters, "SWAP_XY", context),
                            settings=settings, within=self.layer_spec(parameters, "WITHIN", context, feedback),
                            clip=self.layer_spec(parameters, "CLIP", context, feedback), overwrite=True,
                            progress=self.progress(feedback))
        for name, u in rep["units"].items():
            feedback.pushInfo(f"{name}: volume {u['volume']:,.0f} (+{u['volume_positive']:,.0f} / "
                              f"{u['volume_negative']:,.0f}) {rep['volume_unit']}; thickness {u['thickness_min']:.2f} / "
                              f"{u['thickness_mean']:.2f} / {u['thickness_max']:.2f}")
        for name, path in rep["outputs"]["thickness"].items():
            self.load_on_completion(context, path, f"Thickness {name}", "THICKNESS")
        volumes = {name: {k: u[k] for k in ("volume", "volume_positive", "volume_negative")} for name, u in rep["units"].items()}
        return {"OUTPUT_FOLDER": str(out), "GPKG": str(out / "aquifer.gpkg"), "REPORT": str(out / "report.json"),
                "VOLUMES": json.dumps(volumes)}


class AquiferQueryAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "aquiferquery", "Aquifer heights and thickness at a point", GROUP_AQUIFER
    _help = ("Height of every surface and thickness of every unit of a model (the output folder of 'Aquifer model') "
             "at a point: TIN (default, nothing outside the boundary), k-nearest mean or IDW.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterFile("MODEL", "Aquifer model folder", behavior=QgsProcessingParameterFile.Folder))
        self.add(QgsProcessingParameterNumber("X", "x (model CRS)", type=QgsProcessingParameterNumber.Double))
        self.add(QgsProcessingParameterNumber("Y", "y (model CRS)", type=QgsProcessingParameterNumber.Double))
        self.add(QgsProcessingParameterEnum("METHOD", "Method", options=["tin", "knn", "idw"], defaultValue=0))
        self.add(QgsProcessingParameterNumber("K", "Neighbours (knn, idw)", defaultValue=10, minValue=1), advanced=True)
        self.addOutput(QgsProcessingOutputString("RESULT", "Heights and thickness (JSON)"))

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.tasks.aquifer import aquifer_query

        result = aquifer_query(self.text(parameters, "MODEL", context), self.parameterAsDouble(parameters, "X", context),
                               self.parameterAsDouble(parameters, "Y", context),
                               ["tin", "knn", "idw"][self.parameterAsEnum(parameters, "METHOD", context)],
                               k=self.parameterAsInt(parameters, "K", context))
        for layer, h in result["heights"].items():
            feedback.pushInfo(f"{layer}: {h['z']} ({'inside' if h['inside'] else 'outside'} the boundary)")
        for name, t in result["thickness"].items():
            feedback.pushInfo(f"{name}: thickness {t}")
        return {"RESULT": json.dumps(result)}


# ------------------------------------------------------------------ runway

GROUP_RUNWAY = ("Runway", "runway")


class RunwayAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "runway", "Runway earthworks (sections, areas, mass haul)", GROUP_RUNWAY
    _help = ("A runway survey (points with a type field: 1 = centre-line light, 2 = other, and z) and the aerodrome "
             "reference code to the centre line, an ICAO design model, cross sections, signed cut / fill areas, "
             "the area diagram and the Brückner (mass-haul) curve with balance points (gistools runway).")

    def initAlgorithm(self, config=None):  # noqa: N802
        from gistools.runway.icao import RUNWAY_TYPES, TEMPLATES, VALID_CODES

        self._codes, self._types, self._templates = list(VALID_CODES), list(RUNWAY_TYPES), list(TEMPLATES)
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Survey points (id, type, z)", [QgsProcessing.TypeVectorPoint]))
        self.add(QgsProcessingParameterEnum("CODE", "Aerodrome reference code", options=self._codes,
                                            defaultValue=self._codes.index("4E")))
        self.add(QgsProcessingParameterEnum("RUNWAY_TYPE", "Runway type", options=self._types, defaultValue=0))
        self.add(QgsProcessingParameterEnum("TEMPLATE", "Template", options=self._templates, defaultValue=0))
        self.add(QgsProcessingParameterNumber("SPACING", "Station spacing, m (0: from the survey)",
                                              type=QgsProcessingParameterNumber.Double, defaultValue=0.0, minValue=0.0))
        self.add(QgsProcessingParameterNumber("SWELL", "Swell factor of cut", type=QgsProcessingParameterNumber.Double,
                                              defaultValue=1.0, minValue=0.01), advanced=True)
        self.add(QgsProcessingParameterNumber("COMPACTION", "Compaction factor of fill",
                                              type=QgsProcessingParameterNumber.Double, defaultValue=1.0, minValue=0.01),
                 advanced=True)
        self.add(QgsProcessingParameterNumber("FREE_HAUL", "Free-haul distance, m (0: none)",
                                              type=QgsProcessingParameterNumber.Double, defaultValue=0.0, minValue=0.0),
                 advanced=True)
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("DESIGN", "Design surface"))
        self.addOutput(QgsProcessingOutputVectorLayer("GPKG", "Runway GeoPackage"))
        self.addOutput(QgsProcessingOutputNumber("CUT", "Cut (m3)"))
        self.addOutput(QgsProcessingOutputNumber("FILL", "Fill (m3)"))
        self.addOutput(QgsProcessingOutputFile("REPORT", "report.json"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.runway.icao import RUNWAY_TYPES, TEMPLATES, VALID_CODES
        from gistools.tasks.runway import RunwaySettings, runway_earthworks

        out = Path(self.output_folder(parameters, context))
        spacing = self.parameterAsDouble(parameters, "SPACING", context)
        free = self.parameterAsDouble(parameters, "FREE_HAUL", context)
        settings = RunwaySettings(code=VALID_CODES[self.parameterAsEnum(parameters, "CODE", context)],
                                  runway_type=RUNWAY_TYPES[self.parameterAsEnum(parameters, "RUNWAY_TYPE", context)],
                                  template=TEMPLATES[self.parameterAsEnum(parameters, "TEMPLATE", context)],
                                  spacing=spacing or None, f_cut=self.parameterAsDouble(parameters, "SWELL", context),
                                  f_fill=self.parameterAsDouble(parameters, "COMPACTION", context), free_haul=free or None)
        crs = self.layer_crs(parameters, "INPUT", context)
        rep = runway_earthworks(self.layer_spec(parameters, "INPUT", context, feedback), out, settings, crs=crs,
                                overwrite=True, progress=self.progress(feedback))
        feedback.pushInfo(f"cut {rep['cut']:,.1f} m3, fill {rep['fill']:,.1f} m3, net {rep['net']:,.1f} m3; "
                          f"balance points {rep['balance_points']}; removed {rep['removed']}")
        self.load_on_completion(context, out / "design_surface.tif", "Runway design surface", "DESIGN")
        return {"OUTPUT_FOLDER": str(out), "DESIGN": str(out / "design_surface.tif"), "GPKG": str(out / "runway.gpkg"),
                "CUT": rep["cut"], "FILL": rep["fill"], "REPORT": str(out / "report.json")}


# ------------------------------------------------------------------ structure

class StructureAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "structure", "Structure reconstruction (closed 3D mesh)", ("Structure", "structure")
    _help = ("A building's point cloud (ID X Y Z text, or LAS/LAZ) of floor outlines and floor plates to levels, "
             "clusters, loops with holes, matched walls and a watertight, consistently wound mesh (PLY, OBJ), with the "
             "loops as 3D lines (gistools structure). Parameters are estimated from the data unless given.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterFile("INPUT", "Point cloud (ID X Y Z text, or LAS/LAZ)"))
        for name, text in (("HEIGHT_INTERVAL", "Height interval h, m (0: estimated)"),
                           ("DISTANCE", "Planimetric distance d, m (0: estimated)"),
                           ("TOLERANCE", "Tolerance t, m (0: 4 m)")):
            self.add(QgsProcessingParameterNumber(name, text, type=QgsProcessingParameterNumber.Double, defaultValue=0.0,
                                                  minValue=0.0))
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputFile("MESH", "Mesh (PLY)"))
        self.addOutput(QgsProcessingOutputVectorLayer("LOOPS", "Loops (GeoPackage)"))
        self.addOutput(QgsProcessingOutputNumber("VOLUME", "Volume (m3)"))
        self.addOutput(QgsProcessingOutputString("WATERTIGHT", "Watertight"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.structure import structure_model

        out = Path(self.output_folder(parameters, context))
        value = {k: self.parameterAsDouble(parameters, k, context) or None for k in ("HEIGHT_INTERVAL", "DISTANCE", "TOLERANCE")}
        rep = structure_model(self.parameterAsFile(parameters, "INPUT", context), out, h=value["HEIGHT_INTERVAL"],
                              d=value["DISTANCE"], t=value["TOLERANCE"], overwrite=True, progress=self.progress(feedback))
        feedback.pushInfo(f"{rep['levels']} levels, {rep['clusters']} clusters, {rep['triangles']} triangles, volume "
                          f"{rep['volume']:,.1f} m3, watertight {rep['watertight']}, Euler {rep['euler']}")
        return {"OUTPUT_FOLDER": str(out), "MESH": rep["outputs"]["ply"], "LOOPS": rep["outputs"]["gpkg"],
                "VOLUME": rep["volume"], "WATERTIGHT": str(rep["watertight"])}


ALGORITHMS = (InfoAlgorithm, PointsAlgorithm, DsmAlgorithm, DemAlgorithm, NdsmAlgorithm, RastersAlgorithm, BandsAlgorithm,
              BreaklinesAlgorithm, ClipAlgorithm, DensityAlgorithm, ClassifyAlgorithm, ShrubChainAlgorithm,
              AquiferModelAlgorithm, AquiferQueryAlgorithm, RunwayAlgorithm, StructureAlgorithm)
