"""Terrain and visibility: gistools terrain (slope, aspect, hillshade, ruggedness of a DEM) and gistools viewshed."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterRasterLayer,
)

from .base import GistoolsAlgorithm

GROUP_TERRAIN = ("Terrain and visibility", "terrain")


class TerrainAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "terrain", "Slope, aspect, hillshade (DEM)", GROUP_TERRAIN
    _page = "commands/terrain"
    _tags = ("slope", "aspect", "hillshade", "ruggedness", "tri", "gdaldem", "dem", "terrain")
    _help = ("Slope (degrees and percent), aspect (degrees clockwise from north, flat cells nodata), hillshade and "
             "Riley's terrain ruggedness index of a DEM, as gdaldem computes them (Horn's method). The DEM may be a "
             "VRT mosaic of tiles (the dem.vrt of the rasters algorithm): it is read block by block with a one-cell "
             "halo, so tiles join without seams. Cells on the raster's edge or beside nodata are nodata, as gdaldem "
             "without -compute_edges. Elevations in another unit than x and y are scaled (gdaldem -s). Writes "
             "slope.tif, slope_percent.tif, aspect.tif, hillshade.tif and tri.tif (loaded) and report.json.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("DEM", "DEM (GeoTIFF or VRT mosaic)"))
        self.add_spec(command="terrain", skip=("overwrite",))
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("SLOPE", "Slope (degrees)"))
        self.addOutput(QgsProcessingOutputRasterLayer("HILLSHADE", "Hillshade"))

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
    _help = ("Cells seen from one or several observers, as GDAL's gdal_viewshed (Wang et al. 2000), on a surface "
             "raster: the DSM, where trees and buildings hide a person, or the DEM. Observers are X,Y positions "
             "in the raster's CRS (several separated by ;) and / or a point layer. Writes viewshed.tif (1 seen by at "
             "least one observer, 0 hidden, 255 nodata; loaded) and viewshed_count.tif (how many observers see each "
             "cell). Earth curvature and refraction are optional, as gdal_viewshed -cc.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("SURFACE_RASTER", "Surface (DSM or DEM raster)"))
        self.add_spec(command="viewshed", skip=("overwrite", "hiding_surface"))
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("VIEWSHED", "Viewshed"))
        self.addOutput(QgsProcessingOutputNumber("CELLS_SEEN", "Cells seen"))

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
