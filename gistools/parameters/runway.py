"""Parameters of the runway earthworks (gistools runway, RunwaySettings and its SurveyChecks). Lengths are metres:
the ICAO template is in metres (a bare number is metres; 30ft is taken as 9.144 m)."""

from ..runway.icao import VALID_CODES
from .core import Parameter, command, declare, option  # noqa: F401

RUNWAY_TYPES = {"precision": "Precision approach", "non_precision": "Non-precision approach",
                "non_instrument": "Non-instrument"}
TEMPLATES = {"icao": "ICAO Annex 14 strip", "dissertation": "The dissertation's section"}
ORIGINS = {"low": "The low end", "high": "The high end", "first": "The first light of the file"}
AREA_METHODS = {"exact": "Exact: signed, split where the ground crosses the design",
                "dissertation": "The dissertation's: unsigned hull and Heron's formula"}

declare(
    # a text, not a choice: the library's refusal lists the codes and says what the number and the letter are
    Parameter("code", "text", "Aerodrome reference code (1A ... 4F).", "Aerodrome reference code", default="4E",
              example="4E", choices={c: c for c in VALID_CODES}),
    Parameter("runway_type", "choice", "The runway's approach: sets the strip's half-width.", "Runway type",
              default="precision", choices=RUNWAY_TYPES),
    Parameter("template", "choice", "icao: Annex 14 half-widths; dissertation: its widths read as offsets (45 / 52.5 / "
              "75 / 150 m).", "Template", default="icao", choices=TEMPLATES),
    Parameter("spacing", "length", "Station and lateral spacing, e.g. 10m.", "Station spacing (empty: from the survey)",
              default_text="sqrt(area / points) of the survey", example="10m"),
    Parameter("origin", "choice", "Chainage 0 at the low end, the high end, or the first light of the file.",
              "Chainage 0 at", default="low", choices=ORIGINS, advanced=True),
    Parameter("profile_window", "int", "Design grade: running mean of this many light heights, an odd number (1: the "
              "lights themselves, the spec).", "Design grade: running mean of this many light heights", default=1,
              minimum=1, advanced=True, example="5"),
    Parameter("f_cut", "float", "Factor on cut volumes (swell of dug material).", "Swell factor of cut", default=1.0,
              flag="--swell", qgis="SWELL", minimum=0.01, advanced=True, example="1.2"),
    Parameter("f_fill", "float", "Factor on fill volumes (compaction).", "Compaction factor of fill", default=1.0,
              flag="--compaction", qgis="COMPACTION", minimum=0.01, advanced=True, example="0.9"),
    Parameter("free_haul", "length", "Free-haul distance, e.g. 150m: reports the overhaul.",
              "Free-haul distance (empty: no overhaul)", default_text="no overhaul", advanced=True, example="150m"),
    Parameter("area_method", "choice", "exact: signed, split where ground crosses design; dissertation: unsigned hull "
              "+ Heron.", "Cut and fill areas", default="exact", flag="--areas", choices=AREA_METHODS, advanced=True),
    Parameter("max_offset", "length", "Lights farther off the axis are anomalies.",
              "Survey check: lights farther off the axis are anomalies", default="1m", minimum=0.0, advanced=True,
              example="1m"),
    Parameter("min_offset", "length", "Lights closer to the axis are never anomalies, however high their robust "
              "z-score.", "Survey check: lights closer to the axis are never anomalies", default="0.1m", minimum=0.0,
              advanced=True, example="0.1m"),
    Parameter("z_max", "float", "Robust z-score limit of the checks.", "Survey check: robust z-score limit",
              default=3.5, advanced=True, example="3.5"),
)

RUNWAY = command("runway", "code", "runway_type", "template", "spacing", "crs", "origin", "profile_window", "f_cut",
                 "f_fill", "free_haul", "area_method", "max_offset", "min_offset", "z_max", "fields", "overwrite",
    library="products.runway:runway_earthworks", settings="products.runway:RunwaySettings", cli="runway:runway")
