"""Parameters of the LiDAR commands: ground, normalize, metrics, chm, points and info (declared once:
gistools.parameters.core). The tiles' CRS, the run (jobs, scheduler, chunk size), the cell size and the buffer are
the shared ones (``common``, ``rasters``); a command whose default differs passes its own (``defaults=``).

The library's choice constants are these: ``lidar.ground.GROUND_METHODS`` (rasters' GROUND_METHODS),
``lidar.noise.NOISE_METHODS``, ``products.ground.FORMATS``, ``products.points.RETURNS`` and ``products.metrics.RETURNS``,
``lidar.chm.CHM_METHODS`` and ``lidar.bands.PRESETS`` (the same words in the same order).
"""

import warnings

from .common import AREA
from .core import COMMAND_DEFAULTS, DEFAULT_TEXTS, PARAMETERS, Parameter, command, declare, option, render
from .rasters import GROUND_METHODS

NOISE_METHODS = {"ivf": "Isolated points in voxels (IVF)", "sor": "Statistical outliers (SOR)", "none": "None"}
POINT_FORMATS = {"laz": "LAZ (compressed LAS)", "las": "LAS", "copc": "COPC (cloud-optimised LAZ)"}
LAYER_FORMATS = {"gpkg": "GeoPackage", "parquet": "GeoParquet"}
# one vocabulary for the returns of gistools points and gistools metrics; "any" was points' word for "all"
RETURNS = {"first": "First returns", "last": "Last returns", "all": "Every return"}
CHM_METHODS = {"p2r": "Highest first return per cell (p2r)", "pitfree": "Pit-free (Khosravipour et al. 2014)",
               "tin": "TIN of the first returns"}
BAND_PRESETS = {"exact": "Exact metres: 1 / 2 / 6 m",
                "text_literal": "As printed in the dissertation: 3.28 / 6.56 / 19.658 ft"}
# the metrics the dialog offers as a checklist (gistools metrics takes any name lidar.metrics parses)
COMMON_METRICS = ("count", "density", "z_min", "z_max", "z_mean", "z_median", "z_sd", "z_cv", "z_p25", "z_p50", "z_p75",
                  "z_p95", "i_mean", "i_max", "hag_p95", "cover_above2m", "fhd", "vci", "fuel_0_1m", "fuel_1_3m",
                  "fuel_3_6m")
DEFAULT_METRICS = ("count", "density", "z_min", "z_max", "z_mean", "z_sd", "z_p95")

