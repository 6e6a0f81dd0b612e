"""Parameters of gistools fuels (canopy fuels and the FlamMap landscape) and the QGIS algorithm gistools:fuels.

The cell size and the buffer are the shared ones (``rasters``: the command's own defaults below), the tiles' CRS
and the run's in ``common``, the height bands and their floor in ``lidar`` and the class breaks in ``shrub``.
Every constant of the method is one of these parameters (docs/commands/fuels.md cites each one's source).
"""

from .common import AREA
from .core import COMMAND_DEFAULTS, ByUnits, Parameter, command, declare, option
from . import common, lidar, rasters, shrub  # noqa: F401  (declared there)

PROFILES = {"ratio": "Returns over path length, bias-corrected (Pimont et al. 2018)",
            "macarthur-horn": "ln(N_in / N_out) of first returns (MacArthur-Horn)"}

declare(
    Parameter("canopy_floor", "length", "Returns higher than this above the ground are canopy: canopy cover is the "
              "share of first returns above it, and the canopy bulk density profile starts at it (LANDFIRE, FVS: 2 m).",
              "Canopy starts at this height above ground", default="2m", minimum=0.0, example="2m", advanced=True),
    Parameter("height_percentile", "float", "Canopy height: this percentile of the heights of the canopy returns "
              "(100: the highest, as LANDFIRE's canopy height of the tallest trees).", "Canopy height percentile",
              default=100.0, minimum=50.0, maximum=100.0, example="99", advanced=True),
    Parameter("layer", "length", "Thickness of the layers of the vertical profile (FVS uses 1 ft, LidarForFuel 1 m).",
              "Profile layer thickness", default="1m", example="1m", advanced=True),  # no minimum: positive
    Parameter("extinction", "float", "Extinction coefficient k of the Beer-Lambert (MacArthur-Horn) profile: "
              "LAD = ln(N_in / N_out) / (k dz); 0.5 is a spherical leaf-angle distribution seen from above.",
              "Extinction coefficient k", default=0.5, minimum=0.0, example="0.5", advanced=True),
    Parameter("leaf_mass_area", "float", "Leaf mass per leaf area (kg/m2) that turns leaf area density (m2/m3) into "
              "bulk density (kg/m3); 0.141 is LidarForFuel's average LMA (141 g/m2).",
              "Leaf mass per area (kg/m2)", default=0.141, minimum=0.0, example="0.141", advanced=True),
    Parameter("running_mean", "length", "The bulk density profile is smoothed by a centred running mean this deep "
              "before the canopy base and the canopy bulk density are read (FVS: 15 ft).",
              "Running mean over", default="3m", minimum=0.0, example="3m", advanced=True),
    Parameter("cbh_threshold", "float", "Canopy base height: the lowest layer whose running-mean bulk density exceeds "
              "this (kg/m3; FVS 0.011, LANDFIRE and LidarForFuel 0.012).", "Canopy base threshold (kg/m3)",
              default=0.012, minimum=0.0, example="0.012", advanced=True),
    Parameter("column", "length", "The profile is computed in columns of the cell (voxels of a column by a layer), "
              "then averaged over the cell, so that gaps between crowns do not dilute the crowns' density; wider "
              "columns mix crown and gap and read the crowns too thin, narrower ones get too few pulses. The cell is "
              "split into equal square columns about this wide (0: one profile per cell).", "Profile column width",
              default_text=f"columns that get {option('column_pulses')} pulses each (1 m at 20 pulses per m2)",
              minimum=0.0, example="1m", advanced=True),
    Parameter("column_pulses", "int", f"Without {option('column')}, each cell is split into the square columns that "
              "get this many pulses (first returns) on average, so that a layer only some of them reach keeps the few "
              "pulses the bias-corrected estimator needs (Pimont et al. 2018: five or more).",
              "Pulses per profile column", default=20, minimum=1, example="20", advanced=True),
    Parameter("profile", "choice", "The leaf area density estimator of each layer: ratio, every return in the layer "
              "over k times the pulses' path through it down to their last return, bias-corrected (Pimont et al. "
              "2018); macarthur-horn, ln(N_in / N_out) / (k dz) of the first returns (MacArthur and Horn 1969).",
              "Leaf area density estimator", default="ratio", choices=PROFILES, advanced=True),
    Parameter("fuel_raster", "raster", "A fuel-model raster (Scott and Burgan 40 codes, e.g. LANDFIRE FBFM40), "
              f"sampled at the cell centres; without it the codes of {option('fuel_codes')} follow the shrub class.",
              "Fuel-model raster (FBFM40 codes)", metavar="RASTER"),
    Parameter("fuel_codes", "numbers", "Scott and Burgan fuel-model codes for light, medium and heavy shrub (the class "
              f"of the share of returns between {option('noise_floor')} and 2 m by {option('class_breaks')}); the "
              "same code three times is a constant fuel model.", "Fuel models for light / medium / heavy shrub",
              default=(121, 142, 145), count=3, minimum=0.0, maximum=32767.0, example="121,142,145"),
    Parameter("latitude", "float", "The landscape's latitude for the .lcp header (degrees).",
              "Latitude for the .lcp", default_text="the centre of the tiles, from their CRS", minimum=-90.0,
              maximum=90.0, advanced=True, example="44.1"),
)

FUELS = command("fuels", "cell_size", "canopy_floor", "height_percentile", "layer", "extinction", "leaf_mass_area",
                "running_mean", "cbh_threshold", "column", "column_pulses", "profile", "bands", "noise_floor",
                "class_breaks", "fuel_raster", "fuel_codes", "latitude", "buffer", "crs", "jobs", "overwrite",
                "scheduler", *AREA,
    library="products.fuels:fuels_from_tiles", settings="products.fuels:FuelsSettings", cli="fuels:fuels", command_line=AREA)

# LANDFIRE's 30 m lattice; 100 ft on data in feet (30.48 m) reads naturally there
COMMAND_DEFAULTS.update({"fuels": {"cell_size": ByUnits("100ft", "30m", "LANDFIRE's 30 m cells"), "buffer": "30m"}})
