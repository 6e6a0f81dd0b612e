"""gistools for QGIS: the gistools library as a Processing provider (id ``gistools``)."""


def classFactory(iface):  # noqa: N802 (QGIS's name)
    from .plugin import GistoolsPlugin

    return GistoolsPlugin(iface)
