"""Parameters every batch command takes: the tiles' CRS, the run (jobs, scheduler, chunk size), resume."""

from .core import ByUnits, Parameter, declare

declare(
    Parameter("out", "folder", "Output folder.", "Output folder", flag="--out", short="-o", qgis="OUTPUT_FOLDER",
              required=True),
    Parameter("crs", "crs", "CRS of the input (EPSG:2882, WKT): needed where the data carry none (a LAS header, a CSV); "
              "it replaces the data's own CRS otherwise.", "Input CRS (overrides the data's own; needed where they carry none)",
              advanced=True),
    Parameter("jobs", "int", "Tiles processed in parallel. auto: on threads of this process (one a CPU) until the "
              "tiles hold enough points to repay starting worker processes (about 5 million a worker), then as many "
              "workers as that work, the tiles, the CPUs and the memory allow; a number: that many worker processes "
              "(1: one tile at a time in this process), capped by the tiles, the CPUs and the memory.", "Tiles in parallel (local processes; 0: auto)", default="auto", minimum=1,
              short="-j", advanced=True, words=("auto",), metavar="auto|N"),
    Parameter("scheduler", "text", "Run the tiles on a Dask cluster: its scheduler address (tcp://host:8786), or "
              "'local' for a LocalCluster of as many workers as jobs. Workers must see the tiles and the output "
              "folder at the same paths.", "Dask scheduler address (tcp://host:8786), or 'local'", metavar="ADDRESS",
              advanced=True),
    Parameter("chunk_size", "int", "Points read at a time; memory grows with it (about 60 bytes per point).",
              "Points read at a time", default=2_000_000, minimum=1, advanced=True),
    Parameter("overwrite", "flag", "Replace existing outputs (default: keep complete outputs of an earlier or killed "
              "run and do the rest).", "Replace existing outputs", default=False),
)

# --- points of an area: a service (EPT, COPC over HTTP), or local data clipped to the area ---------------------------
declare(
    Parameter("aoi", "area", "The area of interest: minx,miny,maxx,maxy in the data's CRS (or with ,EPSG:code after "
              "it), or a polygon layer (file.gpkg, file.gpkg|layername=NAME). Only the points in it (and a margin "
              "around it) are read, as tiles on an absolute lattice; a service (a URL of an EPT dataset's ept.json "
              "or of a COPC file) needs one.", "Area of interest (read only the points in it)", metavar="AREA",
              example="515380,4918350,515400,4918370"),
    Parameter("resolution", "length", "Read a point cloud service's octree only to the depth whose point spacing is "
              "at least this fine (as PDAL's resolution).", "Point spacing to read down to (services)",
              default_text="every point", advanced=True, example="1m", minimum=0.0),
    Parameter("tile_size", "length", "The side of the tiles an area is cut into (on the lattice of its multiples).",
              "Tile side for an area", default=ByUnits("1500ft", "500m"), advanced=True, example="500m", minimum=0.0),
    Parameter("cache", "folder", "Where the points of an area are kept once fetched: a rerun, or another product of "
              "the same area, fetches nothing.", "Cache of fetched points", default_text="OUT/fetched",
              metavar="FOLDER", advanced=True),
    Parameter("max_download", "text", "Refuse an area of a service that holds more than this (500MB, 2GB), before any "
              "point is fetched.", "Largest download (e.g. 2GB)", default_text="no limit", metavar="SIZE",
              advanced=True, example="2GB"),
)
AREA = ("aoi", "resolution", "tile_size", "cache", "max_download")  # what a command taking tiles takes of an area
