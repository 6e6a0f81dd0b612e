"""The aquifer model (gistools aquifer)."""

from __future__ import annotations

from pathlib import Path

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputString,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorLayer,
)

from .base import labels, GistoolsAlgorithm, AQUIFER
from ..compat import DOUBLE, FOLDER, VECTOR_POINT, VECTOR_POLYGON


GROUP_AQUIFER = ("Aquifer", "aquifer")


CONTACT_FIELDS = {"ID_FIELD": ("Contact id field", "id"), "Z_FIELD": ("Height field (z; empty: the point's z)", "z"),
                  "LAYER_FIELD": ("Layer name field", "layer")}


class AquiferModelAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "aquifer", "Aquifer model", GROUP_AQUIFER
    _help = ("Borehole layer contacts (points with x, y, z and a layer field) to a 3D aquifer model (gistools aquifer "
             "model): outliers flagged with their rule, one TIN per layer, boundaries, matched walls, a closed mesh "
             "per unit, thickness rasters and exact volumes (report.json). Layers are named top to bottom.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Layer contacts (points with a layer name field)",
                                                   [VECTOR_POINT]))
        self.add_fields("INPUT", CONTACT_FIELDS)
        self.add(QgsProcessingParameterString("LAYERS", "Layer names, top to bottom (comma-separated)",
                                              defaultValue="LS,AU,AD,AQ"))
        self.add(QgsProcessingParameterVectorLayer("WITHIN", "Volumes inside this polygon (default: common footprint)",
                                                   [VECTOR_POLYGON], optional=True))
        self.add(QgsProcessingParameterVectorLayer("CLIP", "Cut the surfaces to this polygon", [VECTOR_POLYGON],
                                                   optional=True), advanced=True)
        self.add(QgsProcessingParameterBoolean("SWAP_XY", "Swap x and y", defaultValue=False), advanced=True)
        self.add_length("XY_TOL", "Duplicates: same position within", AQUIFER.xy_tol, advanced=True)
        self.add_length("ABS_THR", "Outliers: smallest residual threshold", AQUIFER.abs_thr, advanced=True)
        self.add(QgsProcessingParameterEnum("ORDER", "Where the TINs of a unit's top and base cross",
                                            options=["Stratigraphic: thickness from the boreholes (isopach), never below 0",
                                                     "Raw: the two TINs as they are (thickness can go negative)"],
                                            defaultValue=["stratigraphic", "raw"].index(AQUIFER.order)), advanced=True)
        self.add(QgsProcessingParameterEnum("MESH", "Mesh format", options=labels(["ply", "obj"]),
                                            defaultValue=["ply", "obj"].index(AQUIFER.mesh_format)), advanced=True)
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputVectorLayer("GPKG", "Aquifer GeoPackage"))
        self.addOutput(QgsProcessingOutputFile("REPORT", "report.json"))
        self.addOutput(QgsProcessingOutputString("VOLUMES", "Volumes per unit (JSON)"))

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.tasks.aquifer import AquiferSettings, aquifer_model

        out = Path(self.output_folder(parameters, context))
        layers = [x.strip() for x in self.parameterAsString(parameters, "LAYERS", context).split(",") if x.strip()]
        settings = AquiferSettings(xy_tol=self.text(parameters, "XY_TOL", context),
                                   abs_thr=self.text(parameters, "ABS_THR", context),
                                   mesh_format=["ply", "obj"][self.parameterAsEnum(parameters, "MESH", context)],
                                   order=["stratigraphic", "raw"][self.parameterAsEnum(parameters, "ORDER", context)])
        source = self.layer_spec(parameters, "INPUT", context, feedback)
        crs = self.layer_crs(parameters, "INPUT", context)
        rep = aquifer_model(source, layers, out, crs=crs, swap_xy=self.parameterAsBool(parameters, "SWAP_XY", context),
                            settings=settings, within=self.layer_spec(parameters, "WITHIN", context, feedback),
                            clip=self.layer_spec(parameters, "CLIP", context, feedback), overwrite=True,
                            progress=self.progress(feedback),
                            fields=self.chosen_fields(parameters, context, "INPUT", CONTACT_FIELDS))
        for name, u in rep["units"].items():
            feedback.pushInfo(f"{name}: volume {u['volume']:,.0f} (+{u['volume_positive']:,.0f} / "
                              f"{u['volume_negative']:,.0f}) {rep['volume_unit']}; thickness {u['thickness_min']:.2f} / "
                              f"{u['thickness_mean']:.2f} / {u['thickness_max']:.2f}")
        for name, path in rep["outputs"]["thickness"].items():
            self.load_on_completion(context, path, f"Thickness {name}", "THICKNESS")
        volumes = {name: {k: u[k] for k in ("volume", "volume_positive", "volume_negative")} for name, u in rep["units"].items()}
        return {"OUTPUT_FOLDER": str(out), "GPKG": str(out / "aquifer.gpkg"), "REPORT": str(out / "report.json"),
                "VOLUMES": json.dumps(volumes)}


class AquiferQueryAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "aquiferquery", "Aquifer at a point", GROUP_AQUIFER
    _help = ("Height of every surface and thickness of every unit of a model (the output folder of 'Aquifer model') "
             "at a point: TIN (default, nothing outside the boundary), k-nearest mean or IDW.")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterFile("MODEL", "Aquifer model folder", behavior=FOLDER))
        self.add(QgsProcessingParameterNumber("X", "x (model CRS)", type=DOUBLE))
        self.add(QgsProcessingParameterNumber("Y", "y (model CRS)", type=DOUBLE))
        self.add(QgsProcessingParameterEnum("METHOD", "Method", options=labels(["tin", "knn", "idw"], tin="TIN of each surface (nothing outside its boundary)", knn="Mean of the k nearest contacts", idw="Inverse-distance weighted contacts"), defaultValue=0))
        self.add(QgsProcessingParameterNumber("K", "Neighbours (knn, idw)", defaultValue=10, minValue=1), advanced=True)
        self.addOutput(QgsProcessingOutputString("RESULT", "Heights and thickness (JSON)"))

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.tasks.aquifer import aquifer_query

        result = aquifer_query(self.text(parameters, "MODEL", context), self.parameterAsDouble(parameters, "X", context),
                               self.parameterAsDouble(parameters, "Y", context),
                               ["tin", "knn", "idw"][self.parameterAsEnum(parameters, "METHOD", context)],
                               k=self.parameterAsInt(parameters, "K", context))
        for layer, h in result["heights"].items():
            feedback.pushInfo(f"{layer}: {h['z']} ({'inside' if h['inside'] else 'outside'} the boundary)")
        for name, t in result["thickness"].items():
            feedback.pushInfo(f"{name}: thickness {t}")
        return {"RESULT": json.dumps(result)}
