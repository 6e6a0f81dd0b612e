"""The ``gistools`` Processing provider: one algorithm per gistools tool, plus the models shipped in models/."""

from __future__ import annotations

import os
from pathlib import Path

from qgis.core import QgsMessageLog, QgsProcessingModelAlgorithm, QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from .algorithms import ALGORITHMS

HERE = Path(__file__).resolve().parent
# each shipped model's name in the toolbox and its group (its id stays gistools:<file's model name>)
MODEL_NAMES = {"shrub_density": ("Shrub model (the steps wired)", "Shrub chain", "shrub"),
               "search_plan_model": ("Search plan from tiles (model)", "Search and rescue", "sar")}


class ShippedModel(QgsProcessingModelAlgorithm):
    """A model of models/, listed under a readable name in its group's place of the toolbox (a model's own name is
    its id's word)."""

    def displayName(self):  # noqa: N802
        return MODEL_NAMES.get(self.name(), (super().displayName(),))[0]

    def group(self):
        return MODEL_NAMES[self.name()][1] if self.name() in MODEL_NAMES else super().group()

    def groupId(self):  # noqa: N802
        return MODEL_NAMES[self.name()][2] if self.name() in MODEL_NAMES else super().groupId()

    def createInstance(self):  # noqa: N802
        model = ShippedModel()
        model.loadVariant(self.toVariant())
        model.setSourceFilePath(self.sourceFilePath())
        return model


class GistoolsProvider(QgsProcessingProvider):
    def id(self):
        return "gistools"

    def name(self):
        return "gistools"

    def longName(self):  # noqa: N802
        import gistools

        return f"gistools {gistools.__version__} (LiDAR shrub density)"

    def versionInfo(self):  # noqa: N802
        import gistools

        return gistools.__version__

    def icon(self):
        return QIcon(str(HERE / "icon.svg"))

    def svgIconPath(self):  # noqa: N802
        return str(HERE / "icon.svg")

    def loadAlgorithms(self):  # noqa: N802
        for cls in ALGORITHMS:
            self.addAlgorithm(cls())
        for path in sorted((HERE / "models").glob("*.model3")):
            model = ShippedModel()
            if model.fromFile(os.fspath(path)):
                self.addAlgorithm(model)
            else:
                QgsMessageLog.logMessage(f"gistools: cannot read the model {path}", "gistools")

    # outputs are files gistools writes itself (atomically): GeoTIFF and GeoPackage, no memory layers
    def supportsNonFileBasedOutput(self):  # noqa: N802
        return False

    def supportedOutputRasterLayerExtensions(self):  # noqa: N802
        return ["tif"]

    def supportedOutputVectorLayerExtensions(self):  # noqa: N802
        return ["gpkg"]

    def defaultRasterFileExtension(self):  # noqa: N802
        return "tif"

    def defaultVectorFileExtension(self, hasGeometry=True):  # noqa: N802
        return "gpkg"
