"""The aquifer model (gistools aquifer)."""

from __future__ import annotations

import inspect
from pathlib import Path

from qgis.core import QgsProcessingOutputString, QgsProcessingParameterFile, QgsProcessingParameterVectorLayer

from gistools.products.aquifer import aquifer_query

from .base import GistoolsAlgorithm, AQUIFER
from ..compat import FOLDER, VECTOR_POINT


GROUP_AQUIFER = ("Aquifer", "aquifer")
QUERY_K = inspect.signature(aquifer_query).parameters["k"].default  # the library's default, never a copy


CONTACT_FIELDS = {"ID_FIELD": ("Contact id field", "id"), "Z_FIELD": ("Height field (z; empty: the point's z)", "z"),
                  "LAYER_FIELD": ("Layer name field", "layer")}


class AquiferModelAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "aquifer", "Aquifer model", GROUP_AQUIFER

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Layer contacts (points with a layer name field)",
                                                   [VECTOR_POINT]))
        self.add_fields("INPUT", CONTACT_FIELDS)
        # the command line's settings (gistools.parameters.aquifer) but --no-figures; the CRS where the layer has
        # none (a CSV picked as a file)
        self.add_spec("layers", "crs", "within", "clip", "swap_xy", "xy_tol", "abs_thr", "order", "mesh_format",
                      "concave_ratio", "k", "c", "f_nn", "order_tol", "n_per_edge", "densify", "thickness_cell_size",
                      "matching", labels={"k": f"Neighbours of the outlier plane fit (at least 3; empty: {AQUIFER.k})"},
                      defaults={"layers": "LS,AU,AD,AQ"})  # the dissertation's Milan layers, as the dialog offered
        self.add_outputs(
            "Output folder", GPKG=("vector", "Aquifer GeoPackage"), REPORT=("file", "report.json"),
            VOLUMES=("string", "Volumes per unit (JSON)"))

    def _model_settings(self, parameters, context, feedback):
        """(the layers top to bottom, the run's inputs, the AquiferSettings) of the dialog's values."""
        from gistools.products.aquifer import AquiferSettings

        values = self.spec_values(parameters, context, feedback)
        layers = [x.strip() for x in (values.pop("layers") or "").split(",") if x.strip()]
        run = {k: values.pop(k) for k in ("within", "clip", "swap_xy", "crs")}
        values["cell_size"] = values.pop("thickness_cell_size")
        return layers, run, AquiferSettings(**{k: v for k, v in values.items() if v is not None})

    def run_gistools(self, parameters, context, feedback):
        import json

        from gistools.products.aquifer import aquifer_model

        out = Path(self.output_folder(parameters, context))
        layers, run, settings = self._model_settings(parameters, context, feedback)
        source = self.layer_spec(parameters, "INPUT", context, feedback, tables=True)
        crs = run.pop("crs") or self.layer_crs(parameters, "INPUT", context)
        rep = aquifer_model(source, layers, out, crs=crs, settings=settings, overwrite=True,
                            progress=self.progress(feedback), **run,
                            fields=self.chosen_fields(parameters, context, "INPUT", CONTACT_FIELDS))
        for w in rep.get("warnings") or []:
            feedback.pushWarning(f"WARNING {w}") if hasattr(feedback, "pushWarning") else feedback.reportError(f"WARNING {w}")
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

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterFile("MODEL", "Aquifer model folder", behavior=FOLDER))
        self.add_spec(command="aquifer query", labels={"k": f"Neighbours (knn, idw; empty: {QUERY_K})"})
        self.addOutput(QgsProcessingOutputString("RESULT", "Heights and thickness (JSON)"))

    def run_gistools(self, parameters, context, feedback):
        import json

        v = self.spec_values(parameters, context, feedback)
        result = aquifer_query(self.text(parameters, "MODEL", context), v["x"], v["y"], v["height_method"],
                               k=QUERY_K if v["k"] is None else v["k"])
        for layer, h in result["heights"].items():
            feedback.pushInfo(f"{layer}: {h['z']} ({'inside' if h['inside'] else 'outside'} the boundary)")
        for name, t in result["thickness"].items():
            feedback.pushInfo(f"{name}: thickness {t}")
        return {"RESULT": json.dumps(result)}
