"""Parameters of the travel time of a walker (gistools travel, TravelSettings): the DEM and the points last seen,
the shrub classes, roads and water, and the speed model (Tobler's hiking function, vegetation factors)."""

from .core import ByUnits, Parameter, command, declare, option  # noqa: F401

NEIGHBOURS = {"16": "16: the king's and the knight's moves (straight walks within 2.75 %)",
              "8": "8: the king's moves (straight walks within 8.24 %)"}

declare(
    Parameter("dem", "raster", "The DEM: a raster or VRT (e.g. out/dem.vrt of gistools rasters), or an output folder "
              "of gistools rasters or gistools shrub (its dem.vrt, and its classes.vrt for shrub, roads and water).",
              "DEM (raster, VRT, or a gistools output folder)", metavar="DEM", required=True, example="out"),
    Parameter("last_seen", "text", "A point last seen as X,Y in the DEM's CRS, or a point layer (file.gpkg:LAYER); "
              "give it again for more points: each cell gets the time from the nearest.", "Points last seen",
              flag="--from", metavar="X,Y|LAYER", example="431000,1811000"),
    Parameter("shrub_classes", "raster", "A shrub classes raster of gistools shrub (0 none, 1 light, 2 medium, 3 heavy, "
              "4 road, 5 water) on the DEM's grid.",
              "Shrub classes raster (gistools shrub classes.vrt)", flag="--classes", qgis="CLASSES", metavar="RASTER",
              default_text="classes.vrt of the folder when the DEM is a gistools shrub folder", keyword="classes"),
    Parameter("tobler", "numbers", "Tobler's hiking function v = A exp(-B |slope + C|) km/h: A,B,C (the slope along "
              "each step, rise over run, uphill positive).", "Tobler's function A,B,C of v = A exp(-B |s + C|) km/h",
              default=(6, 3.5, 0.05), count=3, minimum=0.0, example="6,3.5,0.05", advanced=True),
    Parameter("shrub_factors", "numbers", "Speed factors of light, medium and heavy shrub (1 open ground); 0 makes a "
              "class impassable.", "Speed factors of light, medium, heavy shrub", default=(0.92, 0.83, 0.75), count=3,
              minimum=0.0, maximum=1.0, example="0.92,0.83,0.75", advanced=True),
    Parameter("road_speed", "float", "Walking speed on roads in km/h, whatever the slope.",
              "Road speed, km/h (empty: Tobler's on the slope, no shrub)", minimum=0.01, example="5",
              default_text="Tobler's speed on the slope, without shrub"),
    Parameter("wade_speed", "float", "Wading speed across water in km/h.", "Wading speed, km/h (empty: water is "
              "impassable)", minimum=0.01, example="1", default_text="water is impassable"),
    Parameter("neighbours", "choice", "Moves of the grid walk: 16 (with the knight's moves) or 8.", "Neighbours",
              default="16", choices=NEIGHBOURS, advanced=True),
    Parameter("isotropic", "flag", "The same speed both ways: each cell's speed from its steepest slope taken uphill "
              "(no downhill gain), as a cost-distance tool.", "Isotropic (no uphill / downhill difference)",
              default=False, advanced=True),
    Parameter("isochrones", "numbers", "The isochrones, minutes.", "Isochrones (minutes)", default=(30, 60, 120,
              240), minimum=0.0, example="30,60,120,240"),
    Parameter("max_memory", "float", "The most memory the travel time may take, in GB: the whole grid's graph when it "
              "fits (about 0.6 KB a cell at 16 neighbours), else the graph block by block beside the cell arrays "
              "(about 80 bytes a cell), to the same minutes; a DEM whose cell arrays pass it is refused before "
              "anything is written.", "Memory limit, GB (beyond the whole graph: block by block)",
              default=4.0, minimum=0.01, advanced=True, example="4"),
)

TRAVEL = command("travel", "dem", "last_seen", "shrub_classes", "roads", "hydro", "waterbodies", "road_speed",
                 "wade_speed", "isochrones", "tobler", "shrub_factors", "neighbours", "isotropic", "max_memory", "snap",
                 "max_road_width", "max_hydro_width", "single_line_width", "reproject_vectors", "overwrite",
    library="products.travel:travel_from_dem", settings="products.travel:TravelSettings", cli="travel:travel")
