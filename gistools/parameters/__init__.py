"""One declaration of each parameter (``core``), grouped by the part of gistools that takes it: ``common`` (the
tiles, the run), ``rasters`` (DSM, DEM, nDSM), and so on. The command line, the QGIS algorithms, the settings'
checks and the documentation's option tables are made from these."""

from .core import (COMMAND_LINE, COMMANDS, DECLARED, ENV, KINDS, LIBRARY, PARAMETERS, ByUnits, Parameter, by_units, command, declare, flag_of, option,
                   render, speaking, speaks)
from . import common, rasters, lidar, shrub, deliver, aquifer, runway, structure, terrain, travel, fuels, search  # noqa: F401,E402  (the declarations)
from .check import check, check_all, choices, default_for, in_data_units, setting_default  # noqa: E402

__all__ = ["COMMAND_LINE", "COMMANDS", "DECLARED", "ENV", "KINDS", "LIBRARY", "PARAMETERS", "ByUnits", "Parameter", "by_units", "command", "declare", "flag_of",
           "option", "render", "speaking", "speaks", "check", "check_all", "choices", "default_for", "in_data_units",
           "setting_default"]
