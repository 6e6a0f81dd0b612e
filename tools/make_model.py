"""Write qgis_plugin/models/shrub_density.model3, the dissertation's ModelBuilder chain as a QGIS graphical model,
and qgis_plugin/models/search_plan_model.model3: the shrub chain then the search plan, from the tiles and a point last
seen.

Run with QGIS's Python and the plugin importable (the test command's venv does both):

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/make_model.py

The model is built through the QGIS API (not hand-written XML), so it is what the Model
Designer itself would save; open it there to see and change each step.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "qgis_plugin" / "models" / "shrub_density.model3"
SEARCH_TARGET = ROOT / "qgis_plugin" / "models" / "search_plan_model.model3"
SEARCH_HELP = (
    "The search plan from the tiles: the whole shrub chain (gistools:shrubchain), then gistools:search_plan on its "
    "DEM and shrub classes from the point last seen and the staging point: the probability of area of the lost "
    "person's category, the segments with their probability of detection, the barriers and the routes."
)

HELP = (
    "The shrub density chain of the dissertation (ch. 9), one gistools algorithm per ModelBuilder step: LAS to "
    "ground and non-ground points (LAS To Multipoint), DSM (max of first returns), DEM (ground TIN), nDSM = DSM - DEM, "
    "height bands, breaklines split by the tile index and polygonised, clip of roads and water with selection of "
    "wetland vegetation, point density and cover, light / medium / heavy classes. It gives the same class raster as "
    "gistools shrub (and gistools:shrubchain) on the same tiles. The two point steps only write the dissertation's "
    "point layers for inspection; on a county, deactivate them in the Model Designer (right click > Deactivate)."
)


def add_child(model, cid: str, alg: str, description: str, at: tuple, sources: dict, outputs: dict) -> None:
    """A child algorithm of ``model`` at ``at`` (x, y), its parameters from ``sources`` (every other mandatory one at
    its declared default, so the Model Designer validates the model) and ``outputs`` ({child output: model output
    name}) made outputs of the model."""
    from qgis.core import (QgsApplication, QgsProcessingModelChildAlgorithm, QgsProcessingModelOutput,
                           QgsProcessingModelChildParameterSource as Src)
    from qgis.PyQt.QtCore import QPointF

    from gistools_qgis.compat import OPTIONAL

    c = QgsProcessingModelChildAlgorithm(alg)
    c.setChildId(cid)
    c.setDescription(description)
    c.setPosition(QPointF(*at))
    for d in QgsApplication.processingRegistry().algorithmById(alg).parameterDefinitions():
        if not d.isDestination() and not d.flags() & OPTIONAL and d.name() not in sources:
            sources[d.name()] = Src.fromStaticValue(d.defaultValue())
    for name, src in sources.items():
        c.addParameterSources(name, [src])
    if outputs:
        mos = {}
        for child_output, model_name in outputs.items():
            mo = QgsProcessingModelOutput(model_name, model_name)
            mo.setChildId(cid)
            mo.setChildOutputName(child_output)
            mo.setPosition(QPointF(at[0] + 200, at[1] + 40))
            mos[model_name] = mo
        c.setModelOutputs(mos)
    model.addChildAlgorithm(c)


def build():
    from qgis.core import (
        QgsProcessingModelAlgorithm,
        QgsProcessingModelChildParameterSource as Src,
        QgsProcessingModelParameter,
        QgsProcessingParameterFile,
        QgsProcessingParameterString,
        QgsProcessingParameterVectorLayer,
    )
    from qgis.PyQt.QtCore import QPointF

    # the plugin as load_plugin() imported it; its enums by the names of the running QGIS (3.22 to 4)
    from gistools_qgis.compat import FOLDER, VECTOR_LINE, VECTOR_POLYGON

    from gistools.lidar.bands import PRESETS
    from gistools.lidar.dsmfill import DSM_FILLS
    from gistools.lidar.gridding import DEM_METHODS
    from gistools.lidar.shrub import CLASS_METHODS
    from gistools.parameters import default_for
    from gistools.products.settings import DEFAULTS as D

    R = D.raster  # the values the model passes are the library's defaults, as the algorithms' own
    model = QgsProcessingModelAlgorithm("shrub_density", "Models")
    model.setHelpContent({"ALG_DESC": HELP, "ALG_CREATOR": "gistools", "ALG_VERSION": "1", "HELP_URL": help_url()})

    inputs = [
        (QgsProcessingParameterFile("TILES", "LAS/LAZ tile folder", behavior=FOLDER), 0),
        (QgsProcessingParameterVectorLayer("ROADS", "Road breaklines", [VECTOR_LINE], optional=True), 1),
        (QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", [VECTOR_LINE],
                                           optional=True), 2),
        (QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", [VECTOR_POLYGON],
                                           optional=True), 3),
        (QgsProcessingParameterVectorLayer("WETLANDS", "Wetland polygons", [VECTOR_POLYGON],
                                           optional=True), 4),
        (QgsProcessingParameterVectorLayer("TILE_INDEX", "Tile index (footprints)", [VECTOR_POLYGON],
                                           optional=True), 5),
        (QgsProcessingParameterString("TILE_FIELD", "Tile number field", defaultValue=D.tile_field), 6),
        # the dissertation's chain on its data in feet: its 5 ft cells and 25 ft radius (the command line and the
        # chain's algorithm take 1.5 m and 7.5 m on metre data; the model's form shows its values)
        (QgsProcessingParameterString("CELL_SIZE", "Cell size (with unit)", defaultValue=default_for("cell_size", True)), 7),
        (QgsProcessingParameterString("RADIUS", "Density radius (with unit)", defaultValue=default_for("radius", True)), 8),
    ]
    for definition, row in inputs:
        component = QgsProcessingModelParameter(definition.name())
        component.setPosition(QPointF(120, 60 + 70 * row))
        model.addModelParameter(definition, component)
    model.setParameterOrder([d.name() for d, _ in inputs])  # the form in the chain's order (else alphabetical)

    def child(cid, alg, description, x, y, sources, outputs=None):
        add_child(model, cid, alg, description, (x, y), sources,
                  {k: name for k, (name, _param) in (outputs or {}).items()})

    P, C, V = Src.fromModelParameter, Src.fromChildOutput, Src.fromStaticValue
    child("points_ground", "gistools:points", "LAS to ground points (class 2)", 420, 40,
          {"INPUT": P("TILES"), "CLASSES": V("2"), "RETURNS": V(2), "FORMAT": V(0)})
    child("points_nonground", "gistools:points", "LAS to non-ground points (classes 1, 2, first returns)", 420, 110,
          {"INPUT": P("TILES"), "CLASSES": V("1,2"), "RETURNS": V(0), "FORMAT": V(0)})
    child("dsm", "gistools:dsm", "DSM (max of first returns)", 420, 200,
          {"INPUT": P("TILES"), "CELL_SIZE": P("CELL_SIZE"), "DSM_FILL": V(list(DSM_FILLS).index(R.dsm_fill)), "JOBS": V(1)})
    child("dem", "gistools:dem", "DEM (ground TIN)", 420, 280,
          {"INPUT": P("TILES"), "CELL_SIZE": P("CELL_SIZE"), "DEM_METHOD": V(list(DEM_METHODS).index(R.dem_method)),
           "DEM_MAX_DISTANCE": V(R.dem_max_distance),
           "JOBS": V(1)})
    child("ndsm", "gistools:ndsm", "nDSM = DSM - DEM", 680, 240,
          {"DSM": C("dsm", "OUTPUT"), "DEM": C("dem", "OUTPUT")})
    child("bands", "gistools:bands", "Height bands B0-B3", 900, 240,
          {"NDSM": C("ndsm", "OUTPUT"), "TOP_CLASS": C("dsm", "TOP_CLASS"), "PRESET": V(list(PRESETS).index(D.bands)),
           "NOISE_FLOOR": V(D.noise_floor),
           "Z_UNIT": V(0)})
    child("breaklines", "gistools:breaklines", "Split breaklines by tiles, polygonise roads and water", 680, 420,
          {"ROADS": P("ROADS"), "HYDRO": P("HYDRO"), "WATERBODIES": P("WATERBODIES"), "TILE_INDEX": P("TILE_INDEX"),
           "TILE_FIELD": P("TILE_FIELD"), "SNAP": V(D.snap), "MAX_ROAD_WIDTH": V(D.max_road_width),
           "MAX_HYDRO_WIDTH": V(D.max_hydro_width), "SINGLE_LINE_WIDTH": V(D.single_line_width), "REPROJECT": V(False)})
    child("clip", "gistools:clip", "Clip roads and water; select wetland vegetation", 1120, 330,
          {"BANDS": C("bands", "OUTPUT"), "ROAD_POLYGONS": C("breaklines", "OUTPUT_ROADS"),
           "WATER_POLYGONS": C("breaklines", "OUTPUT_WATER"), "WETLANDS": P("WETLANDS"), "REPROJECT": V(False)},
          outputs={"OUTPUT_WETLAND": ("Vegetation in wetlands", None)})
    child("density", "gistools:density", "Point density and cover of vegetation", 1340, 330,
          {"VEGETATION": C("clip", "OUTPUT"), "RADIUS": P("RADIUS"), "DENSITY_BANDS": V([b - 1 for b in D.density_bands])},
          outputs={"OUTPUT": ("Cover", None)})
    child("classify", "gistools:classify", "Light / medium / heavy shrub classes", 1560, 330,
          {"COVER": C("density", "OUTPUT"), "VEGETATION": C("clip", "OUTPUT"), "METHOD": V(list(CLASS_METHODS).index(D.classify)),
           "BREAKS": V(",".join(f"{b:g}" for b in D.class_breaks))},
          outputs={"OUTPUT": ("Shrub classes", None), "OUTPUT_POLYGONS": ("Shrub class polygons", None)})
    # the model outputs become destination parameters of the model (as the Model Designer does on save)
    model.updateDestinationParameters()
    return model


def build_search_plan():
    """The search plan's model: tiles and breaklines -> gistools:shrubchain -> gistools:search_plan."""
    from qgis.core import (
        QgsProcessingModelAlgorithm,
        QgsProcessingModelChildParameterSource as Src,
        QgsProcessingModelParameter,
        QgsProcessingParameterEnum,
        QgsProcessingParameterFile,
        QgsProcessingParameterString,
        QgsProcessingParameterVectorLayer,
    )
    from qgis.PyQt.QtCore import QPointF

    from gistools_qgis.compat import FOLDER, VECTOR_LINE, VECTOR_POLYGON

    from gistools.parameters import PARAMETERS

    model = QgsProcessingModelAlgorithm("search_plan_model", "Models")
    model.setHelpContent({"ALG_DESC": SEARCH_HELP, "ALG_CREATOR": "gistools", "ALG_VERSION": "1",
                          "HELP_URL": help_url(SEARCH_HELP_PAGE)})
    categories = list(PARAMETERS["category"].choices)
    inputs = [
        QgsProcessingParameterFile("TILES", "LAS/LAZ tile folder", behavior=FOLDER),
        QgsProcessingParameterVectorLayer("ROADS", "Road breaklines", [VECTOR_LINE], optional=True),
        QgsProcessingParameterVectorLayer("HYDRO", "Hydrographic breaklines", [VECTOR_LINE], optional=True),
        QgsProcessingParameterVectorLayer("WATERBODIES", "Water body polygons", [VECTOR_POLYGON], optional=True),
        QgsProcessingParameterString("LAST_SEEN", "Point last seen X,Y"),
        QgsProcessingParameterEnum("CATEGORY", "Lost person category", options=categories,
                                   defaultValue=categories.index("hiker")),
        QgsProcessingParameterString("STAGING", "Staging point(s) X,Y", optional=True),
    ]
    for row, definition in enumerate(inputs):
        component = QgsProcessingModelParameter(definition.name())
        component.setPosition(QPointF(120, 60 + 70 * row))
        model.addModelParameter(definition, component)
    model.setParameterOrder([d.name() for d in inputs])
    P, C, V = Src.fromModelParameter, Src.fromChildOutput, Src.fromStaticValue

    def child(cid, alg, description, x, y, sources, outputs):
        add_child(model, cid, alg, description, (x, y), sources, outputs)

    child("shrub", "gistools:shrubchain", "Shrub map (whole chain)", 420, 120,
          {"INPUT": P("TILES"), "ROADS": P("ROADS"), "HYDRO": P("HYDRO"), "WATERBODIES": P("WATERBODIES"),
           "MAKE_MAP": V(False), "JOBS": V(1)}, {"CLASSES": "Shrub classes"})
    child("plan", "gistools:search_plan", "Search plan", 700, 220,
          {"DEM": C("shrub", "DEM"), "CLASSES": C("shrub", "CLASSES"), "LAST_SEEN": P("LAST_SEEN"),
           "CATEGORY": P("CATEGORY"), "STAGING": P("STAGING")},
          {"POA": "Probability of area", "SEGMENTS": "Segments", "ROUTES": "Routes"})
    model.updateDestinationParameters()
    return model