# --- gistools ground: noise, then SMRF (Pingel et al. 2013; PDAL's names) or CSF (lidR csf()) -------------------
declare(
    Parameter("ground_method", "choice", "adaptive: smrftin whose thresholds follow what the survey is: where "
              "pulses record one return (open ground, ISPRS-era scans), from its measured ground noise; where at "
              "least 10 % of the points come from pulses that returned more than once (a canopy), a tight set on "
              "1.75 m cells (smaller on dense surveys) that keeps low vegetation out; the best on the ISPRS filter "
              "test and on the real forest surveys. smrf: Simple Morphological Filter (Pingel et al. 2013), the "
              "fastest; csf: Cloth Simulation Filter (needs cloth-simulation-filter); smrftin: SMRF on a 1.5 m "
              "lattice, one step of TIN densification, raised patches (roofs, decks) removed, thresholds from the "
              "survey's measured ground noise.", "Ground filter", default="adaptive",
              choices=GROUND_METHODS,
              flag="--method", qgis="METHOD", keyword="method"),
    Parameter("noise", "choice", "Noise first: ivf (isolated points in voxels, lasR classify_with_ivf), sor "
              "(statistical outliers) or none.", "Noise filter", default="ivf", choices=NOISE_METHODS),
    Parameter("cell", "length", "SMRF cell size.", "SMRF cell size", default="1m", advanced=True, example="1m",
              read_by="smrf"),
    Parameter("slope", "float", "SMRF slope (rise over run).", "SMRF slope (rise over run)", default=0.1, minimum=0.0,
              advanced=True, example="0.1", read_by="smrf"),
    Parameter("window", "length", "SMRF largest window radius.", "SMRF largest window radius", default="18m",
              advanced=True, example="18m", read_by="smrf"),
    Parameter("threshold", "length", "SMRF elevation threshold: a point within threshold + scalar x local slope of the "
              "ground surface is ground.", "SMRF elevation threshold", default="0.15m", advanced=True, example="0.15m",
              read_by="smrf"),
    Parameter("scalar", "length", "SMRF elevation scalar: threshold added per unit of slope.",
              "SMRF elevation scalar (threshold per unit of slope)", default="0.5m", minimum=0.0, advanced=True,
              example="0.5m", read_by="smrf"),
    Parameter("smrftin_cell", "length", "smrftin: SMRF cell size.", "SMRF+TIN cell size", default="1.5m", advanced=True,
              example="1.5m", read_by="smrftin"),
    Parameter("smrftin_slope", "float", "smrftin: SMRF slope (rise over run).", "SMRF+TIN slope (rise over run)",
              default=0.15, minimum=0.0, advanced=True, example="0.15", read_by="smrftin"),
    Parameter("smrftin_window", "length", "smrftin: largest window radius.", "SMRF+TIN largest window radius",
              default="24m", advanced=True, example="24m", read_by="smrftin"),
    Parameter("smrftin_threshold", "length", "smrftin: a point within threshold + scalar x local slope of the ground "
              "surface (then of the TIN of the ground found) is ground.", "SMRF+TIN elevation threshold",
              default="0.4m", advanced=True, example="0.4m", read_by="smrftin"),
    Parameter("smrftin_scalar", "length", "smrftin: threshold added per unit of slope.",
              "SMRF+TIN elevation scalar (threshold per unit of slope)", default="1m", minimum=0.0, advanced=True,
              example="1m", read_by="smrftin"),
    Parameter("smrftin_step", "length", "smrftin: ground cells whose heights differ by more than this per cell are "
              "parted (walls); a patch of ground standing above all around it and narrower than "
              f"{option('smrftin_patch')} is an object (roofs, decks).", "SMRF+TIN height step that parts patches",
              default="1m", minimum=0.0, advanced=True, example="1m", read_by="smrftin"),
    Parameter("smrftin_patch", "length", "smrftin: raised ground patches narrower than this are objects (0: keep "
              "them).", "SMRF+TIN widest raised patch removed", default="60m", minimum=0.0, advanced=True,
              example="60m", read_by="smrftin"),
    Parameter("csf_resolution", "length", "CSF cloth resolution.", "CSF cloth resolution", default="0.5m",
              advanced=True, example="0.5m", read_by="csf"),
    Parameter("csf_threshold", "length", "CSF class threshold.", "CSF class threshold", default="0.5m", advanced=True,
              example="0.5m", read_by="csf"),
    Parameter("csf_rigidness", "int", "CSF rigidness: 1 for steep terrain, 3 for flat.", "CSF rigidness (1-3)",
              default=1, minimum=1, maximum=3, advanced=True, read_by="csf"),
    Parameter("csf_iterations", "int", "CSF iterations.", "CSF iterations", default=500, minimum=1, advanced=True,
              read_by="csf"),
    Parameter("csf_time_step", "float", "CSF time step.", "CSF time step", default=0.65, minimum=0.0, advanced=True,
              read_by="csf"),
    Parameter("csf_slope_smooth", "flag", "CSF post-processing of steep slopes.", "CSF: smooth steep slopes",
              default=False, advanced=True, read_by="csf"),
    Parameter("ivf_res", "length", "IVF voxel size.", "IVF voxel size", default="5m", advanced=True, example="5m"),
    Parameter("ivf_n", "int", "IVF: a point with at most this many other points in its 27 voxels is noise.",
              "IVF: noise with at most this many other points in 27 voxels", default=6, minimum=0, advanced=True),
    Parameter("sor_k", "int", "SOR: the neighbours of each point whose mean distance is measured.",
              "SOR: neighbours per point", default=8, minimum=1, advanced=True),
    Parameter("sor_multiplier", "float", "SOR: a point whose mean distance to its neighbours exceeds the mean by this "
              "many standard deviations is noise.", "SOR: standard deviations", default=2.0, minimum=0.0,
              advanced=True),
    Parameter("low_noise_depth", "length", "Points this far below the ground surface are low noise (7), even in "
              "clusters.", "Points this far below the ground are low noise", default="1m", advanced=True,
              example="1m"),
    Parameter("keep_classes", "flag", "Points that were ground or noise and are not now keep their class (else 1).",
              "Points no longer ground or noise keep their class (else 1)", default=False, advanced=True),
    Parameter("format", "choice", "Output format: laz, las, or copc (needs copclib; COPC holds point formats 6-8, so "
              "formats 0-5 are converted).", "Output format", default="laz", choices=POINT_FORMATS, advanced=True),
)

