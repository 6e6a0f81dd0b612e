"""Terrain and visibility: gistools terrain (slope, aspect, hillshade, ruggedness of a DEM) and gistools viewshed."""

from __future__ import annotations

from qgis.core import QgsProcessingParameterRasterLayer

from .base import GistoolsAlgorithm

GROUP_TERRAIN = ("Terrain and visibility", "terrain")


class TerrainAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "terrain", "Slope, aspect, hillshade (DEM)", GROUP_TERRAIN
    _page = "commands/terrain"
    _tags = ("slope", "aspect", "hillshade", "ruggedness", "tri", "gdaldem", "dem", "terrain")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("DEM", "DEM (GeoTIFF or VRT mosaic)"))
        self.add_spec(command="terrain", skip=("overwrite",))
        self.add_outputs("Output folder", SLOPE=("raster", "Slope (degrees)"), HILLSHADE=("raster", "Hillshade"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.terrain import terrain_from_dem

        out = self.output_folder(parameters, context)
        v = self.spec_values(parameters, context, feedback)
        report = terrain_from_dem(self.raster_path(parameters, "DEM", context), out, products=v["terrain_products"],
                                  azimuth=v["azimuth"], altitude=v["altitude"], z_unit=v["dem_z_unit"] or "raster",
                                  overwrite=True, progress=self.progress(feedback))
        u = report["units"]
        feedback.pushInfo(f"x, y in {u['horizontal']}, z in {u['vertical']} ({u['vertical_from']}), scale {u['scale']:.6g}")
        for w in report.get("warnings", []):
            feedback.pushWarning(f"WARNING {w}") if hasattr(feedback, "pushWarning") else feedback.reportError(f"WARNING {w}")
        for name, path in report["outputs"].items():
            self.load_on_completion(context, path, name.replace("_", " ").capitalize(), name.upper())
        return {"OUTPUT_FOLDER": out, "SLOPE": report["outputs"].get("slope"),
                "HILLSHADE": report["outputs"].get("hillshade")}


class ViewshedAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "viewshed", "Viewshed (what observers see)", GROUP_TERRAIN
    _page = "commands/terrain"
    _tags = ("viewshed", "visibility", "line of sight", "observer", "search and rescue", "gdal_viewshed")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("SURFACE_RASTER", "Surface (DSM or DEM raster)"))
        self.add_spec(command="viewshed", skip=("overwrite", "hiding_surface"))
        self.add_outputs("Output folder", VIEWSHED=("raster", "Viewshed"), CELLS_SEEN=("number", "Cells seen"))

    def checkParameterValues(self, parameters, context):  # noqa: N802
        if parameters.get("OBSERVER") in (None, "") and parameters.get("OBSERVERS") in (None, ""):
            return False, (f"No observer: give '{self.parameterDefinition('OBSERVER').description()}' or "
                           f"'{self.parameterDefinition('OBSERVERS').description()}'")
        return super().checkParameterValues(parameters, context)

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.viewshed import viewshed_from_surface

        out = self.output_folder(parameters, context)
        v = self.spec_values(parameters, context, feedback)
        report = viewshed_from_surface(self.raster_path(parameters, "SURFACE_RASTER", context), out,
                                       observers=v["observer"], observers_layer=v["observers"],
                                       observer_height=v["observer_height"], target_height=v["target_height"] or "0",
                                       max_distance=v["max_distance"] or "0",
                                       curvature=v["curvature"], curvature_coefficient=v["curvature_coefficient"],
                                       z_unit=v["dem_z_unit"] or "raster", overwrite=True,
                                       progress=self.progress(feedback))
        for o in report["observers"]:
            feedback.pushInfo(f"observer {o['x']:.10g},{o['y']:.10g}: eye at {o['eye_elevation']:.2f} "
                              f"{report['units']['vertical']}, {o['cells_seen']:,} cells seen")
        self.load_on_completion(context, report["outputs"]["visibility"], "Viewshed", "VIEWSHED")
        return {"OUTPUT_FOLDER": out, "VIEWSHED": report["outputs"]["visibility"], "CELLS_SEEN": report["cells_seen"]}
