"""Parameters of the search plan (gistools search-plan, SearchSettings): the lost person's category and its
distance rings, segments, detection, barriers and handrails, routes and the litter carry."""

import csv
from pathlib import Path

from .core import ByUnits, Parameter, command, declare


def _categories() -> dict:
    """{category: label} of the shipped distance table (gistools/datasets/lost_person.csv), in its order."""
    with open(Path(__file__).resolve().parent.parent / "datasets" / "lost_person.csv", encoding="utf-8",
              newline="") as f:
        names = [r["category"] for r in csv.DictReader(f)]
    return {n: n.replace("_", " ") for n in dict.fromkeys(names)}


DISTANCES = {"crow": "crow: as the crow flies (Koester's rings)",
             "walk": "walk: walked on the travel graph, as the distance on open flat ground in the same time"}

declare(
    Parameter("category", "text", "The lost person's category, a row of the categories table (gistools "
              "search-plan --list-categories lists them): hiker, hunter, child_1_3, dementia, ...",
              "Lost person category", metavar="NAME", example="dementia", choices=_categories(),
              required=True),
    Parameter("ecoregion", "text", "The terrain of the table's rows to use, as Koester's tables divide them "
              "(e.g. temperate_mountainous, temperate_flat); the first row of the category when not given.",
              "Terrain of the distance table (e.g. temperate_mountainous)", metavar="TERRAIN",
              example="temperate_mountainous", default_text="the category's first row"),
    Parameter("categories", "file", "A CSV of your own distance statistics with the columns of the shipped table "
              "(category, ecoregion, p25_km, p50_km, p75_km, p95_km; optional near_linear_share, downhill_share, "
              "level_share, uphill_share, source).",
              "Own categories table (CSV)", metavar="CSV", default_text="the shipped table (Koester 2008)",
              advanced=True),
    Parameter("distance", "choice", "How the distance from the point last seen is measured for the rings.",
              "Distance of the rings", default="crow", choices=DISTANCES),
    Parameter("staging", "text", "A staging point X,Y in the DEM's CRS (or a point layer) from which teams walk to "
              "the segments; give it again for more.", "Staging point(s) X,Y", metavar="X,Y|LAYER",
              example="431200,1810600", default_text="the point last seen"),
    Parameter("route_to", "text", "A point X,Y to route to from the nearest staging point (where a dog alerted, a "
              "clue); give it again for more.", "Route to point(s) X,Y", metavar="X,Y", example="430700,1810900"),
    Parameter("effort", "file", "A CSV of segment,hours: the searcher-hours given to each segment (a segment "
              "not listed gets 0).", "Effort per segment (CSV segment,hours)", metavar="CSV"),
    Parameter("search_speed", "float", "The searchers' speed while searching, km/h: coverage = sweep width x "
              "speed x hours / area.", "Search speed, km/h", default=1.0, minimum=0.01, example="1"),
    Parameter("detection_ranges", "numbers", "The average range of detection (Rd) of a searcher, metres, in open "
              "ground, light, medium and heavy shrub: measured by the team before the search (walk away from a "
              "target until it is lost from sight, in several directions, and average).",
              "Ranges of detection Rd, m (open, light, medium, heavy)", default=(25.0, 15.0, 10.0, 5.0), count=4,
              minimum=0.0, example="25,15,10,5"),
    Parameter("visibility", "choice", "The subject's visibility: the effective sweep width is 1.8, 1.6 or 1.1 "
              "times Rd (Koester et al. 2014).", "Subject visibility", default="medium",
              choices={"high": "high: W = 1.8 Rd", "medium": "medium: W = 1.6 Rd", "low": "low: W = 1.1 Rd"}),
    Parameter("feature_weights", "numbers", "How much likelier a find is near a road, a trail, water, a drainage "
              "and a ridge than elsewhere in its ring (Jacobs 2015, from ISRID finds); 1,1,1,1,1: no weighting.",
              "Weights near roads, trails, water, drainages, ridges", default=(3.0, 5.0, 2.0, 1.5, 2.0), count=5,
              minimum=0.0, example="3,5,2,1.5,2", advanced=True),
    Parameter("cover_weight", "float", "How much likelier a find is in medium and heavy shrub than in the open "
              "(a person with dementia often ends up hidden by brush): 1 is no weighting.",
              "Weight of dense shrub cover", default=1.0, minimum=0.0, example="2", advanced=True),
    Parameter("segment_size", "text", "The target area of a segment: ha, ac, km2, m2 or ft2 (a bare number: CRS "
              "units squared).", "Target segment area (e.g. 10ha, 25ac)", default=ByUnits("25ac", "10ha"),
              metavar="AREA", example="10ha"),
    Parameter("near_distance", "length", "A cell within this distance of a linear feature (road, trail, "
              "drainage, ridge, water's or thicket's edge) is near it.", "Near a linear feature within",
              default=ByUnits("100ft", "30m"), minimum=0.0, advanced=True, example="30m"),
    Parameter("cliff_slope", "float", "A cliff is steeper than this, degrees.", "Cliff slope, degrees",
              default=45.0, minimum=0.0, maximum=90.0, advanced=True),
    Parameter("cliff_height", "length", "... and at least this high from its foot to its top.",
              "Cliff height at least", default=ByUnits("10ft", "3m"), minimum=0.0, advanced=True, example="3m"),
    Parameter("thicket_area", "text", "Heavy shrub is a thicket (a barrier and its own segment) from this area: "
              "ha, ac, km2, m2, ft2.", "Thicket area at least", default=ByUnits("0.25ac", "0.1ha"), metavar="AREA",
              advanced=True, example="0.1ha"),
    Parameter("channel_area", "text", "A drainage starts where this area drains through a cell; a ridge where "
              "as much drains up to it on the inverted DEM.", "Drainage and ridge area at least",
              default=ByUnits("5ac", "2ha"), metavar="AREA", advanced=True, example="2ha"),
    Parameter("litter_speed", "float", "The speed of a litter carry on open flat ground, km/h (Tobler's "
              "function scaled to it on slopes).", "Litter carry speed on flat ground, km/h", default=1.0,
              minimum=0.01, advanced=True),
    Parameter("litter_max_slope", "float", "A litter is not carried across a cell steeper than this, degrees "
              "(beyond it a rope system lowers it).", "Litter carry's steepest slope, degrees", default=20.0,
              minimum=0.0, maximum=90.0, advanced=True),
    Parameter("litter_width", "length", "The width of the litter team: a gap in heavy shrub, cliffs or water "
              "narrower than this is closed to it.", "Litter team width", default=ByUnits("8ft", "2.5m"),
              minimum=0.0, advanced=True, example="2.5m"),
    Parameter("list_categories", "flag", "List the categories of the shipped table with their distances, and exit.",
              "List the categories", default=False),
    Parameter("trails", "layer", "Trail lines (a path or file.gpkg:LAYER) in the DEM's CRS: handrails, walked as "
              "roads are.", "Trails (lines)", geometry="line", metavar="LAYER"),
)

SEARCH_PLAN = command(
    "search-plan", "dem", "last_seen", "category", "ecoregion", "categories", "distance", "staging", "route_to",
    "effort", "search_speed", "detection_ranges", "visibility", "feature_weights", "cover_weight",
    "segment_size", "shrub_classes", "roads", "trails", "hydro",
    "waterbodies", "near_distance", "cliff_slope", "cliff_height", "thicket_area", "channel_area", "litter_speed",
    "litter_max_slope", "litter_width", "road_speed", "wade_speed", "tobler", "shrub_factors", "neighbours",
    "max_memory", "reproject_vectors", "overwrite", "list_categories",
    library="products.search_plan:search_plan", settings="products.search_plan:SearchSettings",
    command_line=("list_categories",),
    cli="search_plan:search_plan")
"""The search plan (``gistools search-plan``, ``gistools:search_plan``): the probability of area of a lost person
category, barriers and handrails, segments with their probability of detection, routes from the staging points."""
