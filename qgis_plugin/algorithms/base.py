"""Shared plumbing of the gistools Processing algorithms: parameter helpers, progress and cancel through the
feedback object, gistools errors as QgsProcessingException, and the library's choices and defaults.

Lengths are text with a unit ("5ft", "0.1m"; a bare number is in the data's CRS units), as
in the CLI: QGIS distance widgets hold a number in the layer's units, and the dissertation's
defaults (25 ft, 0.2 ft, ...) must not turn into 25 m on metre data.
"""

from __future__ import annotations

import inspect
from pathlib import Path

from qgis.core import (
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingParameterCrs,
    QgsProcessingParameterField,
    QgsProcessingParameterFile,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
)
from qgis.PyQt.QtGui import QIcon

from gistools.lidar import bands as _bands
from gistools.lidar import gridding as _gridding
from gistools.lidar import shrub as _shrub
from gistools.tasks import points as _points
from gistools.lidar import ground as _ground
from gistools.lidar import noise as _noise
from gistools.tasks import ground as _ground_task
from gistools.tasks.aquifer import AquiferSettings
from gistools.tasks.runway import RunwaySettings
from gistools.tasks.settings import ShrubSettings
from ..compat import ADVANCED, FOLDER, POINT_CLOUD

HERE = Path(__file__).resolve().parents[1]  # the plugin folder (icon.svg)

TILE_FOLDER_LABEL = "Folder of LAS/LAZ tiles"
TILE_FILES_LABEL = "Or LAS/LAZ files or point cloud layers"
NO_TILES = f"No tiles: choose a '{TILE_FOLDER_LABEL}', or files in '{TILE_FILES_LABEL}' (the ... button, then Add File(s))"


def _homepage() -> str:
    for line in (HERE / "metadata.txt").read_text().splitlines():
        if line.startswith("homepage="):
            return line.split("=", 1)[1].strip()
    return ""


HOMEPAGE = _homepage()

GROUP_LIDAR = ("LiDAR", "lidar")
README_SECTIONS = {"lidar": "command-line", "shrub": "the-shrub-chain", "deliverables": "field-deliverables", "aquifer": "aquifer-model", "runway": "runway-earthworks",
                   "structure": "structure-reconstruction"}
GROUP_SHRUB = ("Shrub chain", "shrub")
GROUP_DELIVER = ("Field deliverables", "deliverables")

# choices are the library's own (the provider loads only once gistools imports)
DEM_METHODS = list(_gridding.DEM_METHODS)
RETURNS = list(_points.RETURNS)
PRESETS = list(_bands.PRESETS)
CLASSIFY = list(_shrub.CLASS_METHODS)
Z_UNITS = ["from the raster", "m", "ft", "ftUS"]
BANDS = ["B1 (0-1 m)", "B2 (1-2 m)", "B3 (2-6 m)"]

# defaults are the library's own too: the settings objects' defaults, never copies
GROUND_METHODS = list(_ground.GROUND_METHODS)
NOISE_METHODS = list(_noise.NOISE_METHODS)
POINT_FORMATS = list(_ground_task.FORMATS)
GROUND = _ground_task.GroundSettings()
SHRUB = ShrubSettings()
RASTER = SHRUB.raster
AQUIFER = AquiferSettings()
RUNWAY = RunwaySettings()
POINTS = {k: v.default for k, v in inspect.signature(_points.points_from_tiles).parameters.items()}


# what the dialogs show for the library's choices (the enum index is the library's order, so values do not change)
LABELS = {
    "exact": "Exact metres: 1 / 2 / 6 m", "text_literal": "As printed in the dissertation: 3.28 / 6.56 / 19.658 ft",
    "breaks": "The cover breaks below", "quantile": "Quantiles of the cover (ignores the breaks below)",
    "jenks": "Jenks natural breaks of the cover (ignores the breaks below)",
    "tin": "TIN of the ground points (fills gaps)", "max": "Highest ground point of each cell (the dissertation's)",
    "min": "Lowest ground point of each cell", "mean": "Mean of the ground points of each cell",
    "idw": "Inverse-distance weighted ground points",
    "smrf": "SMRF (Simple Morphological Filter)", "csf": "CSF (Cloth Simulation Filter)",
    "ivf": "Isolated points in voxels (IVF)", "sor": "Statistical outliers (SOR)", "none": "None",
    "laz": "LAZ (compressed LAS)", "las": "LAS", "copc": "COPC (cloud-optimised LAZ)",
    "first": "First returns", "last": "Last returns", "any": "Every return",
    "precision": "Precision approach", "non_precision": "Non-precision approach", "non_instrument": "Non-instrument",
    "icao": "ICAO Annex 14 strip", "dissertation": "The dissertation's section", "ply": "PLY", "obj": "OBJ (Wavefront)",
    "gpkg": "GeoPackage", "parquet": "GeoParquet",
}
LENGTH_HELP = ("A length with its unit, the same rules in every gistools algorithm and on the command line: m; ft is the "
               "CRS's own foot on a CRS in feet (international or US survey), else the international foot; ftUS is the "
               "US survey foot; a bare number is in the CRS's unit.")
