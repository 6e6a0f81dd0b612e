"""The shrub chain's settings. Each parameter, with its default (the dissertation's values), is declared once in
gistools.parameters.shrub; the chain (``products.shrub``), the one-step functions (``products.steps``), the CLI options and
the QGIS algorithms take them from there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import InputError
from ..parameters import check_all, choices, default_for, option, setting_default
from ..validation import check_breaks
from .rasters import RasterSettings

__all__ = ["ShrubSettings", "DEFAULTS"]

@dataclass(frozen=True)
class ShrubSettings:
    """Parameters of the shrub chain. Lengths take a unit ("25ft", "0.1m") or are CRS units. Each is declared once,
    with its default, in gistools.parameters.shrub.

    bands: "exact" (1, 2, 6 m) or "text_literal" (the dissertation's 3.28 / 6.56 / 19.658 ft),
    or band_breaks_m = three heights in metres. noise_floor: heights up to it are bare (B0).
    snap: breakline snapping (0.2 ft, the dissertation's cluster tolerance). max_road_width /
    max_hydro_width: faces wider than this are blocks between lines, not road / river.
    single_line_width: width given to single-line hydro features. radius: density circle.
    density_bands: the bands whose vegetation counts (default B1-B3; the dissertation used B1).
    classify: "breaks" (class_breaks on cover), "quantile" or "jenks". raster: the rasters' settings (the DSM's
    pinholes are left by default: filling them raises the cover of sparse data, docs/commands/shrub.md).
    """

    raster: RasterSettings = field(default_factory=RasterSettings)
    bands: str = default_for("bands")
    band_breaks_m: tuple[float, float, float] | None = default_for("band_breaks_m")
    noise_floor: str | float = default_for("noise_floor")
    # lengths that follow the data's unit (None: 0.2 ft / 0.06 m, 60 ft / 18 m, 500 ft / 150 m, 8 ft / 2.5 m,
    # 25 ft / 7.5 m), set once the tiles' CRS is known (gistools.parameters.in_data_units)
    snap: str | float | None = setting_default("snap")
    max_road_width: str | float | None = setting_default("max_road_width")
    max_hydro_width: str | float | None = setting_default("max_hydro_width")
    single_line_width: str | float | None = setting_default("single_line_width")
    radius: str | float | None = setting_default("radius")
    density_bands: tuple[int, ...] = default_for("density_bands")
    classify: str = default_for("classify")
    class_breaks: tuple[float, float] = default_for("class_breaks")
    tile_field: str = default_for("tile_field")

    def validate(self):
        """Every option checked before anything is read or written (validation layer): each field against its
        declaration (gistools.parameters), then what a declaration does not say."""
        self.raster.validate()
        check_all(self)  # every field with a declaration of its name
        bands = choices("density_bands")
        if not self.density_bands or any(b not in bands for b in self.density_bands):
            raise InputError(f"{option('density_bands', tuple(self.density_bands))} must be among "
                             f"{', '.join(map(str, bands))}", hint=f"e.g. {option('density_bands', bands)}")
        if self.band_breaks_m is not None:  # heights above the ground: the first one above 0
            check_breaks(self.band_breaks_m, "band_breaks_m", count=3, low=0, high=math.inf, low_open=True,
                         example="1,2,6")


DEFAULTS = ShrubSettings()  # the defaults, for signatures and option declarations
