"""Structure reconstruction (gistools structure)."""

from __future__ import annotations

from pathlib import Path

from qgis.core import QgsProcessingParameterFile

from .base import GistoolsAlgorithm


class StructureAlgorithm(GistoolsAlgorithm):
    _name, _display, _group = "structure", "Structure mesh (closed 3D)", ("Structure", "structure")

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add(QgsProcessingParameterFile("INPUT", "Point cloud (ID X Y Z text, or LAS/LAZ)"))
        # the command line's settings (gistools.parameters.structure); h, d, t: 0 is "estimated" (4 m for t)
        self.add_spec(command="structure", defaults={"h": 0.0, "d": 0.0, "t": 0.0})
        self.add_outputs(
            "Output folder", MESH=("file", "Mesh (PLY)"), LOOPS=("vector", "Loops (GeoPackage)"),
            VOLUME=("number", "Volume (m3)"), WATERTIGHT=("string", "Watertight"))

    def run_gistools(self, parameters, context, feedback):
        from gistools.products.structure import structure_model

        out = Path(self.output_folder(parameters, context))
        values = self.spec_values(parameters, context, feedback)
        values.update({k: values[k] or None for k in ("h", "d", "t")})  # 0 (or empty): estimated
        rep = structure_model(self.parameterAsFile(parameters, "INPUT", context), out, overwrite=True,
                              progress=self.progress(feedback), **{k: v for k, v in values.items() if v is not None})
        feedback.pushInfo(f"{rep['levels']} levels, {rep['clusters']} clusters, {rep['triangles']} triangles, volume "
                          f"{rep['volume']:,.1f} m3, watertight {rep['watertight']}, Euler {rep['euler']}")
        return {"OUTPUT_FOLDER": str(out), "MESH": rep["outputs"]["ply"], "LOOPS": rep["outputs"]["gpkg"],
                "VOLUME": rep["volume"], "WATERTIGHT": str(rep["watertight"])}