# each parameter's help (the dialog's tooltips and the help panel), by name where a name means one thing everywhere
HELP_BY_NAME = {
    "CELL_SIZE": "Side of the raster cells; the cells snap to multiples of it, so tiles line up.",
    "RADIUS": "Radius of the circle around each vegetation cell whose vegetated share is the cover (25 ft in the "
              "dissertation).",
    "NOISE_FLOOR": "Heights above ground up to this are bare ground (band B0), not low vegetation.",
    "MAX_ROAD_WIDTH": "A face between road breaklines wider than this is a block between roads, not road.",
    "SNAP": "Breakline ends closer than this are joined (the dissertation's 0.2 ft cluster tolerance).",
    "DEM_MAX_DISTANCE": "DEM cells farther than this from every ground point stay nodata.",
    "DENSITY_BANDS": "The height bands whose vegetation counts toward the cover (the dissertation counted B1 only).",
    "JOBS": "Tiles processed at once, each in its own process.",
    "SCHEDULER": "For runs past one machine: the address of a Dask scheduler (tcp://host:8786), or 'local'.",
    "CRS": "The tiles' CRS where their headers carry none (or a wrong one); it replaces the headers' CRS.",
}
BREAKS_LABEL = "Cover breaks light / medium, medium / heavy (fractions 0-1, e.g. 0.3,0.7)"
CLASS_METHOD_LABEL = "How the class breaks are chosen"
PRESET_LABEL = "Height band limits"
HELP_BY_LABEL = {
    BREAKS_LABEL: "Cover fractions (0-1) between light and medium and between medium and heavy shrub. Used only when "
                  "the class breaks are 'the cover breaks below'.",
    CLASS_METHOD_LABEL: "The cover breaks below, or breaks found in the data: quantiles (equal areas) or Jenks natural "
                        "breaks (both ignore the breaks below).",
    PRESET_LABEL: "The limits of the height bands B1 (low shrub), B2 (medium) and B3 (tall): exact metres, or the "
                  "values printed in the dissertation.",
}


def labels(values, **override) -> list[str]:
    """The dialog's words for the library's choices ``values``, in their order."""
    return [override.get(v, LABELS.get(v, v)) for v in values]


def band_choices(bands) -> list[int]:
    """The BANDS enum indices of density bands (1-3)."""
    return [b - 1 for b in bands]


def text_list(values) -> str:
    """A tuple of numbers as the comma-separated text of a string parameter."""
    return ",".join(f"{v:g}" for v in values)


def int_list(text: str, name: str):
    text = (text or "").strip()
    if not text:
        return None
    try:
        return tuple(int(v) for v in text.split(","))
    except ValueError:
        raise QgsProcessingException(f"{name}: {text!r} is not a comma-separated list of integers, e.g. 1,2") from None


