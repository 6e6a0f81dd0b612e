"""The synthetic runway of the design spec (T8), in its local frame and rotated to Monte Mario coordinates.

Local frame: x chainage (m) from the low end, y offset (m, left +). 196 centre-line lights every 15 m
(x 0 ... 2925), z_CL = 230 + 0.0025 x, noise N(0, 0.02 m) laterally and vertically; other points on a
``grid`` m grid, x in [0, 2930], y in [-150, 150], ground = template design + ``cut`` + ``wave`` sin(2 pi x /
1000) + N(0, 0.01 m). Planted: 4 lateral light outliers (+5, -8, +12, +20 m), 1 light height outlier (+3 m),
1 duplicate (x, y, z) under a new id, 1 reused id. ``design_from="lights"`` draws the ground against the
grade of the surveyed (noisy) lights instead of the true one, the design the pipeline itself can know. ``breakpoint_lines`` adds survey lines along the
template's breakpoints (so the ground's kinks are surveyed and closed forms hold exactly). ``to_world`` rotates to EPSG:3003-like coordinates
(origin E 1 553 700, N 5 057 760, axis bearing 103.8 degrees).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .icao import template as make_template

__all__ = ["synthetic_runway", "to_world", "ORIGIN", "BEARING"]

ORIGIN = (1_553_700.0, 5_057_760.0)
BEARING = 103.8


def to_world(x, y, origin=ORIGIN, bearing=BEARING):
    b = np.radians(bearing)
    ux, uy = np.sin(b), np.cos(b)
    nx, ny = -uy, ux  # left of the axis
    return origin[0] + x * ux + y * nx, origin[1] + x * uy + y * ny


def synthetic_runway(seed: int = 8, *, grid: float = 10.0, cut: float = 0.2, wave: float = 0.5, x_end: float = 2930.0,
                     half_width: float = 150.0, code: str = "4E", kind: str = "icao", outliers: bool = True,
                     world: bool = True, noise: bool = True, breakpoint_lines: bool = False, lights: int = 196,
                     design_from: str = "truth"):
    """(points id, type, x, y, z; truth: planted anomalies id, reason). Coordinates in the world frame unless ``world`` is False."""
    rng = np.random.default_rng(seed)
    tpl = make_template(code, "precision", kind)
    lx = np.arange(lights) * 15.0
    ly = rng.normal(0, 0.02, lights) if noise else np.zeros(lights)
    lz = 230 + 0.0025 * lx + (rng.normal(0, 0.02, lights) if noise else 0)
    ys = np.arange(-half_width, half_width + 1e-9, grid)
    if breakpoint_lines:  # survey lines along the template's breakpoints too: the ground's kinks are surveyed
        ys = np.unique(np.concatenate([ys, np.asarray(tpl.breakpoints), -np.asarray(tpl.breakpoints)]))
    gx, gy = np.meshgrid(np.arange(0, x_end + 1e-9, grid), ys, indexing="ij")
    gx, gy = gx.ravel(), gy.ravel()
    # the design the ground is drawn against: the true grade line, or the grade the surveyed lights give
    grade = 230 + 0.0025 * gx if design_from == "truth" else np.interp(gx, lx, lz)
    gz = grade - tpl.drop(gy) + cut + wave * np.sin(2 * np.pi * gx / 1000)
    if noise:
        gz = gz + rng.normal(0, 0.01, gz.size)
    pts = pd.DataFrame({"id": np.concatenate([np.arange(1, lights + 1), 100001 + np.arange(gx.size)]),
                        "type": np.concatenate([np.ones(lights, int), np.full(gx.size, 2)]),
                        "x": np.concatenate([lx, gx]), "y": np.concatenate([ly, gy]), "z": np.concatenate([lz, gz])})
    truth = []
    if outliers:
        lateral = rng.choice(np.arange(3, lights - 3), 5, replace=False)
        for k, shift in zip(lateral[:4], (5.0, -8.0, 12.0, 20.0)):
            pts.loc[k, "y"] += shift
            truth.append((int(pts.at[k, "id"]), "light_off_axis"))
        pts.loc[lateral[4], "z"] += 3.0
        truth.append((int(pts.at[lateral[4], "id"]), "light_height"))
        dup_row = lights + int(rng.integers(0, gx.size))
        dup = pts.loc[[dup_row]].copy()
        dup["id"] = 20_000_001
        reused_row = lights + int(rng.integers(0, gx.size))
        pts.loc[reused_row, "id"] = 7  # the id of a light, at another position
        pts = pd.concat([pts, dup], ignore_index=True)
        truth += [(20_000_001, "duplicate"), (7, "renumbered")]
    if world:
        pts["x"], pts["y"] = to_world(pts["x"].to_numpy(), pts["y"].to_numpy())
    return pts, pd.DataFrame(truth, columns=["id", "reason"])
