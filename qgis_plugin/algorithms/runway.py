"""Runway earthworks (gistools runway)."""

from __future__ import annotations

from pathlib import Path

from qgis.core import QgsProcessingParameterVectorLayer


from .base import GistoolsAlgorithm
from ..compat import VECTOR_POINT


GROUP_RUNWAY = ("Runway", "runway")


SURVEY_FIELDS = {"TYPE_FIELD": ("Point type field (1 centre-line light, 2 other)", "type"),
                 "Z_FIELD": ("Height field (z; empty: the point's z)", "z"), "ID_FIELD": ("Point id field", "id")}


class RunwayAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "runway", "Runway earthworks", GROUP_RUNWAY

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Survey points (with a point type field)", [VECTOR_POINT]))
        self.add_fields("INPUT", SURVEY_FIELDS)
        # the code: a text on the command line (the library's refusal lists the valid ones), a list here
        self.add_spec("code")
        # the command line's settings (gistools.parameters.runway); the CRS where the layer has none (a CSV)
        self.add_spec("crs", "runway_type", "template", "spacing", "f_cut", "f_fill", "free_haul", "origin", "profile_window",
                      "area_method", "max_offset", "min_offset", "z_max")
        self.add_outputs(
            "Output folder", DESIGN=("raster", "Design surface"), GPKG=("vector", "Runway GeoPackage"),
            CUT=("number", "Cut (m3)"), FILL=("number", "Fill (m3)"), REPORT=("file", "report.json"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.runway.survey import SurveyChecks
        from gistools.products.runway import RunwaySettings, runway_earthworks, runway_metres

        out = Path(self.output_folder(parameters, context))
        values = self.spec_values(parameters, context, feedback)
        for name in ("spacing", "free_haul"):  # in metres (the ICAO template's unit); empty or 0: none
            text = values.pop(name)
            values[name] = runway_metres(text, name) if text and text not in ("0", "0.0") else None
        checks = {name: values.pop(name) for name in ("z_max", "max_offset", "min_offset")}
        checks = SurveyChecks(**{name: value if name == "z_max" else runway_metres(value, name)
                                 for name, value in checks.items() if value is not None})
        crs = values.pop("crs") or self.layer_crs(parameters, "INPUT", context)
        settings = RunwaySettings(checks=checks, **values)
        rep = runway_earthworks(self.layer_spec(parameters, "INPUT", context, feedback, tables=True), out, settings, crs=crs,
                                overwrite=True, progress=self.progress(feedback),
                                fields=self.chosen_fields(parameters, context, "INPUT", SURVEY_FIELDS))
        feedback.pushInfo(f"cut {rep['cut']:,.1f} m3, fill {rep['fill']:,.1f} m3, net {rep['net']:,.1f} m3; "
                          f"balance points {rep['balance_points']}; removed {rep['removed']}")
        self.load_on_completion(context, out / "design_surface.tif", "Runway design surface", "DESIGN")
        return {"OUTPUT_FOLDER": str(out), "DESIGN": str(out / "design_surface.tif"), "GPKG": str(out / "runway.gpkg"),
                "CUT": rep["cut"], "FILL": rep["fill"], "REPORT": str(out / "report.json")}
