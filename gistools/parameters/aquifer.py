"""Parameters of the aquifer model (gistools aquifer model / query, AquiferSettings, aquifer_query)."""

from .core import Parameter, command, declare, option  # noqa: F401

ORDERS = {"stratigraphic": "Stratigraphic: thickness from the boreholes (isopach), never below 0",
          "raw": "Raw: the two TINs as they are (thickness can go negative)"}
MATCHINGS = {"3d": "3D distance (the dissertation's)", "2d": "Plan (2D) distance"}
MESH_FORMATS = {"ply": "PLY", "obj": "OBJ (Wavefront)"}
HEIGHT_METHODS = {"tin": "TIN of each surface (nothing outside its boundary)", "knn": "Mean of the k nearest contacts",
                  "idw": "Inverse-distance weighted contacts"}

declare(
    Parameter("layers", "text", "Layer names top to bottom, e.g. LS,AU,AD,AQ.",
              "Layer names, top to bottom (comma-separated)", required=True, example="LS,AU,AD,AQ"),
    Parameter("swap_xy", "flag", "Swap x and y (the dissertation labels East as North).", "Swap x and y", default=False,
              advanced=True),
    Parameter("within", "layer", "Polygon layer: volumes and thickness statistics inside it.",
              "Volumes inside this polygon (default: common footprint)", geometry="polygon",
              default_text="each unit's common footprint"),
    Parameter("clip", "layer", "Polygon layer the surfaces are cut to (concave outline, holes).",
              "Cut the surfaces to this polygon", geometry="polygon", advanced=True),
    Parameter("concave_ratio", "float", "Cut each surface to the concave hull of its points (shapely ratio 0-1).",
              "Cut each surface to the concave hull of its points (ratio 0-1)", flag="--concave", minimum=0.0,
              maximum=1.0, default_text="the convex hull (the dissertation's)", advanced=True, example="0.3"),
    Parameter("xy_tol", "length", "Duplicates: same position within this.", "Duplicates: same position within",
              default="0.5m", minimum=0.0, advanced=True, example="0.5m"),
    Parameter("k", "int", "Neighbours: of the outlier plane fit (aquifer model, at least 3), of the knn / idw height "
              "(aquifer query).", "Neighbours", minimum=1, advanced=True,
              default_text="12 for the model's outlier fit, 10 for a query", example="12"),
    Parameter("abs_thr", "length", "Outliers: smallest residual threshold.", "Outliers: smallest residual threshold",
              default="8m", advanced=True, example="8m"),
    Parameter("c", "float", f"Outliers: threshold = max({option('abs_thr')}, c x 1.4826 MAD).",
              "Outliers: MAD factor of the threshold", default=5.0, advanced=True, example="5"),
    Parameter("f_nn", "float", "Outside the cloud: a point whose nearest-neighbour distance is over this factor x "
              "the median.",
              "Outside the cloud: nearest-neighbour distance over this x the median", default=5.0, advanced=True,
              example="5"),
    Parameter("order_tol", "length", "Report points beyond a neighbour layer by more than this.",
              "Report points beyond a neighbour layer by more than", default="1m", minimum=0.0, advanced=True,
              example="1m"),
    Parameter("n_per_edge", "int", "Densified points per TIN edge.", "Densified points per TIN edge", default=2,
              minimum=0, advanced=True, example="2"),
    Parameter("densify", "flag", "Write the densified points (densified_<layer>.csv).",
              "Write the densified points (densified_<layer>.csv)", default=False, advanced=True),
    # AquiferSettings.cell_size; "cell_size" is the rasters' (a default of 5ft): messages name it cell_size all the same
    Parameter("thickness_cell_size", "length", "Thickness raster cell.", "Thickness raster cell size",
              flag="--cell-size", qgis="CELL_SIZE", default_text="about 500 cells across", advanced=True,
              example="10m", keyword="cell_size"),
    Parameter("matching", "choice", "How the boundaries of two neighbouring layers are matched into walls: by 3D or "
              "plan distance.", "Wall matching", default="3d", choices=MATCHINGS, advanced=True),
    Parameter("mesh_format", "choice", "Format of the unit meshes.", "Mesh format", default="ply", flag="--mesh",
              qgis="MESH", choices=MESH_FORMATS, advanced=True),
    # AquiferSettings.figures, negated: the figures are drawn unless this is given
    Parameter("no_figures", "flag", "Skip the PNG figures.", "Skip the PNG figures", default=False, advanced=True,
              keyword="figures"),  # AquiferSettings(figures=False)
    Parameter("order", "choice", "stratigraphic: a lower surface is never above the one above it (a unit that "
              "pinches out has thickness 0, not negative); raw: the TINs as they are. The crossing's area and volume "
              "are reported either way.", "Where the TINs of a unit's top and base cross", default="stratigraphic",
              choices=ORDERS, advanced=True),
    Parameter("fields", "fields", "Columns of some fields where the table names them otherwise: field=column pairs "
              "(aquifer: id, x, y, z, layer, borehole_id; runway: id, type, x, y, z).", "Columns of the fields",
              metavar="FIELD=COLUMN,...", example="z=ELEV,layer=FORMATION", advanced=True),
    Parameter("x", "float", "x of the point (the model's CRS).", "x (model CRS)", required=True, example="1517365"),
    Parameter("y", "float", "y of the point (the model's CRS).", "y (model CRS)", required=True, example="5031638"),
    # aquifer_query's method; "method" is the ground / CHM methods' word
    Parameter("height_method", "choice", "tin: the TIN of each surface (nothing outside its boundary); knn: mean of "
              f"the {option('k')} nearest contacts; idw: their inverse-distance weighted mean.", "Method",
              default="tin", flag="--method", qgis="METHOD", choices=HEIGHT_METHODS, keyword="method"),
)

AQUIFER_MODEL = command("aquifer model", "layers", "crs", "swap_xy", "within", "clip", "concave_ratio", "xy_tol", "k",
                        "abs_thr", "c", "f_nn", "order_tol", "n_per_edge", "densify", "thickness_cell_size",
                        "matching", "mesh_format", "no_figures", "order", "fields", "overwrite",
    library="products.aquifer:aquifer_model", settings="products.aquifer:AquiferSettings", cli="aquifer:aquifer")
AQUIFER_QUERY = command("aquifer query", "x", "y", "height_method", "k",
    library="products.aquifer:aquifer_query", cli="aquifer:aquifer")
