"""The synthetic multi-layer aquifer of the design spec (section 3b), with analytic answers.

Local frame in km: u = (E - 1,500,000) / 1000, v = (N - 5,024,000) / 1000 on [0, 30]^2 (EPSG:3003).
Heights in m:  LS = 100 + 3v + 0.5u + 0.02 (u-15)^2 + 5 sin(2 pi u / 10);  AU = LS - T_A, T_A = 30 + 0.5v;
AD = AU - T_q, T_q = max(0, 12 - 0.8v);  AQ = AD - T_B, T_B = 50 + 0.05 (u-15)^2.
Planar variant: LS = 100 + 3v + 0.5u, T_A = 30 + 0.5v, T_q = 6, T_B = 50 + 0.1u.

Draws, in this order, from ``numpy.random.default_rng(seed)``: 991 collars ``uniform(0, 30, (991, 2))``;
``permutation(991)`` (a borehole reaches layer L when its rank < count_L: LS 991, AU 959, AD 723, AQ 354);
then the injected outliers: AU duplicates (``choice`` of 6 AU points; copies with new ids, z + 9, 10, 11,
12, 13, 13 m); AU wrong layer (10 points, z := LS - uniform(0, 5)); AD wrong layer (8, z := AQ +
uniform(0, 5)); AD placeholders (4, z := 1.0); AQ wrong layer (6, z := AD); AU outside the cloud (2 new
points, 3-5 km outside the square: side ``integers(0, 4)``, distance ``uniform(3, 5)``, position along
the side ``uniform(0, 30)``, z := AU there). The injected points are drawn among the non-corner
boreholes, each at most once. Four corner boreholes reach every layer, so every hull is the square.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["surfaces_uv", "synthetic_aquifer", "E0", "N0", "LAYERS", "COUNTS"]

E0, N0 = 1_500_000.0, 5_024_000.0
LAYERS = ("LS", "AU", "AD", "AQ")
COUNTS = {"LS": 991, "AU": 959, "AD": 723, "AQ": 354}
ID_BASE = {"LS": 0, "AQ": 1000, "AD": 2000, "AU": 3000}


def surfaces_uv(u, v, planar: bool = False) -> dict:
    """Heights (m) of the four surfaces at (u, v) km."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    if planar:
        ls = 100 + 3 * v + 0.5 * u
        ta, tq, tb = 30 + 0.5 * v, np.full_like(u, 6.0), 50 + 0.1 * u
    else:
        ls = 100 + 3.0 * v + 0.5 * u + 0.02 * (u - 15) ** 2 + 5 * np.sin(2 * np.pi * u / 10)
        ta, tq, tb = 30 + 0.5 * v, np.maximum(0.0, 12 - 0.8 * v), 50 + 0.05 * (u - 15) ** 2
    au = ls - ta
    ad = au - tq
    return {"LS": ls, "AU": au, "AD": ad, "AQ": ad - tb}


def synthetic_aquifer(seed: int = 2012, *, planar: bool = False, outliers: bool = True):
    """(points, truth): points has id, x, y, z, layer, borehole_id (EPSG:3003 metres);
    truth lists the injected outliers: id, layer, kind (dup, wrong_layer, outside_cloud)."""
    rng = np.random.default_rng(seed)
    uv = rng.uniform(0, 30, (991, 2))
    rank = rng.permutation(991)
    corners = np.array([[0, 0], [30, 0], [30, 30], [0, 30]], float)
    uv_all = np.vstack([uv, corners])
    rank_all = np.concatenate([rank, [-1, -1, -1, -1]])
    rows = []
    for layer in LAYERS:
        reach = np.flatnonzero(rank_all < COUNTS[layer])
        z = surfaces_uv(uv_all[reach, 0], uv_all[reach, 1], planar)[layer]
        ids = ID_BASE[layer] + 1 + np.arange(len(reach))
        rows.append(pd.DataFrame({"id": ids, "u": uv_all[reach, 0], "v": uv_all[reach, 1], "z": z, "layer": layer,
                                  "borehole_id": reach + 1}))
    pts = pd.concat(rows, ignore_index=True)
    truth = []
    if outliers:
        used: set[int] = set()

        def pick(layer, n):
            cand = pts.index[(pts["layer"] == layer) & (pts["borehole_id"] <= 991) & ~pts.index.isin(list(used))]
            chosen = rng.choice(np.asarray(cand), n, replace=False)
            used.update(int(c) for c in chosen)
            return chosen

        def surf(idx, layer):
            return surfaces_uv(pts.loc[idx, "u"].to_numpy(), pts.loc[idx, "v"].to_numpy(), planar)[layer]

        next_id = {layer: int(pts.loc[pts["layer"] == layer, "id"].max()) + 1 for layer in LAYERS}
        src = pick("AU", 6)
        dup = pts.loc[src].copy()
        dup["z"] = dup["z"].to_numpy() + np.array([9, 10, 11, 12, 13, 13], float)
        dup["id"] = next_id["AU"] + np.arange(6)
        next_id["AU"] += 6
        truth += [(int(i), "AU", "dup") for i in dup["id"]]
        idx = pick("AU", 10)
        pts.loc[idx, "z"] = surf(idx, "LS") - rng.uniform(0, 5, 10)
        truth += [(int(i), "AU", "wrong_layer") for i in pts.loc[idx, "id"]]
        idx = pick("AD", 8)
        pts.loc[idx, "z"] = surf(idx, "AQ") + rng.uniform(0, 5, 8)
        truth += [(int(i), "AD", "wrong_layer") for i in pts.loc[idx, "id"]]
        idx = pick("AD", 4)
        pts.loc[idx, "z"] = 1.0
        truth += [(int(i), "AD", "wrong_layer") for i in pts.loc[idx, "id"]]
        idx = pick("AQ", 6)
        pts.loc[idx, "z"] = surf(idx, "AD")
        truth += [(int(i), "AQ", "wrong_layer") for i in pts.loc[idx, "id"]]
        side = rng.integers(0, 4, 2)
        dist = rng.uniform(3, 5, 2)
        along = rng.uniform(0, 30, 2)
        ou = np.where(side == 0, -dist, np.where(side == 1, 30 + dist, along))
        ov = np.where(side == 2, -dist, np.where(side == 3, 30 + dist, along))
        out = pd.DataFrame({"id": next_id["AU"] + np.arange(2), "u": ou, "v": ov,
                            "z": surfaces_uv(ou, ov, planar)["AU"], "layer": "AU", "borehole_id": [9001, 9002]})
        truth += [(int(i), "AU", "outside_cloud") for i in out["id"]]
        pts = pd.concat([pts, dup, out], ignore_index=True)
    pts["x"] = E0 + 1000.0 * pts["u"]
    pts["y"] = N0 + 1000.0 * pts["v"]
    points = pts[["id", "x", "y", "z", "layer", "borehole_id"]].reset_index(drop=True)
    return points, pd.DataFrame(truth, columns=["id", "layer", "kind"])
