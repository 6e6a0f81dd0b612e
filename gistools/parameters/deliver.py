"""Parameters of the field deliverables made from a shrub chain's output folder: gistools webmap (web_map), scene
(scene_glb) and mapbook (map_book)."""

from .core import Parameter, command, declare, option  # noqa: F401

SURFACES = {"dsm": "DSM (the DEM where it has no value)", "dem": "DEM (bare ground)"}
PAPERS = {"letter": "Letter", "a4": "A4", "tabloid": "Tabloid"}

declare(
    # web map (also gistools shrub --web-map)
    Parameter("basemap", "text", "An XYZ tile URL under the polygons, for users who are online (the page then needs "
              "the network for the basemap; the polygons still work without).",
              "Basemap tile URL for users who are online (empty: none)", metavar="URL",
              default_text="none; the page then makes no request to any network address",
              example="https://tile.openstreetmap.org/{z}/{x}/{y}.png"),
    Parameter("split_mb", "float", "Above this many megabytes of polygons the map is split by tile into parts (and an "
              "index page).", "Split the map by tile above (MB of polygons)", default=40.0, minimum=0.001,
              advanced=True, example="40"),
    # search-and-rescue and fire layers of the web map and the map book
    Parameter("travel", "folder", "The output folder of gistools travel: the isochrones (a legend in minutes) and the "
              "points last seen drawn on the map; the web map also shows the travel time under the cursor.",
              "Travel time folder (gistools travel; empty: none)", metavar="DIR", default_text="none",
              example="travel"),
    Parameter("viewshed", "folder", "The output folder of gistools viewshed: the cells seen drawn as a semi-transparent "
              "layer of the web map and on the map book's pages.", "Viewshed folder (gistools viewshed; empty: none)", metavar="DIR",
              default_text="none", example="viewshed"),
    Parameter("fuels", "folder", "The output folder of gistools fuels: its canopy base height classes as a layer of "
              "the web map, and a page of the map book.", "Fuels folder (gistools fuels; empty: none)", metavar="DIR",
              default_text="none", example="fuels"),
    Parameter("plan", "folder", "The output folder of gistools search-plan: its segments (their POA and POD under "
              "the cursor) and routes drawn on the web map; in the map book, a page per segment searchers are "
              "assigned to (hours in its effort), else per segment by rank.",
              "Search plan folder (gistools search-plan; empty: none)", metavar="DIR", default_text="none",
              example="plan"),
    # 3D scene
    Parameter("exaggeration", "float", "Heights times this.", "Vertical exaggeration", default=1.0, minimum=0.01,
              example="2"),
    Parameter("max_mb", "float", "The .glb stays under this size: the grid is decimated (every k-th cell) to fit.",
              "Largest file (MB): the mesh is decimated to fit", default=50.0, minimum=0.01, advanced=True,
              example="50"),
    Parameter("surface", "choice", "dsm: the DSM (the DEM where it has no value); dem: the bare ground.", "Surface",
              default="dsm", choices=SURFACES),
    # map book
    Parameter("tile_index", "layer", "Tile footprints (file.gpkg:LAYER, e.g. FOOTPRINT), a polygon per tile named by "
              f"{option('tile_field')}: the shrub chain splits the breaklines by them, as the dissertation did; the map "
              "book makes a page per footprint (without them, a grid of sheets at its scale).", "Tile index (footprints)", geometry="polygon",
              metavar="LAYER"),
    Parameter("tile_field", "text", f"The field of {option('tile_index')} naming the tile.",
              "Tile index field naming the tile", default="TILE_ID", advanced=True, example="TILE_ID"),
    Parameter("scale", "float", "The n of 1:n, for the grid of sheets.", "Scale of the grid of sheets (the n of 1:n)",
              default=10000.0, minimum=1.0, example="10000"),
    Parameter("paper", "choice", "Paper (landscape).", "Paper (landscape)", default="letter", choices=PAPERS,
              advanced=True),
    Parameter("max_pages", "int", "Refuse a map book of more pages than this.", "Largest number of pages",
              default=1000, minimum=1, advanced=True, example="1000"),
)

WEBMAP = command("webmap", "travel", "viewshed", "fuels", "plan", "basemap", "split_mb",
    library="deliver.webmap:web_map", cli="deliver:webmap")
SCENE = command("scene", "exaggeration", "max_mb", "surface",
    library="deliver.scene:scene_glb", cli="deliver:scene")
MAPBOOK = command("mapbook", "tile_index", "tile_field", "travel", "viewshed", "fuels", "plan", "scale", "paper", "max_pages",
    library="deliver.mapbook:map_book", cli="deliver:mapbook")