# --- gistools normalize ---------------------------------------------------------------------------------------
declare(
    Parameter("replace_z", "flag", "Write the heights above ground as z (no extra dimension).",
              "Write the heights as z (no extra dimension)", default=False),
    Parameter("classify_vegetation", "flag", "Unclassified points (0, 1) become low / medium / high vegetation "
              "(3 / 4 / 5) by the height bands; with breaklines, surface points in roads road surface (11), in water "
              "water (9).", "Classify vegetation 3 / 4 / 5 by height (and roads 11, water 9)", default=False),
    Parameter("bands", "choice", "The limits of the height bands B1 (low shrub), B2 (medium) and B3 (tall): exact "
              "1 / 2 / 6 m, or the dissertation's printed 3.28 / 6.56 / 19.658 ft.", "Height band limits",
              default="exact", choices=BAND_PRESETS, advanced=True, qgis="PRESET"),
    Parameter("noise_floor", "length", "Heights above ground up to this are bare ground (band B0), not vegetation.",
              "Heights up to this are bare ground", default="0.1m", minimum=0.0, advanced=True, example="0.1m"),
    Parameter("roads", "layer", "Edge-of-pavement lines (file.gpkg:LAYER, file.gpkg|layername=LAYER, or a shapefile).",
              "Road breaklines (edge of pavement)", geometry="line", metavar="LAYER"),
    Parameter("hydro", "layer", "Hydrographic breaklines: dual-line banks and single-line features.",
              "Hydrographic breaklines", geometry="line", metavar="LAYER"),
    Parameter("waterbodies", "layer", "Water body polygons (islands as holes).", "Water body polygons",
              geometry="polygon", metavar="LAYER"),
    Parameter("reproject_vectors", "flag", "Reproject vector layers to the points' CRS instead of refusing.",
              "Reproject layers in another CRS (else refuse)", default=False, qgis="REPROJECT", advanced=True),
)

# --- gistools metrics and gistools points ---------------------------------------------------------------------
declare(
    Parameter("metrics", "choices", "Comma-separated names: count, density; z_ / i_ / hag_ + min, max, mean, median, "
              "sum, sd, cv, pNN, aboveX; cover_aboveX; fhd; vci; fuel_A_B (the documentation's metrics page). Any such name is "
              "taken; the choices are the dialog's checklist.", "Metrics", choices={m: m for m in COMMON_METRICS},
              default=DEFAULT_METRICS, example="count,z_max,z_p95"),
    Parameter("more_metrics", "text", f"More metric names, comma-separated, added to {option('metrics')} (in QGIS, "
              "those not in the checklist).", "More metrics (comma-separated names, e.g. z_p99,hag_above6ft,"
              "cover_above5m)", example="z_p99,hag_above6ft"),
    Parameter("normalized", "flag", "Compute the z_* metrics on heights above ground (named hag_*).",
              "z metrics on heights above ground (hag_*)", default=False),
    Parameter("classes", "classes", "ASPRS classes of the points used, e.g. 1,2,3,4,5.", "ASPRS classes",
              default_text="every class but noise (7, 18)", example="1,2"),
    Parameter("returns", "choice", "Which returns: first, last or all.", "Returns", default="all", choices=RETURNS,
              aliases={"any": "all"}),
    Parameter("fmt", "choice", "GeoPackage, or GeoParquet (needs pyarrow) for tiles of millions of points.", "Format",
              default="gpkg", choices=LAYER_FORMATS, flag="--format", qgis="FORMAT", advanced=True),
)

# --- gistools chm ---------------------------------------------------------------------------------------------
declare(
    Parameter("chm_method", "choice", "p2r: the highest first return of each cell; pitfree: Khosravipour et al. 2014 "
              "(lidR pitfree()); tin: a TIN of the first returns.", "Method", default="pitfree", choices=CHM_METHODS,
              flag="--method", qgis="METHOD", keyword="method"),
    Parameter("thresholds", "text", f"pitfree: the height thresholds of the layers, comma-separated lengths (then one "
              f"every {option('threshold_step')}).", "Pit-free height thresholds (comma-separated, with unit)",
              default="0m,2m", advanced=True, example="0m,2m,5m,10m,15m"),
    Parameter("threshold_step", "length", "pitfree: a threshold every this above the last given, up to the highest "
              f"return (0: none; lidR's pitfree() is {option('thresholds', '0m,2m,5m,10m,15m')} "
              f"{option('threshold_step', '0')} {option('max_edge', '0,1m')}).",
              "Pit-free: a threshold every (0: only those given)", default="2m", minimum=0.0, advanced=True,
              example="2m"),
    Parameter("max_edge", "text", "pitfree: the longest triangle edge of the first layer, then of the upper layers "
              "(0: no limit; auto: 4 times the nominal spacing of the tiles' first returns).",
              "Pit-free longest triangle edge: first layer, upper layers (0: no limit; auto: from the returns' "
              "spacing)", default="0,auto", advanced=True, example="0,1m"),
    Parameter("tin_max_edge", "length", "tin: the longest triangle edge (0: no limit).",
              "TIN longest triangle edge (0: no limit)", default="0", minimum=0.0, advanced=True, example="0"),
)

