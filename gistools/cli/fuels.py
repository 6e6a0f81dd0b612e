"""``gistools fuels``: canopy fuels (cover, height, base height, bulk density) and the FlamMap landscape."""

from __future__ import annotations

from .options import finish_batch, run_batch, tiles_command, tiles_counted


@tiles_command("fuels")
def fuels(inputs, out, cell_size, canopy_floor, height_percentile, layer, extinction, leaf_mass_area, running_mean,
          cbh_threshold, column, column_pulses, profile, bands, noise_floor, class_breaks, fuel_raster, fuel_codes, latitude,
          buffer, crs, jobs, overwrite, scheduler, quiet):
    """Canopy fuels of every tile of INPUTS (files, folders, globs or a .vpc) on LANDFIRE's 30 m lattice (100 ft on
    data in feet): OUT/<layer>/<tile>.tif and OUT/<layer>.vrt for elevation, cover, height, cbh, cbd and the strata
    shares; OUT/landscape.tif (8 int16 bands, LANDFIRE's order and encodings) and OUT/landscape.lcp (FlamMap);
    OUT/report.json. Neighbouring tiles' points are read, so tiles equal one merged run.

    \b
    Examples:
      $ gistools fuels sample_tiles --out out/fuels
      $ gistools fuels tiles --out f --cell-size 20m --fuel-codes 102,142,145 --jobs 2
    """
    from ..products.fuels import FuelsSettings, fuels_from_tiles

    settings = FuelsSettings(cell_size=cell_size, canopy_floor=canopy_floor, height_percentile=height_percentile,
                             layer=layer, extinction=extinction, leaf_mass_area=leaf_mass_area, running_mean=running_mean,
                             cbh_threshold=cbh_threshold, column=column, column_pulses=column_pulses, profile=profile,
                             bands=bands, noise_floor=noise_floor,
                             class_breaks=class_breaks, fuel_raster=fuel_raster, fuel_codes=fuel_codes,
                             latitude=latitude, buffer=buffer, crs=crs)
    report = run_batch(quiet, fuels_from_tiles, inputs, out, settings, jobs=jobs, scheduler=scheduler,
                       overwrite=overwrite)
    land = report.get("landscape") or {}
    finish_batch(report, f"{tiles_counted(report)}; landscape {land.get('lcp', 'not written')}"
                 f"; report: {out}/report.json")
