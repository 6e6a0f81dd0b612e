"""The shrub chain's settings: one place for its parameters and their defaults (the dissertation's values).

The chain (``tasks.shrub``), the one-step functions (``tasks.steps``), the CLI options and the QGIS
algorithms all take their defaults from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import InputError
from ..lidar.shrub import CLASS_METHODS, DEFAULT_BREAKS
from ..validation import check_breaks, check_length
from .rasters import RasterSettings

__all__ = ["ShrubSettings", "DEFAULTS"]


@dataclass(frozen=True)
class ShrubSettings:
    """Parameters of the shrub chain. Lengths take a unit ("25ft", "0.1m") or are CRS units.

    bands: "exact" (1, 2, 6 m) or "text_literal" (the dissertation's 3.28 / 6.56 / 19.658 ft),
    or band_breaks_m = three heights in metres. noise_floor: heights up to it are bare (B0).
    snap: breakline snapping (0.2 ft, the dissertation's cluster tolerance). max_road_width /
    max_hydro_width: faces wider than this are blocks between lines, not road / river.
    single_line_width: width given to single-line hydro features. radius: density circle.
    density_bands: the bands whose vegetation counts (default B1-B3; the dissertation used B1).
    classify: "breaks" (class_breaks on cover), "quantile" or "jenks". raster: the rasters' settings (the DSM's
    pinholes are left by default: filling them raises the cover of sparse data, README "The shrub chain").
    """

    raster: RasterSettings = field(default_factory=RasterSettings)
    bands: str = "exact"
    band_breaks_m: tuple[float, float, float] | None = None
    noise_floor: str | float = "0.1m"
    snap: str | float = "0.2ft"
    max_road_width: str | float = "60ft"
    max_hydro_width: str | float = "500ft"
    single_line_width: str | float = "8ft"
    radius: str | float = "25ft"
    density_bands: tuple[int, ...] = (1, 2, 3)
    classify: str = "breaks"
    class_breaks: tuple[float, float] = DEFAULT_BREAKS
    tile_field: str = "TILE_ID"

    def validate(self):
        """Every option checked before anything is read or written (validation layer)."""
        self.raster.validate()
        if self.classify not in CLASS_METHODS:
            raise InputError(f"--classify {self.classify!r} is not one of {', '.join(CLASS_METHODS)}")
        if not self.density_bands or any(b not in (1, 2, 3) for b in self.density_bands):
            raise InputError(f"density bands {self.density_bands} must be among 1, 2, 3", hint="e.g. --density-bands 1,2,3")
        from ..lidar.bands import PRESETS

        if self.bands not in PRESETS:
            raise InputError(f"--bands {self.bands!r} is not one of {', '.join(PRESETS)}", hint="Use --bands exact")
        if self.band_breaks_m is not None:
            check_breaks(self.band_breaks_m, "--band-breaks", count=3, low=0, high=math.inf, low_open=True, example="1,2,6")
        check_breaks(self.class_breaks, "--breaks", count=2, low=0, high=1, example="0.3,0.7")
        check_length(self.noise_floor, "--noise-floor", allow_equal=True, example="0.1m")
        check_length(self.snap, "--snap", allow_equal=True, example="0.2ft")
        check_length(self.radius, "--radius", example="25ft")
        check_length(self.max_road_width, "--max-road-width", example="60ft")
        check_length(self.max_hydro_width, "max_hydro_width", example="500ft")
        check_length(self.single_line_width, "single_line_width", example="8ft")


DEFAULTS = ShrubSettings()  # the defaults, for signatures and option declarations