def float_list(text: str, name: str, count: int):
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
    _readme_section = ""  # default: the section of the algorithm's group (README_SECTIONS)

    def name(self):
        return self._name

    def displayName(self):  # noqa: N802
        return self._display

    def group(self):
        return self._group[0]

    def groupId(self):  # noqa: N802
        return self._group[1]

    def shortHelpString(self):  # noqa: N802
        """The algorithm's text, then each parameter with its help and each output, as QGIS's own algorithms list them."""
        lines = [self._help, "", "<b>Parameters</b>"]
        for p in self.parameterDefinitions():
            if p.isDestination():
                continue
            tip = p.help() if hasattr(p, "help") and p.help() else ""
            lines.append(f"<i>{p.description()}</i>" + (f": {tip}" if tip else ""))
        lines.append("")
        lines.append("<b>Outputs</b>")
        lines.extend(f"<i>{o.description()}</i>" for o in self.outputDefinitions())
        return "<br>".join(lines)

    def helpUrl(self):  # noqa: N802
        """The README section of the algorithm (the project's homepage in metadata.txt)."""
        return f"{HOMEPAGE}#{self._readme_section or README_SECTIONS.get(self._group[1], 'qgis')}"

    def icon(self):
        return QIcon(str(HERE / "icon.svg"))

    def createInstance(self):  # noqa: N802
        return type(self)()

    # --- parameter helpers
    def add(self, param, advanced: bool = False, help: str | None = None):  # noqa: A002 - QGIS's word
        if advanced:
            param.setFlags(param.flags() | ADVANCED)
        help = help or HELP_BY_LABEL.get(param.description()) or HELP_BY_NAME.get(param.name())  # noqa: A001
        if help and hasattr(param, "setHelp"):
            param.setHelp(help)
        self.addParameter(param)
        return param

    def add_tiles(self):
        """The tiles: a folder, and / or LAS/LAZ files (the layer list's file button) or point cloud layers. QGIS has
        no "one of two is required": checkParameterValues refuses a run with neither, naming both by their labels."""
        self.add(QgsProcessingParameterFile("INPUT", TILE_FOLDER_LABEL, behavior=FOLDER, optional=True))
        self.add(QgsProcessingParameterMultipleLayers("POINT_CLOUDS", TILE_FILES_LABEL, layerType=POINT_CLOUD,
                                                      optional=True))

    def checkParameterValues(self, parameters, context):  # noqa: N802
        if self.parameterDefinition("POINT_CLOUDS") is not None and not parameters.get("INPUT") \
                and not parameters.get("POINT_CLOUDS"):
            return False, NO_TILES
        return super().checkParameterValues(parameters, context)

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
            raise QgsProcessingException(NO_TILES)
        return inputs

    def add_crs(self):
        self.add(QgsProcessingParameterCrs("CRS", "Input CRS (overrides the tiles' own; needed for tiles that carry none)",
                                           optional=True), advanced=True)

    def add_parallel(self):
        self.add(QgsProcessingParameterNumber("JOBS", "Tiles in parallel (local processes)", defaultValue=1, minValue=1),
                 advanced=True)
        self.add(QgsProcessingParameterString("SCHEDULER", "Dask scheduler address (tcp://host:8786), or 'local'",
                                              optional=True), advanced=True)

    def add_length(self, name, description, default, optional=False, advanced=False, help=None):  # noqa: A002
        help = help or HELP_BY_NAME.get(name)  # noqa: A001
        self.add(QgsProcessingParameterString(name, f"{description} (with unit: m, ft, ftUS)", defaultValue=default,
                                              optional=optional), advanced=advanced,
                 help=(help + " " if help else "") + LENGTH_HELP)

    def add_fields(self, layer: str, fields: dict):
        """Field pickers on ``layer`` ({NAME: (label, usual column)}), as QGIS's own algorithms offer them; left
        empty (or naming a column the layer lacks), gistools finds the column by its usual names."""
        for name, (label, usual) in fields.items():
            self.add(QgsProcessingParameterField(name, label, defaultValue=usual, parentLayerParameterName=layer,
                                                 optional=True), advanced=True)

    def chosen_fields(self, parameters, context, layer: str, fields: dict) -> dict | None:
        """{gistools field: column} of the pickers whose column the layer has."""
        vl = self.parameterAsVectorLayer(parameters, layer, context)
        names = set(vl.fields().names()) if vl is not None else set()
        chosen = {}
        for name, (_label, usual) in fields.items():
            column = self.parameterAsString(parameters, name, context)
            if column and column in names:
                chosen[name.removesuffix("_FIELD").lower()] = column
        return chosen or None

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
            raise QgsProcessingException(self.labelled(str(err))) from None

    def labelled(self, message: str) -> str:
        """A library message with its command-line option names (--cell-size) as this dialog's labels."""
        import re

        for p in sorted(self.parameterDefinitions(), key=lambda d: -len(d.name())):
            option = "--" + p.name().lower().replace("_", "-")
            message = re.sub(re.escape(option) + r"(?![\w-])", f"'{p.description()}'", message)
        return message

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
