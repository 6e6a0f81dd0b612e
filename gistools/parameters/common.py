"""Parameters every batch command takes: the tiles' CRS, the run (jobs, scheduler, chunk size), resume."""

from .core import Parameter, declare

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
