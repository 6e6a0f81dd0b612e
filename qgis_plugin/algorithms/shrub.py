"""The whole shrub chain (gistools shrub)."""

from __future__ import annotations

from pathlib import Path


from .base import GistoolsAlgorithm, GROUP_SHRUB
from .steps import add_tile_field, given
from ..compat import VECTOR_POLYGON

LAYERS = ("roads", "hydro", "waterbodies", "wetlands", "tile_index")
RUN = ("reproject_vectors", "make_map", "band_points", "jobs", "scheduler")  # shrub_from_tiles' own arguments


class ShrubChainAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "shrubchain", "Shrub map (whole chain)", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_tiles()
        self.add_spec(*LAYERS)
        add_tile_field(self)
        # the rasters' settings the chain takes, then the steps', then the run's
        self.add_spec("cell_size", "dsm_classes", "dem_method", "dem_max_distance", "dsm_fill", "classify_ground",
                      "bands", "band_breaks_m", "noise_floor", "radius", "density_bands", "classify", "class_breaks",
                      "max_road_width", "snap", "reproject_vectors", "make_map", "band_points", "crs", "jobs",
                      "scheduler", "chunk_size")
        self.add_outputs(
            "Output folder", CLASSES=("raster", "Shrub classes"), COVER=("raster", "Vegetation cover"),
            DEM=("raster", "DEM"),
            POLYGONS=("vector", "Shrub class polygons", VECTOR_POLYGON), MAP_PNG=("file", "Shrub map (PNG)"),
            FOLDER=("folder", "Output folder"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.rasters import RasterSettings
        from gistools.products.shrub import ShrubSettings, shrub_from_tiles

        out = Path(self.output_folder(parameters, context))
        values = given(self.spec_values(parameters, context, feedback))
        layers = {k: values.pop(k) for k in LAYERS if k in values}
        run = {k: values.pop(k) for k in RUN if k in values}
        raster = {k: values.pop(k) for k in list(values) if k in RasterSettings.__dataclass_fields__}
        settings = ShrubSettings(raster=RasterSettings(**raster), **values)
        result = shrub_from_tiles(self.tiles(parameters, context, feedback), out, settings, **layers, **run, overwrite=True,
                                  progress=self.progress(feedback))
        self.report_tiles(result, feedback)
        if "class_area" in result:
            feedback.pushInfo(f"class area ({result['area_unit']}): "
                              + ", ".join(f"{k} {v:,.0f}" for k, v in result["class_area"].items()))
        mosaics = result.get("mosaics", {})
        outputs = {"OUTPUT_FOLDER": str(out), "FOLDER": str(out), "CLASSES": mosaics.get("classes"),
                   "COVER": mosaics.get("cover"), "DEM": mosaics.get("dem"), "POLYGONS": str(out / "shrub_classes.gpkg"),
                   "MAP_PNG": str(out / "shrub_map.png") if (out / "shrub_map.png").exists() else None}
        self.load_on_completion(context, outputs["CLASSES"], "Shrub classes", "CLASSES")
        self.load_on_completion(context, outputs["POLYGONS"], "Shrub class polygons", "POLYGONS")
        return outputs
