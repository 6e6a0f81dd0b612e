"""Vector operations on shapely geometries: breaklines to polygons, polygon masks on grids."""
