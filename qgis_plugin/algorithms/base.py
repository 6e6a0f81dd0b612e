"""Shared plumbing of the gistools Processing algorithms: the parameters made from their one declaration
(``add_spec``, ``spec_values``: gistools.parameters through ``spec.py``), the tile inputs, progress and cancel through
the feedback object, and gistools errors as QgsProcessingException naming the dialog's labels.
"""

from __future__ import annotations

from pathlib import Path

from qgis.core import (
    QgsMapLayer,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingParameterField,
    QgsProcessingParameterFile,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingUtils,
)
from qgis.PyQt.QtGui import QIcon

from gistools.products.aquifer import AquiferSettings
from ..compat import ADVANCED, FILE, FOLDER, POINT_CLOUD, reads_las, reads_vpc
from .texts import HELP

HERE = Path(__file__).resolve().parents[1]  # the plugin folder (icon.svg)

TILE_FOLDER_LABEL = "Folder of LAS/LAZ tiles"
TILE_FILES_LABEL = "Or LAS/LAZ files or point cloud layers"
TILE_LIST_LABEL = "Or LAS/LAZ (or .vpc) files"  # where this QGIS cannot open LAS/LAZ as layers: a list of files
SERVICE_LABEL = "Or a point cloud service (URL of an EPT dataset's ept.json or of a COPC file)"
NO_TILES = "No tiles: choose a '{folder}', or files in '{files}' (the ... button, then Add File(s))"


GROUP_LIDAR = ("LiDAR", "lidar")
# each group's page of the documentation (docs/<page>.md; built into the plugin's help/ by tools/build_plugin.py)
GROUP_PAGES = {"lidar": "commands/rasters", "shrub": "commands/shrub", "deliverables": "commands/deliverables",
               "aquifer": "commands/aquifer", "runway": "commands/runway", "structure": "commands/structure",
               "terrain": "commands/terrain",
               "sar": "search_and_rescue"}
# words the toolbox's search finds an algorithm by, per group (an algorithm adds its own)
GROUP_TAGS = {"lidar": ["lidar", "point cloud", "las", "laz", "elevation", "terrain", "surface"],
              "shrub": ["lidar", "vegetation", "shrub", "density", "fuel", "search and rescue", "fire"],
              "deliverables": ["map", "field", "offline"],
              "aquifer": ["geology", "aquifer", "hydrogeology", "stratigraphy", "volume", "surface"],
              "runway": ["airport", "earthworks", "cut", "fill", "volume", "civil"],
              "structure": ["point cloud", "mesh", "building", "3d", "reconstruction"],
              "terrain": ["terrain", "elevation", "search and rescue"],
              "sar": ["search and rescue", "travel time", "terrain", "slope", "dem"]}


def help_url(page: str, anchor: str = "") -> str:
    """A file URL of the documentation page ``page`` ("commands/rasters", "qgis") at ``anchor``: the site shipped in
    the plugin (help/), else a checkout's docs/ source beside the plugin's folder; "" where neither is there."""
    from qgis.PyQt.QtCore import QUrl

    for path in (HERE / "help" / f"{page}.html", HERE.parent / "docs" / f"{page}.md"):
        if path.is_file():
            url = QUrl.fromLocalFile(str(path))
            if anchor:
                url.setFragment(anchor)
            return url.toString()
    return ""
GROUP_SHRUB = ("Shrub chain", "shrub")
GROUP_DELIVER = ("Field deliverables", "deliverables")
GROUP_SAR = ("Search and rescue", "sar")
AQUIFER = AquiferSettings()  # the aquifer model's defaults, for the labels that state them


