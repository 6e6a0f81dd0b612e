"""Terrain analysis of a surface's cells, arrays in and arrays out (no I/O): ``derivatives`` (slope, aspect,
hillshade, TRI, as gdaldem), ``viewshed`` (lines of sight, as gdal_viewshed) and ``travel`` (a walker's travel time:
Tobler's function and the shortest walks over the grid's graph). The commands that read and write rasters with them
are in gistools.products (terrain, viewshed, slope_classes, travel)."""
