"""The whole shrub chain (gistools shrub)."""

from __future__ import annotations

from pathlib import Path

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputFolder,
    QgsProcessingOutputRasterLayer,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterField,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorLayer,
)

from .base import (labels, PRESET_LABEL, CLASS_METHOD_LABEL, BREAKS_LABEL, GistoolsAlgorithm, GROUP_SHRUB,
                   DEM_METHODS, PRESETS, CLASSIFY, BANDS, float_list, SHRUB, RASTER, band_choices, text_list)
from .rasters import DSM_FILL_LABELS, DSM_FILLS
from ..compat import VECTOR_LINE, VECTOR_POLYGON


class ShrubChainAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "shrubchain", "Shrub map (whole chain)", GROUP_SHRUB
    _help = ("The whole shrub chain on a tile folder (gistools shrub): DSM / DEM / nDSM, height bands, road and water "
             "clipping, vegetation density, light / medium / heavy classes, class polygons, a printable map and "
             "report.json, tile by tile (resumable, one bad tile is reported and the others go on).")

    def initAlgorithm(self, config=None):  # noqa: N802
        line = [VECTOR_LINE]
        poly = [VECTOR_POLYGON]
        self.add_tiles()
        self.add(QgsProcessingParameterVectorLayer("ROADS", "Road breaklines (edge of pavement)", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WETLANDS", "Wetland polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("TILE_INDEX", "Tile index (footprints)", poly, optional=True))
        self.add(QgsProcessingParameterField("TILE_FIELD", "Tile number field", defaultValue=SHRUB.tile_field,
                                             parentLayerParameterName="TILE_INDEX", optional=True))
        self.add_length("CELL_SIZE", "Cell size", RASTER.cell_size)
        self.add(QgsProcessingParameterEnum("DEM_METHOD", "DEM method", options=labels(DEM_METHODS),
                                            defaultValue=DEM_METHODS.index(RASTER.dem_method)), advanced=True)
        self.add(QgsProcessingParameterEnum("DSM_FILL", "DSM cells without a first return",
                                            options=[DSM_FILL_LABELS[m] for m in DSM_FILLS],
                                            defaultValue=list(DSM_FILLS).index(RASTER.dsm_fill)), advanced=True,
                 help="Pinholes of the DSM: left empty (the default and the dissertation's), filled by the nearest "
                      "return's height, by a TIN of the highest returns around them, or by lidR's subcircles. Filling "
                      "raises the cover of sparse data (cells count whole): on the sample a medium patch of low "
                      "shrub reads heavy in a fifth of its cells.")
        self.add(QgsProcessingParameterEnum("PRESET", PRESET_LABEL, options=labels(PRESETS), defaultValue=PRESETS.index(SHRUB.bands)))
        self.add_length("NOISE_FLOOR", "Heights up to this are bare ground", SHRUB.noise_floor, advanced=True)
        self.add_length("RADIUS", "Density radius", SHRUB.radius)
        self.add(QgsProcessingParameterEnum("DENSITY_BANDS", "Bands whose vegetation counts", options=BANDS,
                                            allowMultiple=True, defaultValue=band_choices(SHRUB.density_bands)))
        self.add(QgsProcessingParameterEnum("METHOD", CLASS_METHOD_LABEL, options=labels(CLASSIFY), defaultValue=CLASSIFY.index(SHRUB.classify)))
        self.add(QgsProcessingParameterString("BREAKS", BREAKS_LABEL, 
                                              defaultValue=text_list(SHRUB.class_breaks)))
        self.add_length("MAX_ROAD_WIDTH", "Widest road face", SHRUB.max_road_width, advanced=True)
        self.add_length("SNAP", "Breakline snapping tolerance", SHRUB.snap, advanced=True)
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add(QgsProcessingParameterBoolean("MAP", "Draw the printable map (PNG and PDF)", defaultValue=True))
        self.add_crs()
        self.add_parallel()
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("CLASSES", "Shrub classes"))
        self.addOutput(QgsProcessingOutputRasterLayer("COVER", "Vegetation cover"))
        self.addOutput(QgsProcessingOutputVectorLayer("POLYGONS", "Shrub class polygons", VECTOR_POLYGON))
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
                                  dsm_fill=DSM_FILLS[self.parameterAsEnum(parameters, "DSM_FILL", context)],
                                  crs=self.crs_text(parameters, context)),
            bands=PRESETS[self.parameterAsEnum(parameters, "PRESET", context)],
            noise_floor=self.text(parameters, "NOISE_FLOOR", context), radius=self.text(parameters, "RADIUS", context),
            density_bands=bands, classify=CLASSIFY[self.parameterAsEnum(parameters, "METHOD", context)],
            class_breaks=float_list(self.parameterAsString(parameters, "BREAKS", context), "Breaks", 2) or SHRUB.class_breaks,
            max_road_width=self.text(parameters, "MAX_ROAD_WIDTH", context), snap=self.text(parameters, "SNAP", context),
            tile_field=self.parameterAsString(parameters, "TILE_FIELD", context) or SHRUB.tile_field)
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