class GistoolsAlgorithm(QgsProcessingAlgorithm):
    """Shared plumbing: progress and cancel through the feedback object, gistools errors as QgsProcessingException."""

    _name = ""
    _display = ""
    _group = GROUP_LIDAR
    _help = ""  # where texts.HELP has no entry: a text made when the class is (the declared commands)
    _page = ""  # its documentation page; default: its group's (GROUP_PAGES)
    _tags = ()  # its own search words, beside its group's (GROUP_TAGS)

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
        from .spec import LENGTH_RULE

        lines, lengths = [HELP.get(self._name, self._help), "", "<b>Parameters</b>"], False
        for p in self.parameterDefinitions():
            if p.isDestination():
                continue
            tip = p.help() if hasattr(p, "help") and p.help() else ""
            lengths = lengths or LENGTH_RULE in tip
            tip = tip.replace(LENGTH_RULE, "")  # the unit rule once, below, not under every length
            lines.append(f"<i>{p.description()}</i>" + (f": {tip}" if tip else ""))
        if lengths:
            lines.append(f"<i>Lengths</i>:{LENGTH_RULE}")
        lines.append("")
        lines.append("<b>Outputs</b>")
        lines.extend(f"<i>{o.description()}</i>" for o in self.outputDefinitions())
        return "<br>".join(lines)

    def helpUrl(self):  # noqa: N802
        """The algorithm's section (``#qgis-<name>``) of its page of the documentation shipped in the plugin
        (offline)."""
        return help_url(self._page or GROUP_PAGES.get(self._group[1], "qgis"), f"qgis-{self._name}")

    def tags(self):
        return [*GROUP_TAGS.get(self._group[1], []), *self._tags, "gistools"]

    def icon(self):
        return QIcon(str(HERE / "icon.svg"))

    def createInstance(self):  # noqa: N802
        return type(self)()

    def __init__(self):
        super().__init__()
        self._spec = {}  # the declared parameters added, by Python name
        self._orders = {}  # the order of a choice's values where saved models number them otherwise

    # --- parameter helpers
    def add(self, param, advanced: bool = False, help: str | None = None):  # noqa: A002 - QGIS's word
        if advanced:
            param.setFlags(param.flags() | ADVANCED)
        if help and hasattr(param, "setHelp"):
            param.setHelp(help)
        self.addParameter(param)
        return param

    def add_outputs(self, folder: str | None = "Output folder", **outputs):
        """The output folder parameter OUTPUT_FOLDER (``folder``: its label; None: none) and the algorithm's
        outputs, ``NAME=(kind, label[, layer type])``: kind raster, vector, number, file, string, folder or html."""
        from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputFolder, QgsProcessingOutputHtml,
                               QgsProcessingOutputNumber, QgsProcessingOutputRasterLayer, QgsProcessingOutputString,
                               QgsProcessingOutputVectorLayer, QgsProcessingParameterFolderDestination)

        kinds = {"raster": QgsProcessingOutputRasterLayer, "vector": QgsProcessingOutputVectorLayer,
                 "number": QgsProcessingOutputNumber, "file": QgsProcessingOutputFile,
                 "string": QgsProcessingOutputString, "folder": QgsProcessingOutputFolder,
                 "html": QgsProcessingOutputHtml}
        if folder:
            self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", folder))
        for name, (kind, label, *layer_type) in outputs.items():
            self.addOutput(kinds[kind](name, label, *layer_type))

    def add_spec(self, *names, command: str | None = None, skip=(), defaults: dict | None = None,
                 labels: dict | None = None, orders: dict | None = None):
        """Parameters made from their one declaration (gistools.parameters): ``names``, or every parameter of
        ``command`` but ``skip`` (the command line's own: overwrite). ``defaults``: this algorithm's own;
        ``orders``: {name: choices in the order this algorithm's saved models number them}."""
        from gistools.parameters import COMMANDS, PARAMETERS

        from .spec import qgis_help, qgis_parameter

        defaults, labels, orders = defaults or {}, labels or {}, orders or {}
        names = [n for n in (COMMANDS[command] if command else ()) + names
                 if n not in skip and n != "overwrite" and n not in self._spec]  # (the area's: add_tiles)
        for name in names:
            p = PARAMETERS[name]
            self._spec[name] = p
            if name in orders:
                self._orders[name] = tuple(orders[name])
            self.add(qgis_parameter(p, defaults.get(name), label=labels.get(name), order=orders.get(name)),
                     advanced=p.advanced, help=qgis_help(p, defaults.get(name)))
        return names

    def spec_values(self, parameters, context, feedback, names=None) -> dict:
        """{Python name: value} of the declared parameters this algorithm added (``names``: some of them; the area's,
        which ``tiles`` reads, only when named)."""
        from gistools.parameters.common import AREA

        from .spec import read_value

        return {name: read_value(self, p, parameters, context, feedback, self._orders.get(name))
                for name, p in self._spec.items() if (name not in AREA if names is None else name in names)}

    def add_tiles(self, area: bool = True):
        """The tiles: a folder, and / or LAS/LAZ files (the layer list's file button) or point cloud layers (a
        remote EPT / COPC layer among them), or a point cloud service's URL; and (``area``) the area to read of them. QGIS has
        no "one of two is required": checkParameterValues refuses a run with none, naming them by their labels."""
        from gistools.parameters.common import AREA

        self.add(QgsProcessingParameterFile("INPUT", TILE_FOLDER_LABEL, behavior=FOLDER, optional=True))
        if area:
            self.add(QgsProcessingParameterFile("SERVICE", SERVICE_LABEL, optional=True))
        if reads_las():
            self.add(QgsProcessingParameterMultipleLayers("POINT_CLOUDS", TILE_FILES_LABEL, layerType=POINT_CLOUD,
                                                          optional=True))
        else:  # no PDAL provider (Debian's QGIS 3.22): point cloud layers cannot be made, files can be listed
            self.add(QgsProcessingParameterMultipleLayers("POINT_CLOUDS", TILE_LIST_LABEL, layerType=FILE,
                                                          optional=True))
        if area:
            self.add_spec(*AREA)

    # parameters renamed when one name came to mean one thing in every algorithm: a saved model or script that
    # still gives the old name is refused with the new one (QGIS would otherwise ignore it and run the default)
    _renamed: dict = {}

    def checkParameterValues(self, parameters, context):  # noqa: N802
        for old, new in self._renamed.items():
            if parameters.get(old) not in (None, "") and parameters.get(new) in (None, ""):
                return False, (f"{old} is now {new} ('{self.parameterDefinition(new).description()}'): "
                               f"give {new} instead of {old}")
        if self.parameterDefinition("POINT_CLOUDS") is not None and not parameters.get("INPUT") \
                and not parameters.get("POINT_CLOUDS") and not parameters.get("SERVICE"):
            return False, self.no_tiles()
        return super().checkParameterValues(parameters, context)

    def tiles(self, parameters, context, feedback=None):
        """The tile folder and / or the files of the chosen point cloud layers and the service, as gistools inputs;
        with an area, the area of them (``gistools.Area``, fetched into the output folder's ``fetched/`` unless
        the cache is given)."""
        inputs = []
        folder = self.text(parameters, "INPUT", context)
        if folder:
            inputs.append(folder)
        if parameters.get("POINT_CLOUDS"):
            inputs += self.point_cloud_files(parameters, context)
        service = self.text(parameters, "SERVICE", context)
        if service:
            inputs.append(service)
        if not inputs:
            raise QgsProcessingException(self.no_tiles())
        return self.area_of(inputs, parameters, context, feedback)

    def area_of(self, inputs, parameters, context, feedback):
        """``inputs``, or their area where the algorithm's area is given (a service needs one)."""
        from gistools.io.area import is_area_source
        from gistools.parameters.common import AREA
        from gistools.products.fetch import AREA_FOLDER, Area

        if self.parameterDefinition("AOI") is None:
            return inputs
        area = self.spec_values(parameters, context, feedback, names=AREA)
        if area.get("aoi") is None:
            services = [i for i in inputs if is_area_source(i)]
            if services:
                raise QgsProcessingException(f"{services[0]} is a point cloud service read by area: give the "
                                             f"'{self.parameterDefinition('AOI').description()}'")
            return inputs
        cache = area.pop("cache") or str(Path(self.output_folder(parameters, context) if self.parameterDefinition(
            "OUTPUT_FOLDER") is not None else QgsProcessingUtils.tempFolder()) / AREA_FOLDER)
        buffer = self.spec_values(parameters, context, feedback, names=("buffer",)).get("buffer")
        margin = buffer or ("30m" if "buffer" in self._spec else 0)  # what the command reads around a tile
        found = Area(tuple(inputs), area.pop("aoi"), cache, margin=margin,
                     progress=self.progress(feedback) if feedback else None, **area)
        found.check()  # before any output
        return found

    def no_tiles(self) -> str:
        files = self.parameterDefinition("POINT_CLOUDS")
        text = NO_TILES.format(folder=TILE_FOLDER_LABEL, files=files.description() if files else TILE_FILES_LABEL)
        return text + (f", or give '{SERVICE_LABEL}'" if self.parameterDefinition("SERVICE") is not None else "")

    def extent_text(self, parameters, name, context):
        """An extent parameter as gistools takes an area: minx,miny,maxx,maxy and its CRS (authority id or WKT)."""
        rect = self.parameterAsExtent(parameters, name, context)
        box = f"{rect.xMinimum()!r},{rect.yMinimum()!r},{rect.xMaximum()!r},{rect.yMaximum()!r}"
        value = parameters.get(name)
        if isinstance(value, str) and "[" not in value:  # "xmin,xmax,ymin,ymax" of no CRS: the data's
            return box
        crs = self.parameterAsExtentCrs(parameters, name, context)
        if crs is None or not crs.isValid():
            return box
        return f"{box},{crs.authid() or crs.toWkt()}"

    def point_cloud_files(self, parameters, context) -> list[str]:
        """The files of POINT_CLOUDS: point cloud layers' sources, and files given by name (LAS/LAZ/COPC, or a .vpc,
        which gistools reads even where this QGIS cannot open it as a layer)."""
        values = parameters.get("POINT_CLOUDS") or []
        values = list(values) if isinstance(values, (list, tuple)) else [values]
        files, others = [], []
        for value in values:
            if isinstance(value, QgsMapLayer):
                files.append(value.source().split("|")[0])
            elif isinstance(value, str) and Path(value.split("|")[0]).is_file():
                files.append(value.split("|")[0])
            else:
                others.append(value)
        if others:
            for layer in self.parameterAsLayerList({**parameters, "POINT_CLOUDS": others}, "POINT_CLOUDS", context):
                files.append(layer.source().split("|")[0])
        return files

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

    def crs_text(self, parameters, context, name="CRS"):
        if not parameters.get(name):
            return None
        crs = self.parameterAsCrs(parameters, name, context)
        if not crs.isValid():
            return None
        return crs.authid() or crs.toWkt()

    def layer_spec(self, parameters, name, context, feedback, tables=False):
        """A vector input as gistools reads it (``file.gpkg|layername=LAYER``, unambiguous on Windows paths too);
        memory or filtered layers are exported first. ``tables``: a CSV file is passed as it is (the contacts and
        survey readers read its columns; exported to a GeoPackage it would be a table without geometry)."""
        if parameters.get(name) in (None, ""):
            return None
        formats = ["gpkg", "shp"] + (["csv", "txt"] if tables else [])  # a CSV is read as the table it is
        path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, name, context, formats, "gpkg", feedback)
        if not path:
            return None
        return f"{path}|layername={layer}" if layer and path.lower().endswith(".gpkg") else path

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
        from gistools.parameters import speaks

        labels = {name: self.parameterDefinition(p.qgis_name).description() for name, p in self._spec.items()
                  if self.parameterDefinition(p.qgis_name) is not None}
        with speaks("qgis", labels):  # library messages name the parameters by this dialog's labels
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

    def load_on_completion(self, context, path, name, output, feedback=None):
        """Add ``path`` to the layers QGIS opens when the run ends; a virtual point cloud only where this QGIS opens
        them (3.32+), else a line on the feedback says where it is."""
        if path and str(path).lower().endswith(".vpc") and not reads_vpc():
            if feedback is not None:
                feedback.pushInfo(f"{path}: this QGIS cannot open virtual point clouds (.vpc, QGIS 3.32+), so it is not "
                                  "loaded; gistools reads it as an input, and its tiles open one by one")
            return
        if path and Path(path).exists():
            context.addLayerToLoadOnCompletion(str(path), QgsProcessingContext.LayerDetails(name, context.project(), output))
