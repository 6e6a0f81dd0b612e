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
FILE = _pick("ProcessingSourceType", "File", QgsProcessing, "TypeFile")
INTEGER = _pick("ProcessingNumberParameterType", "Integer", QgsProcessingParameterNumber, "Integer")
DOUBLE = _pick("ProcessingNumberParameterType", "Double", QgsProcessingParameterNumber, "Double")
FOLDER = _pick("ProcessingFileParameterBehavior", "Folder", QgsProcessingParameterFile, "Folder")
OPTIONAL = _pick("ProcessingParameterFlag", "Optional", QgsProcessingParameterDefinition, "FlagOptional")
ADVANCED = _pick("ProcessingParameterFlag", "Advanced", QgsProcessingParameterDefinition, "FlagAdvanced")
CRITICAL = _pick("MessageLevel", "Critical", Qgis, "Critical")


def data_providers() -> set[str]:
    """The data providers of the running QGIS (read once QGIS is initialised)."""
    from qgis.core import QgsProviderRegistry

    return set(QgsProviderRegistry.instance().providerList())


def reads_vpc() -> bool:
    """Whether this QGIS opens virtual point clouds (.vpc) as layers: its "vpc" provider, QGIS 3.32+."""
    return "vpc" in data_providers()


def reads_las() -> bool:
    """Whether this QGIS opens LAS/LAZ files as point cloud layers: its PDAL provider ("pdal"; Debian's 3.22 has none)."""
    return "pdal" in data_providers()
