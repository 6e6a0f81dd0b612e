"""DSM, DEM and nDSM of a tile folder (gistools rasters)."""

from __future__ import annotations

from qgis.core import QgsProcessingOutputRasterLayer, QgsProcessingParameterFolderDestination

from .base import GistoolsAlgorithm


class _RastersBase(GistoolsAlgorithm):
    """Tile folder -> per-tile GeoTIFFs + VRT mosaics (gistools rasters)."""

    products: tuple = ()
    outputs = {}  # product -> (output name, description)

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec("cell_size")
        if "dsm" in self.products:
            self.add_spec("dsm_classes", "dsm_fill", "subcircle")
        if "dem" in self.products:
            self.add_spec("dem_method", "dem_max_distance", "buffer", "dem_fill", "hydro_flatten", "shore_width",
                          "classify_ground")
        self.add_spec("crs", "jobs", "scheduler", "chunk_size")
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder (one GeoTIFF per tile + VRT)"))
        for product in self.products:
            name, description = self.outputs[product]
            self.addOutput(QgsProcessingOutputRasterLayer(name, description))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.rasters import RasterSettings, rasters_from_tiles

        out = self.output_folder(parameters, context)
        values = self.spec_values(parameters, context, feedback)
        run = {k: values.pop(k) for k in ("jobs", "scheduler")}
        settings = RasterSettings(products=self.products, **{k: v for k, v in values.items() if v is not None})
        result = rasters_from_tiles(self.tiles(parameters, context, feedback), out, settings, overwrite=True,
                                    progress=self.progress(feedback), **run)
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
    _tags = ("dsm", "digital surface model", "canopy", "raster")
    products = ("dsm", "topclass")
    outputs = {"dsm": ("OUTPUT", "DSM"), "topclass": ("TOP_CLASS", "Class of the highest first return")}


class DemAlgorithm(_RastersBase):
    _name, _display = "dem", "DEM (ground TIN)"
    _tags = ("dem", "dtm", "digital elevation model", "tin", "bare earth", "raster")
    products = ("dem",)
    outputs = {"dem": ("OUTPUT", "DEM")}


class RastersAlgorithm(_RastersBase):
    _name, _display = "rasters", "DSM, DEM and nDSM"
    products = ("dsm", "dem", "ndsm", "topclass")
    outputs = {"dsm": ("DSM", "DSM"), "dem": ("DEM", "DEM"), "ndsm": ("NDSM", "nDSM"),
               "topclass": ("TOP_CLASS", "Class of the highest first return")}