SEARCH_HELP_PAGE = "search_and_rescue.html#qgis-search_plan"


# the model's section of the documentation: docs/qgis.md's "The shrub density model", as MkDocs publishes it
HELP_PAGE = "qgis.html#the-shrub-density-model"


def help_url(page: str = "") -> str:
    """The model's section of the documentation site at the project's homepage (declared once, in
    qgis_plugin/metadata.txt): the same site the plugin ships in help/, online (a model file holds no path of the
    plugin's folder)."""
    if str(ROOT / "tools") not in sys.path:
        sys.path.insert(0, str(ROOT / "tools"))
    from build_plugin import declared

    return declared()["homepage"].rstrip("/") + "/" + (page or HELP_PAGE)


def load_plugin():
    """The plugin of this checkout (qgis_plugin/) imported as the package gistools_qgis, as QGIS would."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("gistools_qgis", ROOT / "qgis_plugin" / "__init__.py",
                                                  submodule_search_locations=[str(ROOT / "qgis_plugin")])
    module = importlib.util.module_from_spec(spec)
    sys.modules["gistools_qgis"] = module
    spec.loader.exec_module(module)
    return module.classFactory(None)


def main() -> int:
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from qgis.core import QgsApplication

    app = QgsApplication([], False)
    app.initQgis()
    plugin = load_plugin()  # kept: its provider holds the algorithms the children resolve to
    plugin.initProcessing()  # the children's algorithms must resolve for the model outputs to become parameters
    for model, target in ((build(), TARGET), (build_search_plan(), SEARCH_TARGET)):
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(target.name + ".partial")
        if not model.toFile(str(tmp)):
            print(f"could not write {target.name}", file=sys.stderr)
            return 1
        tmp.replace(target)
        print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main())
