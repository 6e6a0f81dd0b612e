"""The Processing algorithm of a command declared whole (gistools.parameters.core.command with ``inputs``): its
inputs, parameters, help, group and page from the declaration, one call of its library function, its rasters
loaded. A new command of this kind needs no module here."""

from __future__ import annotations

from qgis.core import (
    QgsProcessingOutputFolder,
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterRasterLayer,
)

from .base import GistoolsAlgorithm

INPUTS = {"raster": QgsProcessingParameterRasterLayer}  # an input's declared kind -> its QGIS parameter


def algorithm_name(command: str) -> str:
    """The algorithm's name (gistools:<name>) of a declared command: ``slope-classes`` -> ``slope_classes``."""
    return command.replace("-", "_")


def declared_algorithm(command: str, groups: dict) -> type:
    """The algorithm class of the declared ``command``; ``groups``: {group key: (display name, key)}."""
    from gistools.parameters import DECLARED

    spec = DECLARED[command]
    inputs = spec["inputs"]

    class DeclaredAlgorithm(GistoolsAlgorithm):
        _name = algorithm_name(command)
        _display = spec["summary"].split(" (")[0].rstrip(".")
        _group = groups[spec["group"]]
        _page = spec["page"]
        _tags = tuple(command.split("-"))
        _help = (f"{spec['summary']} (gistools {command}; the command line's options, the same outputs and "
                 "report.json).")

        def initAlgorithm(self, config=None):  # noqa: N802
            for keyword, kind, label in inputs:
                self.add(INPUTS[kind](keyword.upper(), label))
            self.add_spec(command=command, skip=("overwrite",))
            self.add(QgsProcessingParameterFolderDestination("OUTPUT_FOLDER", "Output folder"))
            for name in spec["outputs"]:
                self.addOutput(QgsProcessingOutputRasterLayer(name.upper(), name.replace("_", " ").capitalize()))
            self.addOutput(QgsProcessingOutputFolder("FOLDER", "Output folder"))

        def run_gistools(self, parameters, context, feedback):
            from gistools.cli.declared import library_function
            from gistools.parameters import PARAMETERS

            out = self.output_folder(parameters, context)
            args = [self.raster_path(parameters, keyword.upper(), context) for keyword, _kind, _label in inputs]
            given = {PARAMETERS[n].python_name: PARAMETERS[n].library_value(v)
                     for n, v in self.spec_values(parameters, context, feedback).items() if v is not None}
            report = library_function(command)(*args, out, **given, overwrite=True, progress=self.progress(feedback))
            for warning in report.get("warnings", []):
                feedback.pushWarning(f"WARNING {warning}") if hasattr(feedback, "pushWarning") else \
                    feedback.reportError(f"WARNING {warning}")
            outputs = {"OUTPUT_FOLDER": out, "FOLDER": out}
            for name, path in report["outputs"].items():
                outputs[name.upper()] = path
                self.load_on_completion(context, path, name.replace("_", " ").capitalize(), name.upper())
            return outputs

    DeclaredAlgorithm.__name__ = DeclaredAlgorithm.__qualname__ = f"Declared_{algorithm_name(command)}"
    return DeclaredAlgorithm
