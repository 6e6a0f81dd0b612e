"""Parameters of the shrub chain (gistools shrub, the step commands bands / clip / density / classify / map, and the
QGIS algorithms shrubchain, bands, breaklines, clip, density, classify).

The Python names are the fields of ``gistools.products.settings.ShrubSettings`` and the arguments of
``gistools.products.shrub.shrub_from_tiles``. The rasters' parameters (cell_size, dem_method, ...) are declared in
``rasters``, the run's (crs, jobs, scheduler, chunk_size, overwrite) in ``common``, the height bands and the
breaklines gistools normalize takes too in ``lidar``, the tile index and the web map's basemap in ``deliver``.
"""

from .common import AREA
from .core import ByUnits, Parameter, command, declare, option
from . import common, deliver, lidar, rasters  # noqa: F401  (declared there, see below)

# Declared elsewhere and taken as they are: cell_size, dsm_classes, dem_method, dem_max_distance, dsm_fill,
# classify_ground (rasters); crs, jobs, scheduler, chunk_size, overwrite (common); bands, noise_floor, roads, hydro,
# waterbodies, reproject_vectors (lidar: gistools normalize takes them too); tile_index, tile_field, basemap (deliver:
# gistools mapbook and webmap take them too).

# how the class breaks are chosen, and the bands whose vegetation counts (lidar.shrub.CLASS_METHODS is the first)
CLASS_METHOD_LABELS = {"breaks": "The cover breaks below", "quantile": "Quantiles of the cover (ignores the breaks below)",
                       "jenks": "Jenks natural breaks of the cover (ignores the breaks below)"}
DENSITY_BAND_LABELS = {1: "B1 (0-1 m)", 2: "B2 (1-2 m)", 3: "B3 (2-6 m)"}

Z_UNITS = {"raster": "From the raster", "m": "m", "ft": "ft", "ftUS": "ftUS"}

declare(
    Parameter("z_unit", "choice", "The vertical unit of the nDSM: the raster's own (its band unit, else its CRS's), or "
              "the one given here.", "Vertical unit of the nDSM", default="raster", choices=Z_UNITS, advanced=True),
    # the breakline layers (the clip step)
    Parameter("wetlands", "layer", "Wetland polygons: the vegetation inside them is written apart (wetveg/).",
              "Wetland polygons", geometry="polygon", metavar="LAYER"),
    Parameter("snap", "length", "Breakline ends closer than this are joined (the dissertation's 0.2 ft cluster "
              "tolerance).", "Breakline snapping tolerance", default=ByUnits("0.2ft", "0.06m"), minimum=0.0, example="0.2ft",
              advanced=True),
    Parameter("max_road_width", "length", "A face between road breaklines wider than this is a block between roads, "
              "not road.", "Widest road face", default=ByUnits("60ft", "18m"), example="60ft", advanced=True),
    Parameter("max_hydro_width", "length", "A face between hydrographic breaklines wider than this is land between "
              "rivers, not river.", "Widest river face", default=ByUnits("500ft", "150m"), example="500ft", advanced=True),
    Parameter("single_line_width", "length", "The width given to single-line hydrographic features (streams drawn as "
              "one line).", "Width given to single-line hydro features", default=ByUnits("8ft", "2.5m"), example="8ft",
              advanced=True),
    # the height bands
    Parameter("band_breaks_m", "numbers", f"Three band limits in metres, e.g. 1,2,6, instead of {option('bands')}.",
              "Or three band limits in metres (e.g. 1,2,6)", flag="--band-breaks", count=3, minimum=0.0,
              example="1,2,6", default_text=f"those of {option('bands')}", advanced=True, qgis="BAND_BREAKS"),
    Parameter("radius", "length", "Radius of the circle around each vegetation cell whose vegetated share is the cover "
              "(25 ft in the dissertation).", "Density radius", default=ByUnits("25ft", "7.5m"), example="25ft"),
    Parameter("density_bands", "choices", "The height bands whose vegetation counts toward the cover (the dissertation "
              "counted B1 only).", "Bands whose vegetation counts", default=(1, 2, 3), choices=DENSITY_BAND_LABELS,
              aliases={str(b): b for b in DENSITY_BAND_LABELS}, example="1,2,3"),
    Parameter("classify", "choice", f"How the class breaks are chosen: breaks, the cover fractions of "
              f"{option('class_breaks')}; quantile (equal areas) or jenks (Jenks natural breaks): breaks found in the "
              "cover.", "How the class breaks are chosen", default="breaks", choices=CLASS_METHOD_LABELS, qgis="METHOD"),
    Parameter("class_breaks", "numbers", "Cover fractions (0-1) between light and medium and between medium and heavy "
              f"shrub; used when {option('classify')} is breaks.",
              "Cover breaks light / medium, medium / heavy (fractions 0-1, e.g. 0.3,0.7)", flag="--breaks",
              default=(0.3, 0.7), count=2, minimum=0.0, maximum=1.0, example="0.3,0.7", qgis="BREAKS"),
    # the outputs beside the class rasters
    Parameter("make_map", "flag", "The printable shrub map (shrub_map.png and shrub_map.pdf): drawn unless left out "
              "(on the command line, --no-map leaves it out).",
              "Draw the printable map (PNG and PDF)", default=True, flag="--no-map", qgis="MAP"),
    Parameter("web_map", "flag", "Also write OUT/shrub_map.html, the offline web map (gistools webmap).",
              "Also write the offline web map (shrub_map.html)", default=False),
    Parameter("band_points", "flag", "Also write the cell-centre points of each band with their height (band_points/, "
              "the dissertation's Raster To Point).", "Cell-centre points per band (Raster To Point)", default=False,
              advanced=True),
    Parameter("title", "text", "The map's title.", "Map title", metavar="TEXT",
              default_text="the title the chain gave it (OUT/report.json)"),
)

