"""The shrub chain one step at a time, raster in, raster out (gistools.products.steps)."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingParameterField,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterVectorDestination,
    QgsProcessingParameterVectorLayer,
)

from .base import GistoolsAlgorithm, GROUP_LIDAR, GROUP_SHRUB
from ..compat import VECTOR_POINT, VECTOR_POLYGON


def add_tile_field(alg: GistoolsAlgorithm) -> None:
    """tile_field as declared (gistools.parameters), offered as QGIS's field picker on the tile index layer; read
    back as the field's name, as the declared text is."""
    from gistools.parameters import PARAMETERS

    from .spec import qgis_help

    (name,) = alg.add_spec("tile_field")  # registered as declared, then shown as a field picker
    p = PARAMETERS[name]
    label = alg.parameterDefinition(p.qgis_name).description()
    alg.removeParameter(p.qgis_name)
    alg.add(QgsProcessingParameterField(p.qgis_name, label, defaultValue=p.default,
                                        parentLayerParameterName=PARAMETERS["tile_index"].qgis_name, optional=True),
            advanced=p.advanced, help=qgis_help(p))


def given(values: dict) -> dict:
    """The declared parameters' values a run gave (those left empty take the library's default)."""
    return {k: v for k, v in values.items() if v is not None and v != ()}


class NdsmAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "ndsm", "nDSM (DSM - DEM)", GROUP_LIDAR

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("DSM", "DSM"))
        self.add(QgsProcessingParameterRasterLayer("DEM", "DEM"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "nDSM"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.steps import ndsm_from_rasters

        out = self.output_path(parameters, "OUTPUT", context)
        ndsm_from_rasters(self.raster_path(parameters, "DSM", context), self.raster_path(parameters, "DEM", context), out,
                          progress=self.progress(feedback))
        return {"OUTPUT": out}


class BandsAlgorithm(GistoolsAlgorithm):
    _renamed = {"BREAKS": "BAND_BREAKS"}  # BREAKS is the class breaks, in the classify step and the chain
    _name, _display, _group = "bands", "Step 1: height bands", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("NDSM", "nDSM"))
        self.add(QgsProcessingParameterRasterLayer("TOP_CLASS", "Class of the highest first return (from the DSM step)",
                                                   optional=True))
        self.add_spec("bands", "band_breaks_m", "noise_floor", "z_unit")
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Height bands"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POINTS", "Cell-centre points per band (Raster To Point)",
                                                         type=VECTOR_POINT, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.steps import bands_from_ndsm

        out = self.output_path(parameters, "OUTPUT", context)
        points = self.output_path(parameters, "OUTPUT_POINTS", context, optional=True)
        v = given(self.spec_values(parameters, context, feedback))
        z = v.pop("z_unit", "raster")
        steps = {"bands": "preset", "band_breaks_m": "breaks_m", "noise_floor": "noise_floor"}  # the step's words
        result = bands_from_ndsm(self.raster_path(parameters, "NDSM", context), out,
                                 top_class=self.raster_path(parameters, "TOP_CLASS", context),
                                 **{steps[k]: value for k, value in v.items()},
                                 z_unit=None if z == "raster" else z, points_out=points, progress=self.progress(feedback))
        feedback.pushInfo(f"band limits T1, T2, T3 = {', '.join(f'{t:.4f}' for t in result['thresholds'])} "
                          f"{result['z_unit']}")
        return {"OUTPUT": out, **({"OUTPUT_POINTS": points} if points else {})}


class BreaklinesAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "breaklines", "Step 2: road and water polygons", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_spec("roads", "hydro", "waterbodies", "tile_index")
        add_tile_field(self)
        self.add_spec("snap", "max_road_width", "max_hydro_width", "single_line_width", "reproject_vectors")
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_ROADS", "Road polygons", type=VECTOR_POLYGON))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_WATER", "Water polygons", type=VECTOR_POLYGON))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.steps import breakline_polygons

        roads_out = self.output_path(parameters, "OUTPUT_ROADS", context)
        water_out = self.output_path(parameters, "OUTPUT_WATER", context)
        v = given(self.spec_values(parameters, context, feedback))
        v["reproject"] = v.pop("reproject_vectors", False)  # the step's word
        result = breakline_polygons(road_out=roads_out, water_out=water_out, progress=self.progress(feedback), **v)
        feedback.pushInfo(f"{result.get('road_count', 0)} road and {result.get('water_count', 0)} water polygons")
        return {"OUTPUT_ROADS": roads_out, "OUTPUT_WATER": water_out}


class ClipAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "clip", "Step 3: clip roads and water", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        poly = [VECTOR_POLYGON]
        self.add(QgsProcessingParameterRasterLayer("BANDS", "Height bands"))
        self.add(QgsProcessingParameterVectorLayer("ROAD_POLYGONS", "Road polygons", poly, optional=True))
        self.add(QgsProcessingParameterVectorLayer("WATER_POLYGONS", "Water polygons", poly, optional=True))
        self.add_spec("wetlands", "reproject_vectors")
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Vegetation"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT_WETLAND", "Vegetation in wetlands", optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.steps import clip_bands

        out = self.output_path(parameters, "OUTPUT", context)
        wet = self.output_path(parameters, "OUTPUT_WETLAND", context, optional=True)
        v = self.spec_values(parameters, context, feedback)
        clip_bands(self.raster_path(parameters, "BANDS", context), out,
                   road_polygons=self.layer_spec(parameters, "ROAD_POLYGONS", context, feedback),
                   water_polygons=self.layer_spec(parameters, "WATER_POLYGONS", context, feedback),
                   wetlands=v["wetlands"], wetland_out=wet, reproject=v["reproject_vectors"],
                   progress=self.progress(feedback))
        return {"OUTPUT": out, **({"OUTPUT_WETLAND": wet} if wet else {})}


class DensityAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "density", "Step 4: vegetation density", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (from the clip step)"))
        self.add_spec("radius", "density_bands")
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Cover (0-1)"))
        self.add(QgsProcessingParameterRasterDestination("OUTPUT_DENSITY", "Point density", optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.settings import DEFAULTS
        from gistools.products.steps import density_from_vegetation

        out = self.output_path(parameters, "OUTPUT", context)
        dens = self.output_path(parameters, "OUTPUT_DENSITY", context, optional=True)
        v = {"density_bands": DEFAULTS.density_bands, **given(self.spec_values(parameters, context, feedback))}
        result = density_from_vegetation(self.raster_path(parameters, "VEGETATION", context), out, density_out=dens,
                                         progress=self.progress(feedback), **v)
        feedback.pushInfo(f"radius {result['radius']:.4f} CRS units, bands {v['density_bands']}")
        return {"OUTPUT": out, **({"OUTPUT_DENSITY": dens} if dens else {})}


class ClassifyAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "classify", "Step 5: shrub classes", GROUP_SHRUB

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterRasterLayer("COVER", "Cover (from the density step)"))
        self.add(QgsProcessingParameterRasterLayer("VEGETATION", "Vegetation (marks road and water)", optional=True))
        self.add_spec("classify", "class_breaks")
        self.add(QgsProcessingParameterRasterDestination("OUTPUT", "Shrub classes"))
        self.add(QgsProcessingParameterVectorDestination("OUTPUT_POLYGONS", "Shrub class polygons",
                                                         type=VECTOR_POLYGON, optional=True,
                                                         createByDefault=False))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.steps import classes_from_cover

        out = self.output_path(parameters, "OUTPUT", context)
        polys = self.output_path(parameters, "OUTPUT_POLYGONS", context, optional=True)
        v = given(self.spec_values(parameters, context, feedback))
        steps = {"classify": "method", "class_breaks": "breaks"}  # the step's words
        result = classes_from_cover(self.raster_path(parameters, "COVER", context), out,
                                    veg=self.raster_path(parameters, "VEGETATION", context), polygons_out=polys,
                                    progress=self.progress(feedback), **{steps[k]: value for k, value in v.items()})
        feedback.pushInfo(f"breaks {result['breaks']}; class area (CRS units squared): "
                          + ", ".join(f"{k} {v:,.0f}" for k, v in result["class_area"].items()))
        return {"OUTPUT": out, **({"OUTPUT_POLYGONS": polys} if polys else {})}
