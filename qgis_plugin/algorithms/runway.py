"""Runway earthworks (gistools runway)."""

from __future__ import annotations

from pathlib import Path

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputNumber,
    QgsProcessingOutputRasterLayer,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterVectorLayer,
)

from .base import labels, GistoolsAlgorithm, RUNWAY
from ..compat import DOUBLE, VECTOR_POINT


GROUP_RUNWAY = ("Runway", "runway")


SURVEY_FIELDS = {"TYPE_FIELD": ("Point type field (1 centre-line light, 2 other)", "type"),
                 "Z_FIELD": ("Height field (z; empty: the point's z)", "z"), "ID_FIELD": ("Point id field", "id")}


class RunwayAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "runway", "Runway earthworks", GROUP_RUNWAY
    _help = ("A runway survey (points with a type field: 1 = centre-line light, 2 = other, and z) and the aerodrome "
             "reference code to the centre line, an ICAO design model, cross sections, signed cut / fill areas, "
             "the area diagram and the Brückner (mass-haul) curve with balance points (gistools runway).")

    def initAlgorithm(self, config=None):  # noqa: N802
        from gistools.runway.icao import RUNWAY_TYPES, TEMPLATES, VALID_CODES

        self._codes, self._types, self._templates = list(VALID_CODES), list(RUNWAY_TYPES), list(TEMPLATES)
        self.add(QgsProcessingParameterVectorLayer("INPUT", "Survey points (with a point type field)", [VECTOR_POINT]))
        self.add_fields("INPUT", SURVEY_FIELDS)
        self.add(QgsProcessingParameterEnum("CODE", "Aerodrome reference code", options=self._codes,
                                            defaultValue=self._codes.index(RUNWAY.code)))
        self.add(QgsProcessingParameterEnum("RUNWAY_TYPE", "Runway type", options=labels(self._types),
                                            defaultValue=self._types.index(RUNWAY.runway_type)))
        self.add(QgsProcessingParameterEnum("TEMPLATE", "Template", options=labels(self._templates),
                                            defaultValue=self._templates.index(RUNWAY.template)))
        self.add_length("SPACING", "Station spacing (empty: from the survey)", None, optional=True)
        self.add(QgsProcessingParameterNumber("SWELL", "Swell factor of cut", type=DOUBLE,
                                              defaultValue=RUNWAY.f_cut, minValue=0.01), advanced=True)
        self.add(QgsProcessingParameterNumber("COMPACTION", "Compaction factor of fill",
                                              type=DOUBLE, defaultValue=RUNWAY.f_fill, minValue=0.01),
                 advanced=True)
        self.add_length("FREE_HAUL", "Free-haul distance (empty: no overhaul)", None, optional=True, advanced=True)
        self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
        self.addOutput(QgsProcessingOutputRasterLayer("DESIGN", "Design surface"))
        self.addOutput(QgsProcessingOutputVectorLayer("GPKG", "Runway GeoPackage"))
        self.addOutput(QgsProcessingOutputNumber("CUT", "Cut (m3)"))
        self.addOutput(QgsProcessingOutputNumber("FILL", "Fill (m3)"))
        self.addOutput(QgsProcessingOutputFile("REPORT", "report.json"))

    def metres(self, parameters, name, context):
        """A length parameter in metres (the ICAO template's unit; a bare number is metres), None when empty or 0."""
        from gistools.units import METRE, LinearUnit, length_to_crs_units

        text = self.text(parameters, name, context)
        if not text or text in ("0", "0.0"):
            return None
        return length_to_crs_units(text, LinearUnit("metre", METRE), name=self.parameterDefinition(name).description())

    def run_gistools(self, parameters, context, feedback):
        from gistools.runway.icao import RUNWAY_TYPES, TEMPLATES, VALID_CODES
        from gistools.tasks.runway import RunwaySettings, runway_earthworks

        out = Path(self.output_folder(parameters, context))
        spacing, free = (self.metres(parameters, name, context) for name in ("SPACING", "FREE_HAUL"))
        settings = RunwaySettings(code=VALID_CODES[self.parameterAsEnum(parameters, "CODE", context)],
                                  runway_type=RUNWAY_TYPES[self.parameterAsEnum(parameters, "RUNWAY_TYPE", context)],
                                  template=TEMPLATES[self.parameterAsEnum(parameters, "TEMPLATE", context)],
                                  spacing=spacing or None, f_cut=self.parameterAsDouble(parameters, "SWELL", context),
                                  f_fill=self.parameterAsDouble(parameters, "COMPACTION", context), free_haul=free or None)
        crs = self.layer_crs(parameters, "INPUT", context)
        rep = runway_earthworks(self.layer_spec(parameters, "INPUT", context, feedback), out, settings, crs=crs,
                                overwrite=True, progress=self.progress(feedback),
                                fields=self.chosen_fields(parameters, context, "INPUT", SURVEY_FIELDS))
        feedback.pushInfo(f"cut {rep['cut']:,.1f} m3, fill {rep['fill']:,.1f} m3, net {rep['net']:,.1f} m3; "
                          f"balance points {rep['balance_points']}; removed {rep['removed']}")
        self.load_on_completion(context, out / "design_surface.tif", "Runway design surface", "DESIGN")
        return {"OUTPUT_FOLDER": str(out), "DESIGN": str(out / "design_surface.tif"), "GPKG": str(out / "runway.gpkg"),
                "CUT": rep["cut"], "FILL": rep["fill"], "REPORT": str(out / "report.json")}
