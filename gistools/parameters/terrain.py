"""Parameters of the terrain derivatives (``gistools terrain``) and the viewshed (``gistools viewshed``)."""

from .core import COMMAND_DEFAULTS, ByUnits, Parameter, command, declare, option
from .shrub import Z_UNITS

TERRAIN_PRODUCTS = {"slope": "Slope (degrees)", "slope_percent": "Slope (percent)",
                    "aspect": "Aspect (degrees clockwise from north)", "hillshade": "Hillshade",
                    "tri": "Terrain ruggedness index (Riley)"}
SURFACES = {"dsm": "DSM (what hides a person: trees, buildings)", "dem": "DEM (bare ground)"}

declare(
    Parameter("terrain_products", "choices", "Which rasters to write: slope (degrees), slope_percent, aspect (degrees "
              "clockwise from north, flat cells nodata), hillshade (1-255) and tri (Riley's terrain ruggedness index, in "
              "the DEM's vertical unit), as gdaldem slope / slope -p / aspect / hillshade / TRI.", "Rasters to write",
              choices=TERRAIN_PRODUCTS, default=tuple(TERRAIN_PRODUCTS), flag="--products", qgis="PRODUCTS",
              example="slope,hillshade", keyword="products"),
    Parameter("azimuth", "float", "Hillshade: the direction of the light, degrees clockwise from north.",
              "Hillshade light azimuth (degrees from north)", default=315.0, minimum=0.0, maximum=360.0, advanced=True),
    Parameter("altitude", "float", "Hillshade: the height of the light above the horizon, degrees.",
              "Hillshade light altitude (degrees)", default=45.0, minimum=0.0, maximum=90.0, advanced=True),
    Parameter("dem_z_unit", "choice", "The vertical unit of the elevations: the raster's own (its band unit, else "
              "its CRS's vertical unit, else its horizontal unit), or the one given here.", "Vertical unit of the "
              "elevations", default="raster", choices=Z_UNITS, flag="--z-unit", qgis="Z_UNIT", advanced=True,
              keyword="z_unit"),
    Parameter("observer", "text", "An observer's position X,Y in the raster's CRS; give it again for more observers "
              "(in Python a list of (x, y)).", "Observer position(s): X,Y; several separated by ;", flag="--from",
              metavar="X,Y", example="565300,654400", keyword="observers"),
    Parameter("observers", "layer", "A point layer of observers (file.gpkg:LAYER or a shapefile), in the raster's CRS.",
              "Observers (point layer)", geometry="point", metavar="LAYER", keyword="observers_layer"),
    Parameter("observer_height", "length", "The observer's eye above the surface.", "Observer height above the surface",
              default=ByUnits("6ft", "2m", "a standing person's eye, rounded up"), minimum=0.0, flag="--height",
              example="6ft"),
    Parameter("target_height", "length", "A target is seen when a point this high above its cell is.",
              "Target height above the surface", default="0", minimum=0.0, example="6ft"),
    Parameter("hiding_surface", "choice", "The surface that hides: the DSM (trees and buildings hide a person) or the DEM "
              "(bare ground only). Used when the input is a folder of gistools rasters.", "Surface that hides",
              default="dsm", choices=SURFACES, flag="--surface", qgis="SURFACE", keyword="surface_kind"),
    Parameter("max_distance", "length", "Only cells within this distance of an observer are computed (gdal_viewshed "
              "-md); the output covers the observers' ranges only, and cells beyond every range are 0. 0: no limit, "
              "the whole raster (read into memory).", "Maximum distance from an observer (0: no limit)", default="0",
              minimum=0.0, example="3000ft"),
    Parameter("curvature", "flag", f"Lower distant cells by the Earth's curvature less refraction, as gdal_viewshed: "
              f"{option('curvature_coefficient')} x distance^2 / the ellipsoid's diameter.",
              "Earth curvature and refraction", default=False),
    Parameter("curvature_coefficient", "float", "The curvature coefficient (gdal_viewshed -cc): 1 minus the "
              "refraction coefficient; 0.85714 for a refraction of 1/7.", "Curvature coefficient", default=0.85714,
              minimum=0.0, maximum=1.0, advanced=True),
)

declare(
    Parameter("slope_breaks", "numbers", "Slope limits between the classes, degrees, increasing (0-90): class 1 "
              "below the first, the last class at or above the last limit.", "Slope class limits (degrees, e.g. "
              "5,15,30)", default=(5.0, 15.0, 30.0), minimum=0.0, maximum=90.0, flag="--breaks", qgis="BREAKS",
              example="5,15,30", keyword="breaks"),
)
# a command declared whole: its front ends (command line, QGIS algorithm, reference page) are made from this
SLOPE_CLASSES = command("slope-classes", "slope_breaks", "dem_z_unit", "overwrite",
                        library="products.slope_classes:slope_classes_from_dem",
                        inputs=(("dem", "raster", "DEM (GeoTIFF or VRT mosaic)"),),
                        summary="Slope classes of a DEM (gdaldem's slope in degrees, cut at limits).",
                        page="commands/terrain", group="terrain", outputs=("slope_classes",))

TERRAIN = command("terrain", "terrain_products", "azimuth", "altitude", "dem_z_unit", "overwrite",
    library="products.terrain:terrain_from_dem", cli="terrain:terrain")
VIEWSHED = command("viewshed", "observer", "observers", "observer_height", "target_height", "hiding_surface", "max_distance", "curvature",
                   "curvature_coefficient", "dem_z_unit", "overwrite",
    library="products.viewshed:viewshed_from_surface", cli="terrain:viewshed")
COMMAND_DEFAULTS.update({"terrain": {}, "viewshed": {}})
