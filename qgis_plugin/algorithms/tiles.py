"""Tile info and LAS to points."""

from __future__ import annotations

from qgis.core import QgsProcessingParameterFileDestination

from .base import GistoolsAlgorithm
from ..compat import OPTIONAL
from .spec import flag_parameters


class InfoAlgorithm(GistoolsAlgorithm):
    _name, _display = "info", "Tile info"
    _page = "commands/points"
    _tags = ("header", "crs", "statistics", "lasinfo")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles(area=False)
        self.add_spec(command="info")
        self.add(QgsProcessingParameterFileDestination("OUTPUT", "Summary (JSON)", "JSON files (*.json)", optional=True,
                                                       createByDefault=False))
        self.add_outputs(None, POINTS=("number", "Points"), TILES=("number", "Tiles read"), CRS_NAME=("string", "CRS"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.info import tiles_summary

        path = self.parameterAsFileOutput(parameters, "OUTPUT", context) if parameters.get("OUTPUT") else None
        result = tiles_summary(self.tiles(parameters, context, feedback), out=path, progress=self.progress(feedback),
                               **self.spec_values(parameters, context, feedback))
        for t in result["tiles"]:
            if t["status"] == "ok":
                feedback.pushInfo(f"{t['file']}: LAS {t['las_version']} PF {t['point_format']}, {t['points']:,} points, "
                                  f"{t['crs']}, x/y {t['horizontal_unit']}, z {t['vertical_unit']}, "
                                  f"classes {t['points_by_class']}")
        self.report_tiles(result, feedback)
        out = {"POINTS": result["points"], "TILES": result["counts"]["ok"], "CRS_NAME": "; ".join(result["crs"])}
        if path:
            out["OUTPUT"] = path
        return out


class PointsAlgorithm(GistoolsAlgorithm):
    _name, _display = "points", "LAS to points (by class)"
    _page = "commands/points"
    _tags = ("multipoint", "geopackage", "geoparquet", "class", "export")

    def initAlgorithm(self, config=None):  # noqa: N802
        from gistools.parameters.lidar import COMMAND_DEFAULTS

        self.add_tiles()
        self.add_spec(command="points", defaults=COMMAND_DEFAULTS["points"],
                      labels={"classes": "ASPRS classes (comma-separated; empty = all)"})
        flag_parameters(self, OPTIONAL, "CLASSES")  # empty: every class
        self.add_outputs("Point layers folder", POINTS=("number", "Points written"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.points import points_from_tiles

        out = self.output_folder(parameters, context)
        result = points_from_tiles(self.tiles(parameters, context, feedback), out, overwrite=True, progress=self.progress(feedback),
                                   **self.spec_values(parameters, context, feedback))
        self.report_tiles(result, feedback)
        return {"OUTPUT_FOLDER": out, "POINTS": sum(t["points"] for t in result["tiles"])}
