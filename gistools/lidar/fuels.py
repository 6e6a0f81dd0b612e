"""Canopy fuels of a cell from its returns' heights above ground (pure functions over numpy arrays).

The vertical profile, in layers of thickness dz from the ground up, by one of two estimators. The bias-corrected
ratio estimator (Pimont et al. 2018, for vertical pulses): every return above the ground in a layer is an
interception, divided by k times the pulses' path through the layer down to their last return, less the bias that
the paths cut short by a last return cause; NaN in a layer no pulse reaches. MacArthur and Horn (1969): ``N_in(i)``
is the number of pulses that reach layer i (first returns in it or below it, ground returns included) and
``N_out(i)`` the number that leave it (first returns below it); ``LAD_i = ln(N_in / N_out) / (k dz)`` (Beer-Lambert,
extinction k); a layer no pulse leaves takes ``N_out = 1``, a layer no pulse reaches has LAD 0. Bulk density is LAD
times the leaf mass per area (LMA). Canopy bulk density (CBD) is the largest centred running mean of the bulk
density above the canopy floor, canopy base height (CBH) the middle of the lowest layer whose running mean exceeds a
threshold (Reinhardt and Crookston 2003, FVS-FFE; LANDFIRE). Canopy cover is the share of first returns above the
canopy floor (percent), canopy height a high percentile of the canopy returns' heights.

Every height is in the heights' unit; the constants arrive as arguments (gistools.parameters.fuels declares them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["layer_counts", "lad_profile", "ratio_profile", "running_mean", "cbd_cbh", "horn_slope_aspect",
           "fuel_model_codes"]


def layer_counts(cell, n: int, h, ground, *, dz: float, layers: int | None = None) -> np.ndarray:
    """(n cells, L layers + 1) counts of first returns: column 0 the ground returns (``ground`` True: below every
    layer), column i + 1 the returns of layer i = [i dz, (i + 1) dz); heights below 0 count in layer 0."""
    cell = np.asarray(cell, np.int64)
    h = np.asarray(h, np.float64)
    ground = np.asarray(ground, bool)
    k = np.where(ground, 0, np.floor(np.maximum(h, 0.0) / dz).astype(np.int64) + 1)
    width = int(k.max(initial=0)) + 1 if layers is None else layers + 1
    k = np.minimum(k, width - 1)
    return np.bincount(cell * width + k, minlength=n * width).reshape(n, width)


def lad_profile(counts: np.ndarray, *, dz: float, k: float) -> np.ndarray:
    """Leaf area density (m2/m3 when heights are metres) per cell and layer from :func:`layer_counts`:
    ``ln(N_in / N_out) / (k dz)``; N_out = 0 taken as 1, layers no pulse reaches 0."""
    below = np.cumsum(counts, axis=1)  # below[:, j]: returns in columns 0..j
    n_out = below[:, :-1].astype(np.float64)  # leaving layer i: ground + layers below i
    n_in = below[:, 1:].astype(np.float64)  # reaching layer i: those and layer i's own
    with np.errstate(divide="ignore", invalid="ignore"):
        lad = np.where(n_in > 0, np.log(n_in / np.maximum(n_out, 1.0)), 0.0) / (k * dz)
    return lad


def ratio_profile(cell, n: int, h, ground, last, *, dz: float, k: float, layers: int | None = None) -> np.ndarray:
    """Leaf area density per cell (a profile column) and layer: the bias-corrected maximum-likelihood estimator of
    Pimont et al. (2018) for vertical pulses, NaN in a layer no pulse reaches.

    Every return above the ground is an interception; a pulse's path in a layer runs from the layer's top down to
    its last return (the whole layer when it ends on the ground or below). With N the returns of layer i, S the
    pulses' path through it and, for the pulses whose last return lies in it, z their path from the layer's top to
    that return: ``k LAD_i = N / S - sum(z) / S**2``. N / S is the ratio (maximum-likelihood) estimator; the second
    term removes its bias, which a path cut short by the interception that ends it causes (the ratio estimator of a
    layer one pulse reaches with one return left is 1 / z, unbounded; the corrected one 0). Heights and ``dz`` share
    a unit; the result is per that unit (the caller divides by the unit's metres for m2/m3). ``last``: True for each
    pulse's last return."""
    cell = np.asarray(cell, np.int64)
    h = np.asarray(h, np.float64)
    ground = np.asarray(ground, bool)
    hv = np.where(ground, -np.inf, np.maximum(h, 0.0))
    top = int(np.floor(hv[np.isfinite(hv)].max(initial=0.0) / dz)) + 1 if layers is None else layers
    veg = ~ground
    li = np.minimum(np.floor(hv[veg] / dz).astype(np.int64), top - 1)
    events = np.bincount(cell[veg] * top + li, minlength=n * top).reshape(n, top).astype(np.float64)
    # a pulse's path in layer i: dz in the layers above its last return's layer, (i + 1) dz - h in that layer
    lasts = np.asarray(last, bool)
    hl, cl = hv[lasts], cell[lasts]
    hl0 = np.where(np.isfinite(hl), hl, 0.0)
    lj = np.where(np.isfinite(hl), np.minimum(np.floor(hl0 / dz), top - 1), -1).astype(np.int64)
    width = top + 1  # column 0: the pulses that end on the ground, below every layer
    ended = np.bincount(cl * width + lj + 1, minlength=n * width).reshape(n, width)
    inside = np.bincount(cl * width + lj + 1, weights=np.where(lj >= 0, (lj + 1) * dz - hl0, 0.0),
                         minlength=n * width).reshape(n, width)
    below = np.cumsum(ended, axis=1)[:, :-1]  # pulses whose last return is below layer i
    cut = inside[:, 1:]  # sum(z): the paths of the pulses whose last return is in layer i
    exposure = dz * below + cut
    reached = below + ended[:, 1:]  # pulses with a path in layer i
    with np.errstate(divide="ignore", invalid="ignore"):
        att = (events * exposure - cut) / exposure ** 2
        return np.where(reached > 0, np.where(exposure > 0, att, 0.0) / k, np.nan)


def running_mean(profile: np.ndarray, window: int) -> np.ndarray:
    """Centred running mean over ``window`` layers (odd; outside the profile counts as 0), along the last axis. The
    sums are differences of one cumulative sum whose ends are clipped to the profile: a window wider than the
    profile costs no more than the profile."""
    window = max(1, int(window) | 1)
    layers = profile.shape[-1]
    half = min(window // 2, layers)  # a half-window past the profile's end reaches as far
    c = np.concatenate([np.zeros(profile.shape[:-1] + (1,)), np.cumsum(profile, axis=-1)], axis=-1)
    i = np.arange(layers)
    return (c[..., np.minimum(i + half + 1, layers)] - c[..., np.maximum(i - half, 0)]) / float(window)


def cbd_cbh(bulk: np.ndarray, *, dz: float, floor: float, window: int,
            threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """(CBD, CBH) per cell from the bulk density profile (cells x layers): the layers whose bottom is below
    ``floor`` are set to 0, the rest smoothed by :func:`running_mean`; CBD its maximum, CBH the middle of the
    lowest layer above the floor whose mean exceeds ``threshold`` (0 where none does)."""
    n, layers = bulk.shape
    bottoms = np.arange(layers) * dz
    canopy = bottoms >= floor - 1e-9 * dz
    smooth = running_mean(np.where(canopy, bulk, 0.0), window) if layers else bulk
    smooth = np.where(canopy, smooth, 0.0)
    cbd = smooth.max(axis=1, initial=0.0)
    over = smooth > threshold
    first = np.argmax(over, axis=1)
    cbh = np.where(over.any(axis=1), bottoms[np.minimum(first, max(layers - 1, 0))] + dz / 2 if layers else 0.0, 0.0)
    return cbd, cbh


def horn_slope_aspect(elev: np.ndarray, cell: float, *, z_per_xy: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(slope in degrees, aspect in degrees clockwise from north, -1 where flat) of a north-up elevation grid by
    Horn's (1981) 3 x 3 differences, as ``gdaldem slope`` / ``gdaldem aspect`` compute them; NaN where a neighbour
    is NaN; the outer ring from the edge cells repeated. ``z_per_xy``: metres of a z unit over metres of an xy unit."""
    e = np.pad(np.asarray(elev, np.float64) * z_per_xy, 1, mode="edge")
    a, b, c = e[:-2, :-2], e[:-2, 1:-1], e[:-2, 2:]
    d, f = e[1:-1, :-2], e[1:-1, 2:]
    g, h, i = e[2:, :-2], e[2:, 1:-1], e[2:, 2:]
    dx = ((c + 2 * f + i) - (a + 2 * d + g)) / (8.0 * cell)
    dy = ((g + 2 * h + i) - (a + 2 * b + c)) / (8.0 * cell)
    slope = np.degrees(np.arctan(np.hypot(dx, dy)))
    angle = np.degrees(np.arctan2(dy, -dx))
    aspect = np.where(angle < 0, 90.0 - angle, np.where(angle > 90.0, 450.0 - angle, 90.0 - angle))
    aspect = np.where((dx == 0) & (dy == 0), -1.0, aspect)
    return slope, aspect


def fuel_model_codes(share, breaks, codes) -> np.ndarray:
    """Scott and Burgan codes from the share (0-1) of the returns up to 2 m that are above the noise floor: below
    ``breaks[0]`` light, below ``breaks[1]`` medium, else heavy -> ``codes`` (light, medium, heavy); -9999 where NaN."""
    share = np.asarray(share, np.float64)
    cls = np.digitize(np.nan_to_num(share, nan=0.0), breaks)
    return np.where(np.isfinite(share), np.asarray(codes, np.float64)[cls], -9999.0)