_RUN = ("make_map", "scheduler", "jobs")  # how a step rerun runs

SHRUB = command("shrub", "roads", "hydro", "waterbodies", "wetlands", "tile_index", "tile_field", "reproject_vectors",
                "cell_size", "dsm_classes", "dem_method", "dem_max_distance", "dsm_fill", "classify_ground", "bands",
                "band_breaks_m", "noise_floor", "radius", "density_bands", "classify", "class_breaks", "max_road_width",
                "snap", "make_map", "web_map", "basemap", "band_points", "scheduler", "crs", "jobs", "chunk_size",
                "overwrite", *AREA,
    library="products.shrub:shrub_from_tiles", settings="products.shrub:ShrubSettings", command_line=('web_map', 'basemap', *AREA),
    cli="shrub:shrub")
# the settings each step of a run records and a step rerun may change; the command that reruns each step
STAGE_SETTINGS = {"bands": ("bands", "band_breaks_m", "noise_floor"),
                  "clip": ("snap", "max_road_width", "max_hydro_width", "single_line_width", "tile_field", "roads", "hydro",
                           "waterbodies", "wetlands", "tile_index", "reproject_vectors"),
                  "density": ("radius", "density_bands"), "classes": ("classify", "class_breaks")}
STEP_COMMANDS = {"bands": "bands", "clip": "clip", "density": "density", "classes": "classify"}
# the step commands: each takes its own step's settings (STAGE_SETTINGS), then how it runs
BANDS = command("bands", "bands", "band_breaks_m", "noise_floor", *_RUN,
    library="products.shrub:shrub_from_tiles", settings="products.shrub:ShrubSettings", cli="shrub:bands")
CLIP = command("clip", "roads", "hydro", "waterbodies", "wetlands", "tile_index", "tile_field", "reproject_vectors",
               "max_road_width", "snap", *_RUN,
    library="products.shrub:shrub_from_tiles", settings="products.shrub:ShrubSettings", cli="shrub:clip")
DENSITY = command("density", "radius", "density_bands", *_RUN,
    library="products.shrub:shrub_from_tiles", settings="products.shrub:ShrubSettings", cli="shrub:density")
CLASSIFY = command("classify", "classify", "class_breaks", *_RUN,
    library="products.shrub:shrub_from_tiles", settings="products.shrub:ShrubSettings", cli="shrub:classify")
MAP = command("map", "title",
    library="products.shrub:map_from_classes", cli="shrub:map_")
