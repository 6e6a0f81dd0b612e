"""The help text of every algorithm (the right panel of its dialog, above its parameters and outputs), by the
algorithm's name: the words of the plugin in one place, to review them against the documentation and to
translate them."""

HELP = {
    "aquifer": (
        "Borehole layer contacts (points with x, y, z and a layer field) to a 3D aquifer model (gistools aquifer "
        "model): outliers flagged with their rule, one TIN per layer, boundaries, matched walls, a closed mesh per "
        "unit, thickness rasters and exact volumes (report.json). Layers are named top to bottom."),
    "aquiferquery": (
        "Height of every surface and thickness of every unit of a model (the output folder of 'Aquifer model') at a "
        "point: TIN (default, nothing outside the boundary), k-nearest mean or IDW."),
    "webmap": (
        "One self-contained HTML page of a shrub chain's output folder (gistools webmap): the class polygons "
        "(simplified within half a cell, in WGS84) with Leaflet inlined, a legend, a scale bar, the parameters that "
        "made the map and a popup per polygon (class, area in acres and hectares, tile). It asks the network for "
        "nothing unless a basemap URL is given, so it works from a USB stick or a tablet in the field. A county past "
        "the size limit is split by tile into parts, the first page linking them. Given the output folders of "
        "gistools travel, viewshed or fuels, the page also draws their layers (switchable): the isochrones with a "
        "legend in minutes and the points last seen, the travel time under the cursor, the cells seen "
        "(semi-transparent) and the canopy base height classes. The page is written into the folder (shrub_map.html) "
        "and listed in the Results Viewer, which opens it in the browser."),
    "scene": (
        "The surface of a shrub chain's output folder as a glTF binary mesh (gistools scene): the DSM (the DEM where "
        "the DSM has no value) in metres with the shrub classes as vertex colours, x east, y up, z south from the "
        "mosaic's south-west corner (origin and CRS in the asset's extras; scene.prj and scene.wld beside it). QGIS "
        "3D, Cesium and Blender open it. Decimated (every k-th cell) to stay under the size given; heights can be "
        "exaggerated."),
    "mapbook": (
        "A PDF of a shrub chain's output folder to print for field teams (gistools mapbook): a page per tile of the "
        "tile index (each fitted to the page), or per sheet of a grid at a scale, each with the classes, roads and "
        "water, a coordinate grid, a locator map, the legend, a scale bar, a north arrow and the parameters; with a "
        "gistools travel folder, the isochrones and points last seen on every page; with a gistools viewshed folder, "
        "the cells seen; with a gistools fuels folder, a last page of the canopy base height classes. The PDF opens "
        "from the Results Viewer."),
    "ground": (
        "Ground (2) and noise (7 low, 18 high) classes of LAS/LAZ tiles (gistools ground): noise first (isolated "
        "voxels or a statistical rule, and points far below the ground surface), then ground: by default adaptive "
        "(SMRF and a TIN of its ground, its thresholds from the survey's measured noise, or a tight set under a "
        "canopy), or the Simple Morphological Filter (SMRF), SMRF+TIN or the Cloth Simulation Filter (CSF). "
        "Only the classification changes; every "
        "point, its order and every other attribute stay. Points of other classes (water, buildings) keep theirs. "
        "Neighbouring tiles' points are read within a buffer, so tiles equal one merged run. Writes one file per tile"
        " and a virtual point cloud (ground.vpc) indexing them; lengths take a unit (m, ft, ftUS)."),
    "normalize": (
        "Height above ground of every point (gistools normalize): z minus the TIN of the ground points (classes 2 and"
        " 9) of the tile and its neighbours within the buffer, so tiles equal one TIN of all their ground (PDAL "
        "filters.hag_delaunay, lidR normalize_height(tin())). Written as a HeightAboveGround dimension (float32, in "
        "the tiles' vertical unit) or as z. Optionally sets vegetation classes 3 / 4 / 5 by the height bands, and "
        "road surface (11) and water (9) inside the breaklines' polygons. Writes one file per tile and "
        "normalized.vpc."),
    "chm": (
        "Canopy height model of LAS/LAZ tiles (gistools chm; lidR rasterize_canopy): the first returns' heights above"
        " the TIN of the ground, gridded as the highest return per cell (p2r), a TIN of the returns, or pit-free "
        "(Khosravipour et al. 2014: TINs of the returns above a series of height thresholds, long triangles dropped, "
        "stacked by their maximum, so returns deep in a crown leave no pit). Neighbouring tiles' points are read, so "
        "tiles equal one merged run. Writes chm/<tile>.tif and chm.vrt (loaded); the log gives the pits left (cells "
        "more than 1 m below all 8 neighbours)."),
    "fuels": (
        "Canopy fuels of LAS/LAZ tiles (gistools fuels) on LANDFIRE's 30 m lattice (100 ft on data in feet): ground "
        "elevation, canopy cover (share of first returns above 2 m, percent), canopy height, canopy base height and "
        "canopy bulk density from the leaf area density profile of the returns (1 m layers, columns of 20 pulses, "
        "bias-corrected ratio estimator, bulk density = leaf area density x leaf mass per area, 3 m running mean; "
        "base height where it first exceeds 0.012 kg/m3, as FVS and LANDFIRE), and the surface strata shares of the "
        "height bands. Writes a VRT per layer, landscape.tif (eight int16 bands in LANDFIRE's order and encodings) "
        "and landscape.lcp (FlamMap's landscape file, loaded). Neighbouring tiles' points are read, so tiles equal "
        "one merged run."),
    "dsm": (
        "Digital surface model: the highest first return in each cell, on a lattice snapped to multiples of the cell "
        "size so tiles mosaic without seams. Also the class of that return (TOP_CLASS), which the height bands use to"
        " keep bare ground out of the low shrub band."),
    "dem": (
        "Digital elevation model from ground points (class 2): a Delaunay TIN evaluated at cell centres, reading "
        "ground points of neighbouring tiles so tile edges do not show; water (class 9) cells stay empty."),
    "rasters": (
        "DSM, DEM and nDSM (= DSM - DEM) of every tile, each tile decoded once (gistools rasters)."),
    "runway": (
        "A runway survey (points with a type field: 1 = centre-line light, 2 = other, and z) and the aerodrome "
        "reference code to the centre line, an ICAO design model, cross sections, signed cut / fill areas, the area "
        "diagram and the Brückner (mass-haul) curve with balance points (gistools runway)."),
    "shrubchain": (
        "The whole shrub chain on a tile folder (gistools shrub): DSM / DEM / nDSM, height bands, road and water "
        "clipping, vegetation density, light / medium / heavy classes, class polygons, a printable map and "
        "report.json, tile by tile (resumable, one bad tile is reported and the others go on)."),
    "ndsm": (
        "Normalised DSM: heights above ground = DSM - DEM, cell by cell, on the DSM's grid (the DEM must share it)."),
    "bands": (
        "Height bands of an nDSM: 0 = B0 ground (h <= noise floor, or topped by a ground / water return), 1 = B1 0-1 "
        "m, 2 = B2 1-2 m, 3 = B3 2-6 m, 4 = above, 255 = nodata. Thresholds are in metres and converted to the nDSM's"
        " vertical unit (6 m = 19.685 ftUS); 'text_literal' uses the dissertation's printed feet."),
    "breaklines": (
        "The dissertation's Split (by the tile index) and Feature To Polygon: edge-of-pavement lines and hydrographic"
        " breaklines are split by each tile footprint, noded with a snapping tolerance and polygonised; faces wider "
        "than the maximum width are blocks between roads, not road. Water bodies (islands stay holes) and buffered "
        "single-line hydro features join the water polygons."),
    "clip": (
        "Vegetation = height band minus road minus water, by cell centre (the dissertation's Clip and Select By "
        "Location on Raster To Point output). Codes: 0 none, 1-3 band of a vegetation cell, 4 road, 5 water, 255 "
        "nodata. Vegetation inside wetland polygons is a second output."),
    "density": (
        "Point density of vegetation cells (each stands for one Raster To Point point) over a circle: cover = share "
        "of the cell centres within the radius that are vegetation (0-1); density = points per CRS area unit. Blocks "
        "read a halo of the radius, so block and tile edges do not show."),
    "classify": (
        "Light / medium / heavy shrub classes from cover: 0 none, 1 light, 2 medium, 3 heavy, 4 road, 5 water, 255 "
        "nodata. 'breaks' uses the given cover breaks (default 0.3, 0.7), 'quantile' and 'jenks' compute them."),
    "structure": (
        "A building's point cloud (ID X Y Z text, or LAS/LAZ) of floor outlines and floor plates to levels, clusters,"
        " loops with holes, matched walls and a watertight, consistently wound mesh (PLY, OBJ), with the loops as 3D "
        "lines (gistools structure). Parameters are estimated from the data unless given."),
    "terrain": (
        "Slope (degrees and percent), aspect (degrees clockwise from north, flat cells nodata), hillshade and Riley's"
        " terrain ruggedness index of a DEM, as gdaldem computes them (Horn's method). The DEM may be a VRT mosaic of"
        " tiles (the dem.vrt of the rasters algorithm): it is read block by block with a one-cell halo, so tiles join"
        " without seams. Cells on the raster's edge or beside nodata are nodata, as gdaldem without -compute_edges. "
        "Elevations in another unit than x and y are scaled (gdaldem -s). Writes slope.tif, slope_percent.tif, "
        "aspect.tif, hillshade.tif and tri.tif (loaded) and report.json."),
    "viewshed": (
        "Cells seen from one or several observers, as GDAL's gdal_viewshed (Wang et al. 2000), on a surface raster: "
        "the DSM, where trees and buildings hide a person, or the DEM. Observers are X,Y positions in the raster's "
        "CRS (several separated by ;) and / or a point layer. Writes viewshed.tif (1 seen by at least one observer, 0"
        " hidden, 255 nodata; loaded) and viewshed_count.tif (how many observers see each cell). Earth curvature and "
        "refraction are optional, as gdal_viewshed -cc."),
    "info": (
        "Header, CRS, horizontal and vertical units and point counts by class and return of LAS/LAZ tiles (gistools "
        "info). A tile that cannot be read is reported, the others are still listed."),
    "points": (
        "The dissertation's LAS To Multipoint: per tile, a point layer (GeoPackage, or GeoParquet) with x, y, z, "
        "class, return number and intensity of the chosen classes and returns, streamed in chunks. Non-ground: "
        "classes 1,2 first returns; ground: class 2, every return."),
    "travel": (
        "Minutes for a walker to reach every cell of a DEM from the nearest point last seen: Tobler's hiking function"
        " on the slope along each step (uphill and downhill differ), times a factor per shrub class of the shrub "
        "chain, roads clear, water impassable (or waded); isochrone polygons with their areas and isochrone bands "
        "(gistools travel)."),
    "search_plan": (
        "The search plan of a lost person from the point last seen (gistools search-plan): the probability of area of"
        " the category's distance rings (Koester's Lost Person Behavior) weighted near roads, trails, water, "
        "drainages and ridges; cliffs, water and thickets as barriers; segments bounded by roads, trails, drainages, "
        "ridges and thickets; the probability of detection of the searcher-hours given; the quickest routes from the"
        " staging points and a litter carry out."),
}
