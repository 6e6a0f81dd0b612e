"""Parameters of the structure reconstruction (gistools structure, structure_model). h, d and t are the
dissertation's names (and structure_model's arguments); lengths are the cloud's units (metres)."""

from .core import Parameter, command, declare, option  # noqa: F401

LOOP_MODES = {"classic": "Classic: loops through the points as they are",
              "catmull-rom": "Also the dissertation's Catmull-Rom loops (new points and lines)"}

declare(
    Parameter("h", "float", "Largest height step between consecutive levels, m.", "Height interval h, m (0: estimated)",
              flag="--height-interval", qgis="HEIGHT_INTERVAL", minimum=0.0, default_text="estimated", example="8"),
    Parameter("d", "float", "Planimetric distance joining points into a cluster, m.",
              "Planimetric distance d, m (0: estimated)", flag="--distance", qgis="DISTANCE", minimum=0.0,
              default_text="estimated", example="15"),
    Parameter("t", "float", "Planimetric tolerance of matching and of the chain / sown split, m.",
              "Tolerance t, m (0: 4 m)", flag="--tolerance", qgis="TOLERANCE", minimum=0.0, default_text="4",
              example="4"),
    Parameter("columns", "text", "Which input columns are x, y, z (213 swaps x and y).", "Columns of x, y, z",
              default="123", advanced=True, example="213"),
    Parameter("scales", "numbers", "Signed scale per axis.", "Scale per axis (x,y,z; -1 flips an axis)",
              default=(1, 1, 1), advanced=True, example="1,1,1"),
    Parameter("rotations", "numbers", "Degrees about x, y, z.", "Rotation about x, y, z (degrees)", default=(0, 0, 0),
              advanced=True, example="0,0,90"),
    Parameter("loop_mode", "choice", "catmull-rom: also write the dissertation's Catmull-Rom loops (new points and "
              "lines).", "Loops", default="classic", choices=LOOP_MODES, advanced=True),
)

STRUCTURE = command("structure", "h", "d", "t", "columns", "scales", "rotations", "loop_mode", "overwrite",
    library="products.structure:structure_model", cli="structure:structure")