GROUND = command("ground", "ground_method", "noise", "cell", "slope", "window", "threshold", "scalar", "smrftin_cell",
                 "smrftin_slope", "smrftin_window", "smrftin_threshold", "smrftin_scalar", "smrftin_step", "smrftin_patch", "csf_resolution",
                 "csf_threshold", "csf_rigidness", "csf_iterations", "csf_time_step", "csf_slope_smooth", "ivf_res",
                 "ivf_n", "sor_k", "sor_multiplier", "low_noise_depth", "buffer", "keep_classes", "format", "crs", "jobs",
                 "overwrite", "scheduler", *AREA,
    library="products.ground:ground_from_tiles", settings="products.ground:GroundSettings", cli="ground:ground", command_line=AREA)
NORMALIZE = command("normalize", "replace_z", "classify_vegetation", "bands", "noise_floor", "roads", "hydro",
                    "waterbodies", "reproject_vectors", "buffer", "format", "crs", "jobs", "overwrite", "scheduler", *AREA,
    library="products.normalize:normalize_from_tiles", settings="products.normalize:NormalizeSettings",
    cli="normalize:normalize", command_line=AREA)
METRICS = command("metrics", "cell_size", "metrics", "more_metrics", "normalized", "classes", "returns", "buffer", "crs",
                  "jobs", "overwrite", "scheduler", *AREA,
    library="products.metrics:metrics_from_tiles", settings="products.metrics:MetricsSettings", command_line=('more_metrics', *AREA),
    cli="metrics:metrics")
CHM = command("chm", "chm_method", "cell_size", "thresholds", "threshold_step", "max_edge", "tin_max_edge", "buffer",
              "crs", "jobs", "overwrite", "scheduler", *AREA,
    library="products.chm:chm_from_tiles", settings="products.chm:ChmSettings", cli="chm:chm", command_line=AREA)
POINTS = command("points", "classes", "returns", "fmt", "crs", "chunk_size", "overwrite", *AREA,
    library="products.points:points_from_tiles", cli="points:points", command_line=AREA)
INFO = command("info", "crs",
    library="products.info:tiles_summary", cli="info:info")

# the commands' own defaults of shared parameters (spec_options / add_spec ``defaults=``)
BUFFER_30M = {"buffer": "30m"}  # normalize, metrics, chm: lidR's chunk buffer
COMMAND_DEFAULTS.update({"ground": {}, "normalize": BUFFER_30M, "metrics": {"cell_size": "5m", **BUFFER_30M},
                         "chm": {"cell_size": "0.5m", **BUFFER_30M}, "points": {"classes": (1, 2)}, "info": {}})
# what the shared parameters' help says of their default, where a command's own default is computed
DEFAULT_TEXTS.update({"ground": {"buffer": f"2 x {option('window')} + 10 cells (smrftin and adaptive: 2 x "
                                            f"{option('smrftin_window')} + 2 x {option('smrftin_patch')} + 13 cells, "
                                            "of adaptive's larger cell under a canopy)"}})


def current_word(name: str, value):
    """``value`` of choice parameter ``name``, an old word (``aliases``) replaced by the current one with a
    DeprecationWarning naming both, as the command line's deprecation line does."""
    aliases = PARAMETERS[name].aliases
    if isinstance(value, str) and value in aliases:
        new = aliases[value]
        warnings.warn(render(f"{option(name, value)} is an old word for {new!r}; it still works, write "
                             f"{option(name, new)}"), DeprecationWarning, stacklevel=3)
        return new
    return value


def check_method(name: str, value) -> None:
    """A settings object's ``method`` against declaration ``name`` (ground_method, chm_method). The flag --method
    means a different choice in each command, so each has its own declaration (the register is global); the field
    a Python caller sets is ``method`` in both, and the message names it so (``--method`` on the command line, the
    dialog's label in QGIS)."""
    from ..errors import InputError

    p = PARAMETERS[name]
    if value not in p.choices:
        raise InputError(f"{option('method')} {value!r} is not one of {', '.join(p.choices)}",
                         hint=f"Use {option('method', p.default)}")
