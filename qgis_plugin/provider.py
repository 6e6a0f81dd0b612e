"""The ``gistools`` Processing provider: one algorithm per gistools tool, plus the models shipped in models/."""

from __future__ import annotations

import os
from pathlib import Path

from qgis.core import QgsMessageLog, QgsProcessingModelAlgorithm, QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from .algorithms import ALGORITHMS

HERE = Path(__file__).resolve().parent


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
            model = QgsProcessingModelAlgorithm()
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
