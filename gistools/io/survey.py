"""Runway survey points (step 0): a CSV or a point layer to a table id, type, x, y, z, line."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from .text import check_text_file, shown

__all__ = ["read_survey"]


_ALIASES = {"id": ("id",), "type": ("type", "kind", "code"), "x": ("x", "east", "easting"), "y": ("y", "north", "northing"),
            "z": ("z", "h", "height", "elevation")}


def _raw_table(text: str) -> tuple[pd.DataFrame, np.ndarray, object]:
    """(table as read, file line of each row, crs or None) of a CSV or a point layer."""
    from .vector import read_layer, split_layer_spec

    p = Path(text)
    if not p.exists():
        p = split_layer_spec(text)[0]  # a CSV as QGIS names it (survey.csv|layername=survey) is read as a CSV
    if p.suffix.lower() in (".csv", ".txt"):
        if not p.is_file():
            raise DataFileError("file not found", path=p, hint="Check the path")
        check_text_file(p, "survey table")
        try:
            df = pd.read_csv(p, sep=None, engine="python", encoding="utf-8-sig", skipinitialspace=True, keep_default_na=False)
        except (pd.errors.EmptyDataError, pd.errors.ParserError, csv.Error, UnicodeDecodeError) as err:
            raise DataFileError(f"not a readable CSV table ({str(err).splitlines()[0]})", path=p,
                                hint="Give a CSV with a header row id, type, x, y, z and one point per row") from None
        return df, np.arange(len(df)) + 2, None
    gdf = read_layer(text)
    df = pd.DataFrame(gdf.drop(columns="geometry"))
    low = {c.lower() for c in df.columns}
    if "x" not in low:
        df["x"], df["y"] = gdf.geometry.x, gdf.geometry.y
    if "z" not in low and gdf.geometry.has_z.all():
        df["z"] = gdf.geometry.z
    return df, np.arange(len(df)) + 1, gdf.crs


def _columns(df: pd.DataFrame, text: str, fields: dict | None = None) -> dict:
    """{field: column name} for id (optional), type, x, y, z: the chosen ``fields``, else by the usual names."""
    from .contacts import chosen_columns

    cols = {str(c).lower().strip(): c for c in df.columns}
    found = {k: next(cols[n] for n in names if n in cols) for k, names in _ALIASES.items() if any(n in cols for n in names)}
    found = chosen_columns(found, df.columns, fields, text)
    missing = [k for k in ("type", "x", "y", "z") if k not in found]
    if missing:
        raise InputError(f"no {', '.join(missing)} column (columns: {', '.join(map(str, df.columns))})", path=text,
                         hint="Name the columns id, type, x, y, z (type 1 = centre-line light, 2 = other)")
    return found


def _check_types(out: pd.DataFrame, lines, text: str) -> None:
    badtype = np.flatnonzero(~np.isin(out["type"], (1, 2)))
    if badtype.size:
        raise InputError(f"line {lines[badtype[0]]}: type {out['type'].iloc[badtype[0]]} is not 1 (centre-line light) or 2 (other)",
                         path=text, hint="Set type 1 for centre-line lights, 2 for every other point")
    if (out["type"] == 1).sum() < 2:
        raise InputError(f"{int((out['type'] == 1).sum())} centre-line light(s) (type 1); the centre line needs at least 2",
                         path=text, hint="Mark the centre-line lights with type 1")
    if (out["type"] == 2).sum() < 3:
        raise InputError("fewer than 3 ground points (type 2)", path=text, hint="The ground survey is the type 2 points")


def read_survey(path, fields: dict | None = None) -> tuple[pd.DataFrame, object]:
    """(points id, type, x, y, z, line; crs or None) from a CSV or a point layer (``file.gpkg:LAYER``); ``fields``: the
    columns of some fields where they are not named as usual (``{"type": "KIND", "z": "ELEV"}``)."""
    text = str(path)
    df, lines, crs = _raw_table(text)
    found = _columns(df, text, fields)
    out = pd.DataFrame({"line": lines})
    for k in ("type", "x", "y", "z") + (("id",) if "id" in found else ()):
        v = pd.to_numeric(df[found[k]], errors="coerce").to_numpy(np.float64)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise InputError(f"line {lines[bad[0]]}: {k} {shown(df[found[k]].iloc[bad[0]])} is not a number", path=text,
                             hint=f"Fix or remove that row ({bad.size} such row(s) in all)")
        out[k] = v
    if "id" not in out:
        out["id"] = np.arange(1, len(out) + 1)
    out["id"] = out["id"].astype(np.int64)
    out["type"] = out["type"].astype(np.int64)
    _check_types(out, lines, text)
    return out[["id", "type", "x", "y", "z", "line"]], crs
