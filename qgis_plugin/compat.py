"""QGIS enums by their scoped names (QGIS 3.36+, the only names in QGIS 4 / Qt 6), else the unscoped names of
QGIS 3.22-3.34: one place, so the algorithms read the same on every QGIS the plugin supports."""

from __future__ import annotations

from qgis.core import Qgis, QgsProcessing, QgsProcessingParameterDefinition, QgsProcessingParameterFile, QgsProcessingParameterNumber


def _pick(scoped: str, member: str, legacy_owner, legacy: str):
    owner = getattr(Qgis, scoped, None)
    if owner is not None and hasattr(owner, member):
        return getattr(owner, member)
    return getattr(legacy_owner, legacy)


VECTOR_POINT = _pick("ProcessingSourceType", "VectorPoint", QgsProcessing, "TypeVectorPoint")
VECTOR_LINE = _pick("ProcessingSourceType", "VectorLine", QgsProcessing, "TypeVectorLine")
VECTOR_POLYGON = _pick("ProcessingSourceType", "VectorPolygon", QgsProcessing, "TypeVectorPolygon")
POINT_CLOUD = _pick("ProcessingSourceType", "PointCloud", QgsProcessing, "TypePointCloud")
INTEGER = _pick("ProcessingNumberParameterType", "Integer", QgsProcessingParameterNumber, "Integer")
DOUBLE = _pick("ProcessingNumberParameterType", "Double", QgsProcessingParameterNumber, "Double")
FOLDER = _pick("ProcessingFileParameterBehavior", "Folder", QgsProcessingParameterFile, "Folder")
OPTIONAL = _pick("ProcessingParameterFlag", "Optional", QgsProcessingParameterDefinition, "FlagOptional")
ADVANCED = _pick("ProcessingParameterFlag", "Advanced", QgsProcessingParameterDefinition, "FlagAdvanced")
CRITICAL = _pick("MessageLevel", "Critical", Qgis, "Critical")
