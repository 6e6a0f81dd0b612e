"""Parameters of the DSM, DEM and nDSM (gistools rasters, and the shrub chain's first stage)."""

from .common import AREA
from .core import ByUnits, Parameter, command, declare, option

DEM_METHODS = {"tin": "TIN of the ground points (fills gaps)", "max": "Highest ground point of each cell (the dissertation's)",
               "min": "Lowest ground point of each cell", "mean": "Mean of the ground points of each cell",
               "idw": "Inverse-distance weighted ground points"}
DEM_FILLS = {"none": "Leave them empty", "tin": "A TIN across them", "idw": "Inverse distance (8 nearest ground points)"}
DSM_FILLS = {"none": "Leave them empty", "nearest": "The nearest return's height (up to 3 cells)",
             "tin": "A TIN of the highest returns around them (holes up to 3 cells)",
             "subcircle": "Each return on a circle (lidR p2r(subcircle))"}
PRODUCTS = {"dsm": "DSM", "dem": "DEM", "ndsm": "nDSM", "topclass": "Class of the highest first return"}
GROUND_METHODS = {"smrf": "SMRF (Simple Morphological Filter)", "csf": "CSF (Cloth Simulation Filter)",
                  "smrftin": "SMRF, then a TIN of its ground (densification)",
                  "adaptive": "smrftin, its thresholds from what the survey is (noise, canopy)"}

declare(
    Parameter("cell_size", "length", "Side of the raster cells, with its unit (5ft, 1.5m; a bare number is in CRS "
              "units). The cells snap to multiples of it, so tiles line up.", "Cell size", example="5ft",
              default=ByUnits("5ft", "1.5m", "the dissertation's 5 ft cell; 1.5 m is its round metre value")),
    Parameter("dsm_classes", "classes", "Classes in the DSM (first returns), e.g. 1,2 as in the dissertation.",
              "Classes in the DSM", default_text="every class but noise (7, 18)", advanced=True, example="1,2"),
    Parameter("dem_method", "choice", "tin: Delaunay of the ground points, at cell centres (fills gaps); max / min / "
              "mean: the highest / lowest / mean ground point of each cell (max is the dissertation's Point To Raster "
              "MAXIMUM; empty cells stay nodata); idw: inverse-distance weighted ground points within "
              f"{option('dem_max_distance')}.", "DEM method", default="tin", choices=DEM_METHODS),
    Parameter("dem_max_distance", "length", "DEM cells farther than this from every ground point stay nodata (tin, "
              "idw).", "DEM: leave cells farther than this from ground points empty", default="15m", advanced=True,
              example="15m"),
    Parameter("buffer", "length", "How far into the neighbouring tiles their points are read, so that a tile's edge "
              "cells see the points beyond it (tiled == untiled).", "Points read from neighbouring tiles within",
              advanced=True, example="30m", minimum=0.0,
              default_text=f"2 x {option('dem_max_distance')}, at least 20 cells"),
    Parameter("products", "choices", "Which rasters to write.", "Rasters to write", choices=PRODUCTS,
              default=("dsm", "dem", "ndsm"), advanced=True, example="dsm,dem"),
    Parameter("classify_ground", "choice", "For tiles without ground classes: classify ground and noise first (gistools "
              "ground, with its defaults) into OUT/classified/ and make the rasters from those.",
              "Classify ground first (for unclassified tiles)", choices=GROUND_METHODS, advanced=True,
              default_text="use the tiles' own ground class"),
    Parameter("hydro_flatten", "layer", "Water polygons (e.g. the WATERBODY breaklines): the DEM cells inside each take "
              "its lowest ground elevation along the shore, filled where empty; the nDSM follows (USGS 3DEP "
              "hydro-flattening).", "Hydro-flatten in these water polygons", geometry="polygon", metavar="LAYER"),
    Parameter("dem_fill", "choice", "DEM voids (cells farther than the DEM's maximum distance from ground, e.g. under big "
              "buildings): a TIN across them, inverse distance of the 8 nearest ground points, or left empty; water "
              "cells stay empty.", "DEM voids (far from ground, not water)", default="none", choices=DEM_FILLS,
              advanced=True),
    Parameter("dsm_fill", "choice", "DSM cells without a first return: a TIN of the cells' highest returns over every "
              "hole inside their hull, water too (never above them), the nearest return's height (up to 3 cells), each "
              f"return also on a circle of {option('subcircle')} (lidR's p2r(subcircle)), or left empty.",
              "DSM cells without a first return", default="none", choices=DSM_FILLS, advanced=True),
    Parameter("subcircle", "length", "The circle's radius of the subcircle DSM fill.", "DSM subcircle radius",
              default_text="half a cell", advanced=True, example="0.2m"),
    Parameter("shore_width", "length", "Hydro-flattening: how far outside a water polygon its shore's ground points are "
              "taken.", "Hydro-flatten: shore band outside the polygons", default_text="2 cells", advanced=True,
              example="10ft"),
)

RASTERS = command("rasters", "cell_size", "dsm_classes", "dem_method", "dem_max_distance", "buffer", "products",
                  "classify_ground", "hydro_flatten", "dem_fill", "dsm_fill", "subcircle", "shore_width", "crs", "jobs",
                  "chunk_size", "overwrite", "scheduler", *AREA,
    library="products.rasters:rasters_from_tiles", settings="products.rasters:RasterSettings", cli="rasters:rasters", command_line=AREA)
