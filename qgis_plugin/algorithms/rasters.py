"""DSM, DEM and nDSM of a tile folder (gistools rasters)."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorLayer,
)

from gistools.lidar.dsmfill import DSM_FILLS
from gistools.tasks.rasters import RasterSettings
from gistools.lidar.gridding import DEM_FILLS

from .base import labels, GistoolsAlgorithm, DEM_METHODS, int_list, RASTER
from ..compat import VECTOR_POLYGON

RASTERS = RasterSettings()  # gistools rasters' defaults (the chain's, RASTER, fill the DSM)
DSM_FILL_LABELS = {"none": "Leave them empty", "nearest": "The nearest return's height (up to 3 cells)", "tin": "A TIN of the highest returns around them (holes up to 3 cells)",
                   "subcircle": "Each return on a circle of half a cell (lidR p2r(subcircle))"}
DEM_FILL_LABELS = {"none": "Leave them empty", "tin": "A TIN across them", "idw": "Inverse distance (8 nearest ground points)"}


class _RastersBase(GistoolsAlgorithm):
    """Tile folder -> per-tile GeoTIFFs + VRT mosaics (gistools rasters)."""

    products: tuple = ()
    outputs = {}  # product -> (output name, description)

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_length("CELL_SIZE", "Cell size", RASTER.cell_size)
        if "dsm" in self.products:
            self.add(QgsProcessingParameterString("DSM_CLASSES", "Classes in the DSM (empty = all but noise 7, 18)",
                                                  optional=True), advanced=True)
            self.add(QgsProcessingParameterEnum("DSM_FILL", "DSM cells without a first return",
                                                options=[DSM_FILL_LABELS[m] for m in DSM_FILLS],
                                                defaultValue=list(DSM_FILLS).index(RASTERS.dsm_fill)), advanced=True,
                     help="Pinholes of the DSM (cells no first return hit): left empty, filled by a TIN of the highest "
                          "returns around them (never above them), by the nearest return's height, or by spreading each "
                          "return on a circle of half a cell.")
        if "dem" in self.products:
            self.add(QgsProcessingParameterEnum("DEM_METHOD", "DEM method", options=labels(DEM_METHODS),
                                                defaultValue=DEM_METHODS.index(RASTER.dem_method)))
            self.add_length("DEM_MAX_DISTANCE", "DEM: leave cells farther than this from ground points empty", RASTER.dem_max_distance,
                            advanced=True)
            self.add(QgsProcessingParameterEnum("DEM_FILL", "DEM voids (farther than that from ground, not water)",
                                                options=[DEM_FILL_LABELS[m] for m in DEM_FILLS],
                                                defaultValue=list(DEM_FILLS).index(RASTERS.dem_fill)), advanced=True,
                     help="Cells farther than the distance above from every ground point (under big buildings): left "
                          "empty, filled by a TIN of the ground around them, or by inverse distance. Counted per tile.")
            self.add(QgsProcessingParameterVectorLayer("HYDRO_FLATTEN", "Hydro-flatten in these water polygons",
                                                       [VECTOR_POLYGON], optional=True),
                     help="Water body polygons (e.g. WATERBODY): the DEM cells inside each take its lowest ground "
                          "elevation along the shore, filled where empty (USGS 3DEP hydro-flattening).")
            self.add_length("SHORE_WIDTH", "Hydro-flatten: shore band outside the polygons (empty: 2 cells)", None,
                            optional=True, advanced=True)
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
            kwargs["dsm_classes"] = int_list(self.parameterAsString(parameters, "DSM_CLASSES", context), "DSM classes")
            kwargs["dsm_fill"] = DSM_FILLS[self.parameterAsEnum(parameters, "DSM_FILL", context)]
        if "dem" in self.products:
            kwargs["dem_method"] = DEM_METHODS[self.parameterAsEnum(parameters, "DEM_METHOD", context)]
            kwargs["dem_max_distance"] = self.text(parameters, "DEM_MAX_DISTANCE", context)
            kwargs["dem_fill"] = DEM_FILLS[self.parameterAsEnum(parameters, "DEM_FILL", context)]
            kwargs["hydro_flatten"] = self.layer_spec(parameters, "HYDRO_FLATTEN", context, feedback)
            kwargs["shore_width"] = self.text(parameters, "SHORE_WIDTH", context)
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
    _name, _display = "rasters", "DSM, DEM and nDSM"
    _help = "DSM, DEM and nDSM (= DSM - DEM) of every tile, each tile decoded once (gistools rasters)."
    products = ("dsm", "dem", "ndsm", "topclass")
    outputs = {"dsm": ("DSM", "DSM"), "dem": ("DEM", "DEM"), "ndsm": ("NDSM", "nDSM"),
               "topclass": ("TOP_CLASS", "Class of the highest first return")}
