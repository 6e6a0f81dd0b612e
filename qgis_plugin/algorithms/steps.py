"""The shrub chain one step at a time, raster in, raster out (gistools.tasks.steps)."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterField,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorDestination,
    QgsProcessingParameterVectorLayer,
)

from .base import (labels, PRESET_LABEL, CLASS_METHOD_LABEL, BREAKS_LABEL, GistoolsAlgorithm, GROUP_LIDAR,
                   GROUP_SHRUB, PRESETS, CLASSIFY, Z_UNITS, BANDS, float_list, SHRUB, band_choices, text_list)
from ..compat import VECTOR_LINE, VECTOR_POINT, VECTOR_POLYGON


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
    _name, _display, _group = "bands", "Step 1: height bands", GROUP_SHRUB
    _help = ("Height bands of an nDSM: 0 = B0 ground (h <= noise floor, or topped by a ground / water return), "
             "1 = B1 0-1 m, 2 = B2 1-2 m, 3 = B3 2-6 m, 4 = above, 255 = nodata. Thresholds are in metres and converted "
             "to the nDSM's vertical unit (6 m = 19.685 ftUS); 'text_literal' uses the dissertation's printed feet.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("NDSM", "nDSM"))
        self.add(QgsProcessingParameterRasterLayer("TOP_CLASS", "Class of the highest first return (from the DSM step)",
                                                   optional=True))
        self.add(QgsProcessingParameterEnum("PRESET", PRESET_LABEL, options=labels(PRESETS), defaultValue=PRESETS.index(SHRUB.bands)))
        self.add(QgsProcessingParameterString("BREAKS", "Or three band limits in metres (e.g. 1,2,6)", optional=True),
                 advanced=True)
        self.add_length("NOISE_FLOOR", "Heights up to this are bare ground", SHRUB.noise_floor)
        self.add(QgsProcessingParameterEnum("Z_UNIT", "Vertical unit of the nDSM", options=Z_UNITS, defaultValue=0),
                 advanced=True)
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Height bands"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POINTS", "Cell-centre points per band (Raster To Point)",
                                                         type=VECTOR_POINT, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import bands_from_ndsm

        out = self.output_path(parameters, "OUTPUT", context)
        points = self.output_path(parameters, "OUTPUT_POINTS", context, optional=True)
        z = self.parameterAsEnum(parameters, "Z_UNIT", context)
        result = bands_from_ndsm(self.raster_path(parameters, "NDSM", context), out,
                                 top_class=self.raster_path(parameters, "TOP_CLASS", context),
                                 preset=PRESETS[self.parameterAsEnum(parameters, "PRESET", context)],
                                 breaks_m=float_list(self.parameterAsString(parameters, "BREAKS", context), "Band limits", 3),
                                 noise_floor=self.text(parameters, "NOISE_FLOOR", context),
                                 z_unit=None if z == 0 else Z_UNITS[z], points_out=points, progress=self.progress(feedback))
        feedback.pushInfo(f"band limits T1, T2, T3 = {', '.join(f'{t:.4f}' for t in result['thresholds'])} "
                          f"{result['z_unit']}")
        return {"OUTPUT": out, **({"OUTPUT_POINTS": points} if points else {})}


class BreaklinesAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "breaklines", "Step 2: road and water polygons", GROUP_SHRUB
    _help = ("The dissertation's Split (by the tile index) and Feature To Polygon: edge-of-pavement lines and "
             "hydrographic breaklines are split by each tile footprint, noded with a snapping tolerance and "
             "polygonised; faces wider than the maximum width are blocks between roads, not road. Water bodies "
             "(islands stay holes) and buffered single-line hydro features join the water polygons.")

    def initAlgorithm(self, config=None):  # noqa: N802
        line = [VECTOR_LINE]
        poly = [VECTOR_POLYGON]
        self.add(QgsProcessingParameterVectorLayer("ROADS", "Road breaklines (edge of pavement)", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", line, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("TILE_INDEX", "Tile index (footprints)", poly, optional=True))
        self.add(QgsProcessingParameterField("TILE_FIELD", "Tile number field", defaultValue=SHRUB.tile_field,
                                             parentLayerParameterName="TILE_INDEX", optional=True))
        self.add_length("SNAP", "Snapping tolerance", SHRUB.snap)
        self.add_length("MAX_ROAD_WIDTH", "Widest road face", SHRUB.max_road_width)
        self.add_length("MAX_HYDRO_WIDTH", "Widest river face", SHRUB.max_hydro_width, advanced=True)
        self.add_length("SINGLE_LINE_WIDTH", "Width given to single-line hydro features", SHRUB.single_line_width, advanced=True)
        self.add(QgsProcessingParameterBoolean("REPROJECT", "Reproject layers in another CRS (else refuse)",
                                               defaultValue=False), advanced=True)
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_ROADS", "Road polygons", type=VECTOR_POLYGON))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_WATER", "Water polygons", type=VECTOR_POLYGON))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import breakline_polygons

        roads_out = self.output_path(parameters, "OUTPUT_ROADS", context)
        water_out = self.output_path(parameters, "OUTPUT_WATER", context)
        result = breakline_polygons(
            roads=self.layer_spec(parameters, "ROADS", context, feedback),
            hydro=self.layer_spec(parameters, "HYDRO", context, feedback),
            waterbodies=self.layer_spec(parameters, "WATERBODIES", context, feedback),
            tile_index=self.layer_spec(parameters, "TILE_INDEX", context, feedback),
            tile_field=self.parameterAsString(parameters, "TILE_FIELD", context) or SHRUB.tile_field,
            road_out=roads_out, water_out=water_out,
            reproject=self.parameterAsBool(parameters, "REPROJECT", context),
            snap=self.text(parameters, "SNAP", context), max_road_width=self.text(parameters, "MAX_ROAD_WIDTH", context),
            max_hydro_width=self.text(parameters, "MAX_HYDRO_WIDTH", context),
            single_line_width=self.text(parameters, "SINGLE_LINE_WIDTH", context), progress=self.progress(feedback))
        feedback.pushInfo(f"{result.get('road_count', 0)} road and {result.get('water_count', 0)} water polygons")
        return {"OUTPUT_ROADS": roads_out, "OUTPUT_WATER": water_out}


class ClipAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "clip", "Step 3: clip roads and water", GROUP_SHRUB
    _help = ("Vegetation = height band minus road minus water, by cell centre (the dissertation's Clip and Select By "
             "Location on Raster To Point output). Codes: 0 none, 1-3 band of a vegetation cell, 4 road, 5 water, "
             "255 nodata. Vegetation inside wetland polygons is a second output.")

    def initAlgorithm(self, config=None):  # noqa: N802
        poly = [VECTOR_POLYGON]
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
    _name, _display, _group = "density", "Step 4: vegetation density", GROUP_SHRUB
    _help = ("Point density of vegetation cells (each stands for one Raster To Point point) over a circle: cover = "
             "share of the cell centres within the radius that are vegetation (0-1); density = points per CRS area "
             "unit. Blocks read a halo of the radius, so block and tile edges do not show.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (from the clip step)"))
        self.add_length("RADIUS", "Neighbourhood radius", SHRUB.radius)
        self.add(QgsProcessingParameterEnum("DENSITY_BANDS", "Bands whose vegetation counts", options=BANDS,
                                            allowMultiple=True, defaultValue=band_choices(SHRUB.density_bands)))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Cover (0-1)"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT_DENSITY", "Point density", optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import density_from_vegetation

        out = self.output_path(parameters, "OUTPUT", context)
        dens = self.output_path(parameters, "OUTPUT_DENSITY", context, optional=True)
        bands = tuple(i + 1 for i in self.parameterAsEnums(parameters, "DENSITY_BANDS", context)) or SHRUB.density_bands
        result = density_from_vegetation(self.raster_path(parameters, "VEGETATION", context), out, density_out=dens,
                                         radius=self.text(parameters, "RADIUS", context), density_bands=bands,
                                         progress=self.progress(feedback))
        feedback.pushInfo(f"radius {result['radius']:.4f} CRS units, bands {bands}")
        return {"OUTPUT": out, **({"OUTPUT_DENSITY": dens} if dens else {})}


class ClassifyAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "classify", "Step 5: shrub classes", GROUP_SHRUB
    _help = ("Light / medium / heavy shrub classes from cover: 0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water, "
             "255 nodata. 'breaks' uses the given cover breaks (default 0.3, 0.7), 'quantile' and 'jenks' compute them.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("COVER", "Cover (from the density step)"))
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (marks road and water)", optional=True))
        self.add(QgsProcessingParameterEnum("METHOD", CLASS_METHOD_LABEL, options=labels(CLASSIFY), defaultValue=CLASSIFY.index(SHRUB.classify)))
        self.add(QgsProcessingParameterString("BREAKS", BREAKS_LABEL, 
                                              defaultValue=text_list(SHRUB.class_breaks)))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Shrub classes"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POLYGONS", "Shrub class polygons",
                                                         type=VECTOR_POLYGON, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.tasks.steps import classes_from_cover

        out = self.output_path(parameters, "OUTPUT", context)
        polys = self.output_path(parameters, "OUTPUT_POLYGONS", context, optional=True)
        result = classes_from_cover(self.raster_path(parameters, "COVER", context), out,
                                    veg=self.raster_path(parameters, "VEGETATION", context), polygons_out=polys,
                                    method=CLASSIFY[self.parameterAsEnum(parameters, "METHOD", context)],
                                    breaks=float_list(self.parameterAsString(parameters, "BREAKS", context), "Breaks", 2)
                                    or SHRUB.class_breaks, progress=self.progress(feedback))
        feedback.pushInfo(f"breaks {result['breaks']}; class area (CRS units squared): "
                          + ", ".join(f"{k} {v:,.0f}" for k, v in result["class_area"].items()))
        return {"OUTPUT": out, **({"OUTPUT_POLYGONS": polys} if polys else {})}
