"""Travel time of a walker from the points last seen (gistools travel): search and rescue."""

from __future__ import annotations

from pathlib import Path

from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProcessingParameterVectorLayer

from .base import GROUP_SAR, GistoolsAlgorithm
from ..compat import VECTOR_POINT

NO_POINT = "No point last seen: give 'Points last seen' (X,Y in the DEM's CRS) or a 'Point layer of the points last seen'"


class TravelAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "travel", "Travel time from last seen", GROUP_SAR
    _tags = ("isochrone", "tobler", "walking", "cost distance", "lost person")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_spec("dem", "last_seen")
        self.add(QgsProcessingParameterVectorLayer("LAST_SEEN_LAYER", "Point layer of the points last seen",
                                                   [VECTOR_POINT], optional=True))
        self.add_spec("shrub_classes", "roads", "hydro", "waterbodies", "road_speed", "wade_speed", "isochrones",
                      "tobler", "shrub_factors", "neighbours", "isotropic", "max_memory", "snap", "max_road_width",
                      "max_hydro_width", "single_line_width", "reproject_vectors")
        self.add_outputs(
            "Output folder", MINUTES=("raster", "Travel time (minutes)"), BANDS=("raster", "Isochrone bands"),
            ISOCHRONES=("vector", "Isochrones"), MAX_MINUTES=("number", "Farthest cell reached (minutes)"),
            REPORT=("file", "report.json"))

    def checkParameterValues(self, parameters, context):  # noqa: N802
        if not parameters.get("LAST_SEEN") and not parameters.get("LAST_SEEN_LAYER"):
            return False, NO_POINT
        return super().checkParameterValues(parameters, context)

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.travel import TravelSettings, travel_from_dem

        out = Path(self.output_folder(parameters, context))
        values = self.spec_values(parameters, context, feedback)
        seen = [values.pop("last_seen")] if values.get("last_seen") else []
        values.pop("last_seen", None)
        if parameters.get("LAST_SEEN_LAYER"):
            seen.append(self.layer_spec(parameters, "LAST_SEEN_LAYER", context, feedback))
        if not seen:
            raise QgsProcessingException(NO_POINT)
        dem = self.raster_path(parameters, "DEM", context)
        classes = self.raster_path(parameters, "CLASSES", context)
        layers = {name: self.layer_spec(parameters, name.upper(), context, feedback)
                  for name in ("roads", "hydro", "waterbodies")}
        for name in ("dem", "shrub_classes", *layers):
            values.pop(name, None)
        for name in ("road_speed", "wade_speed"):  # empty in the dialog: the default (Tobler's; impassable)
            if parameters.get(name.upper()) in (None, ""):
                values[name] = None
        rep = travel_from_dem(dem, out, seen, TravelSettings(**values), classes=classes, overwrite=True,
                              progress=self.progress(feedback), **layers)
        for iso in rep["isochrones"]:
            feedback.pushInfo(f"within {iso['minutes']:g} min: {iso['hectares']:,.2f} ha ({iso['acres']:,.2f} acres)")
        self.load_on_completion(context, out / "travel_minutes.tif", "Travel time (minutes)", "MINUTES")
        return {"OUTPUT_FOLDER": str(out), "MINUTES": str(out / "travel_minutes.tif"),
                "BANDS": str(out / "isochrone_bands.tif"), "ISOCHRONES": f"{out / 'travel.gpkg'}|layername=isochrones",
                "MAX_MINUTES": rep["max_minutes"], "REPORT": str(out / "report.json")}


class SearchPlanAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "search_plan", "Search plan (POA, POD, routes)", GROUP_SAR
    _tags = ("lost person", "probability of area", "POA", "POD", "segments", "sweep width", "litter", "koester")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_spec(command="search-plan", skip=("list_categories",))
        self.add_outputs(
            "Output folder", POA=("raster", "Probability of area"), SEGMENTS=("vector", "Segments"),
            ROUTES=("vector", "Routes"), BARRIERS=("vector", "Barriers"), REST=("number", "Rest of the world"),
            REPORT=("file", "report.json"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.search_plan import SearchSettings, search_plan

        out = Path(self.output_folder(parameters, context))
        values = self.spec_values(parameters, context, feedback)
        given = {}
        for name in ("last_seen", "staging", "route_to"):  # X,Y; several separated by ;
            text = values.pop(name, None)
            given[name] = [v.strip() for v in str(text).split(";") if v.strip()] if text else None
        for name in ("roads", "trails", "hydro", "waterbodies"):
            values.pop(name, None)
            given[name] = self.layer_spec(parameters, name.upper(), context, feedback)
        dem = self.raster_path(parameters, "DEM", context) or values.get("dem")
        classes = self.raster_path(parameters, "CLASSES", context)
        category, effort, categories = (values.pop(k, None) for k in ("category", "effort", "categories"))
        for name in ("dem", "shrub_classes"):
            values.pop(name, None)
        for name in ("road_speed", "wade_speed", "ecoregion"):  # empty in the dialog: the default
            if parameters.get(name.upper()) in (None, ""):
                values[name] = None
        if not given["last_seen"]:
            raise QgsProcessingException(NO_POINT)
        rep = search_plan(dem, out, given["last_seen"], category, SearchSettings(**values), staging=given["staging"],
                          route_to=given["route_to"], effort=effort or None, classes=classes,
                          categories=categories or None, roads=given["roads"], trails=given["trails"],
                          hydro=given["hydro"], waterbodies=given["waterbodies"], overwrite=True,
                          progress=self.progress(feedback))
        feedback.pushInfo(f"{rep['category']} ({rep['ecoregion']}): rings "
                          + ", ".join(f"{d / 1000:.2f} km" for d in rep["rings_m"])
                          + f"; rest of the world {rep['rest_of_world']:.1%}; {rep['segments']} segments")
        self.load_on_completion(context, out / "poa.tif", "Probability of area", "POA")
        for layer, label, key in (("segments", "Segments", "SEGMENTS"), ("routes", "Routes", "ROUTES")):
            gpkg = out / f"{layer}.gpkg"
            if gpkg.exists():
                context.addLayerToLoadOnCompletion(f"{gpkg}|layername={layer}", QgsProcessingContext.LayerDetails(
                    label, context.project(), key))
        return {"OUTPUT_FOLDER": str(out), "POA": str(out / "poa.tif"),
                "SEGMENTS": f"{out / 'segments.gpkg'}|layername=segments",
                "ROUTES": f"{out / 'routes.gpkg'}|layername=routes",
                "BARRIERS": f"{out / 'barriers.gpkg'}|layername=barriers", "REST": rep["rest_of_world"],
                "REPORT": str(out / "report.json")}
