"""Tile info and LAS to points."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingOutputString,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterString,
)

from .base import labels, GistoolsAlgorithm, RETURNS, int_list, POINTS, text_list


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
        from gistools.tasks.info import tiles_summary

        path = self.parameterAsFileOutput(parameters, "OUTPUT", context) if parameters.get("OUTPUT") else None
        result = tiles_summary(self.tiles(parameters, context), crs=self.crs_text(parameters, context), out=path,
                               progress=self.progress(feedback))
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
    _help = ("The dissertation's LAS To Multipoint: per tile, a point layer (GeoPackage, or GeoParquet) with x, y, z, "
             "class, return number and intensity of the chosen classes and returns, streamed in chunks. "
             "Non-ground: classes 1,2 first returns; ground: class 2, any return.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add(QgsProcessingParameterString("CLASSES", "ASPRS classes (comma-separated; empty = all)", defaultValue=text_list(POINTS["classes"]),
                                              optional=True))
        self.add(QgsProcessingParameterEnum("RETURNS", "Returns", options=labels(RETURNS), defaultValue=RETURNS.index(POINTS["returns"])))
        self.add(QgsProcessingParameterEnum("FORMAT", "Format", options=labels(["gpkg", "parquet"]), defaultValue=0), advanced=True)
        self.add_crs()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Point layers folder"))
        self.addOutput(QgsProcessingOutputNumber("POINTS", "Points written"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.points import points_from_tiles

        out = self.output_folder(parameters, context)
        result = points_from_tiles(self.tiles(parameters, context), out,
                                   classes=int_list(self.parameterAsString(parameters, "CLASSES", context), "Classes"),
                                   returns=RETURNS[self.parameterAsEnum(parameters, "RETURNS", context)],
                                   fmt=["gpkg", "parquet"][self.parameterAsEnum(parameters, "FORMAT", context)],
                                   crs=self.crs_text(parameters, context), overwrite=True, progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        return {"OUTPUT_FOLDER": out, "POINTS": sum(t["points"] for t in result["tiles"])}
