"""Reading layer contacts (S0): one table ``id, x, y, z, layer[, borehole_id]`` or one file per layer.

Accepted: a CSV (comma, semicolon or tab), a point layer (GeoPackage ``file.gpkg:LAYER``,
shapefile) whose z comes from a ``z`` column or the 3D geometry, or the dissertation's
four-file form (``ID East North Height`` per layer, whitespace or comma separated, the layer
named by the file: ``LS=LSInput.txt``). Every row is checked: a malformed row, a layer not in
the order, a non-numeric value is refused naming the file, the line and the fix.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd
import pyproj

from ..errors import DataFileError, InputError
from ..parameters import option
from .text import check_text_file, shown
from .vector import split_layer_spec
from .points import chosen_crs
from .text import read_id_xyz

__all__ = ["read_contacts", "ALIASES", "chosen_columns"]

# accepted column names (lower case) for each field
ALIASES = {
    "id": ("id", "point_id", "fid_", "pid"),
    "x": ("x", "east", "easting", "e"),
    "y": ("y", "north", "northing", "n"),
    "z": ("z", "height", "height_m", "elevation", "elev", "h"),
    "layer": ("layer", "surface", "horizon", "formation", "unit"),
    "borehole_id": ("borehole_id", "borehole", "well", "hole_id", "bh"),
}


def _find(columns, field):
    low = {str(c).strip().lower(): c for c in columns}
    for name in ALIASES[field]:
        if name in low:
            return low[name]
    return None


def chosen_columns(found: dict, columns, fields: dict | None, path) -> dict:
    """``found`` ({field: column} by the usual names) with the columns the user chose for some fields (``fields``,
    e.g. {"z": "ELEV"}: QGIS's field pickers, --z-field); a chosen column that is not in the table is refused."""
    out = dict(found)
    for name, column in (fields or {}).items():
        if column in (None, ""):
            continue
        if column not in list(columns):
            raise InputError(f"the {name} field {column!r} is not a column (columns: {', '.join(map(str, columns))})",
                             path=path, hint=f"Choose the column that holds the {name}")
        out[name] = column
    return out


def _numbers(values, path, field, lines) -> np.ndarray:
    if np.issubdtype(np.asarray(values).dtype, np.number):
        out = np.asarray(values, np.float64)
    else:
        out = pd.to_numeric(pd.Series(values), errors="coerce").to_numpy(np.float64)
    bad = np.flatnonzero(~np.isfinite(out))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"line {lines[k]}: {field} {shown(values[k])} is not a number", path=path,
                         hint=f"Fix or remove that row ({bad.size} such row(s) in all)")
    return out


def _sniff(path: Path) -> str:
    head = path.read_text(encoding="utf-8-sig", errors="replace")[:4096]
    try:
        return csv.Sniffer().sniff(head, delimiters=",;\t").delimiter
    except csv.Error:
        return ","


TABLE_SUFFIXES = (".csv", ".txt", ".tsv", ".xyz", ".dat")


def _read_table_spec(spec: str):
    return _read_table(Path(spec), spec)


def _read_table(path: Path, spec: str | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """A CSV or vector layer as a frame of strings, with the file line of each row."""
    text = spec or str(path)
    if spec is None and path.suffix.lower() in TABLE_SUFFIXES:
        check_text_file(path, "contacts table")
        try:
            df = pd.read_csv(path, sep=_sniff(path), encoding="utf-8-sig", skipinitialspace=True, keep_default_na=False, low_memory=False)
        except Exception as err:
            raise DataFileError(f"cannot read as CSV ({str(err).splitlines()[0] if str(err) else type(err).__name__})",
                                path=path, hint="Give a CSV with a header row") from None
        return df, np.arange(len(df)) + 2
    from .vector import read_layer

    gdf = read_layer(text)
    df = pd.DataFrame(gdf.drop(columns="geometry"))
    geom = gdf.geometry
    if _find(df.columns, "x") is None:
        df["x"] = geom.x
        df["y"] = geom.y
    if _find(df.columns, "z") is None and geom.has_z.all():
        df["z"] = geom.z
    df.attrs["crs"] = gdf.crs
    return df, np.arange(len(df)) + 1


def _from_frame(df, lines, path, swap_xy, fields=None) -> pd.DataFrame:
    if len(df) == 0:
        raise InputError("the table holds no contacts (a header only, or empty)", path=path,
                         hint="One row per contact: id, x, y, z, layer")
    cols = chosen_columns({f: _find(df.columns, f) for f in ALIASES}, df.columns, fields, path)
    missing = [f for f in ("x", "y", "z", "layer") if cols[f] is None]
    if missing:
        raise InputError(f"no {', '.join(missing)} column (columns: {', '.join(map(str, df.columns))})", path=path,
                         hint="Name the columns id, x, y, z, layer (borehole_id optional)")
    out = pd.DataFrame({
        "x": _numbers(df[cols["x"]].to_numpy(), path, "x", lines),
        "y": _numbers(df[cols["y"]].to_numpy(), path, "y", lines),
        "z": _numbers(df[cols["z"]].to_numpy(), path, "z", lines),
        "layer": df[cols["layer"]].astype(str).str.strip().to_numpy(),
    })
    if cols["id"] is not None:
        out.insert(0, "id", _numbers(df[cols["id"]].to_numpy(), path, "id", lines).astype(np.int64))
    else:
        out.insert(0, "id", np.arange(1, len(out) + 1, dtype=np.int64))
    if cols["borehole_id"] is not None:
        out["borehole_id"] = df[cols["borehole_id"]].astype(str).to_numpy()
    if swap_xy:
        out["x"], out["y"] = out["y"].to_numpy(), out["x"].to_numpy()
    out["line"] = lines
    return out


def _read_layer_file(path: Path, layer: str, swap_xy: bool) -> pd.DataFrame:
    """The dissertation's per-layer file: ``ID East North Height`` rows (a header row is allowed)."""
    a, lines = read_id_xyz(path, "ID East North Height")
    x, y = (a[:, 2], a[:, 1]) if swap_xy else (a[:, 1], a[:, 2])
    return pd.DataFrame({"id": a[:, 0].astype(np.int64), "x": x, "y": y, "z": a[:, 3], "layer": layer, "line": lines})


def is_layer_file(text) -> bool:
    """``LAYER=path`` (one of the dissertation's per-layer files): not a file that exists under that whole name
    (``run=1/contacts.csv``), nor QGIS's ``table.gpkg|layername=contacts``, nor a name holding a folder."""
    text = str(text)
    name, sep, _ = text.partition("=")
    if not sep or Path(text).exists():
        return False
    return bool(name.strip()) and not any(c in name for c in "|/\\:")


def _per_layer_files(source, swap_xy) -> list[pd.DataFrame]:
    items = source.items() if isinstance(source, dict) else (str(s).split("=", 1) for s in source)
    frames = []
    for layer, p in items:
        path = Path(p)
        if not path.is_file():
            raise DataFileError("file not found", path=path, hint="Check the path")
        df = _read_layer_file(path, str(layer).strip(), swap_xy)
        df["source"] = str(path)
        frames.append(df)
    return frames


def _one_table(source, swap_xy, fields=None) -> tuple[pd.DataFrame, object]:
    src = str(source[0] if isinstance(source, (list, tuple)) and len(source) == 1 else source)
    path = Path(src)
    if not path.exists():
        path = split_layer_spec(src)[0]
    if not path.exists():
        raise DataFileError("file not found", path=path, hint="Check the path")
    table = path.suffix.lower() in TABLE_SUFFIXES  # a CSV, also as QGIS names it (contacts.csv|layername=contacts)
    df, lines = _read_table(path) if table or Path(src).exists() else _read_table_spec(src)
    out = _from_frame(df, lines, path, swap_xy, fields)
    out["source"] = str(path)
    return out, df.attrs.get("crs")


def _check_layers(pts: pd.DataFrame, layers, min_points: int) -> None:
    unknown = sorted(set(pts["layer"]) - set(layers))
    if unknown:
        k = int(np.flatnonzero(pts["layer"].isin(unknown).to_numpy())[0])
        raise InputError(f"line {pts['line'].iloc[k]}: layer {unknown[0]!r} is not in {option('layers', ','.join(layers))}",
                         path=pts["source"].iloc[k],
                         hint=f"Add it to {option('layers')} in its place top to bottom, or remove its rows (unknown: "
                              f"{', '.join(unknown)})")
    for layer in layers:
        n = int((pts["layer"] == layer).sum())
        if n < min_points:
            raise InputError(f"layer {layer} has {n} point(s); a surface needs at least {min_points}",
                             path=pts["source"].iloc[0], hint=f"Check the layer names in the file and in {option('layers')}")


def _contacts_crs(crs, found_crs, where) -> pyproj.CRS:
    out_crs = chosen_crs(crs, found_crs, "the contacts", where, "the Milan data: EPSG:3003, Monte Mario / Italy zone 1")
    if out_crs.is_geographic:
        raise InputError(f"CRS {out_crs.name!r} is geographic (degrees)", path=where,
                         hint="Give the contacts in a projected CRS in metres or feet")
    return out_crs


def read_contacts(source, layers, *, crs=None, swap_xy: bool = False, min_points: int = 3, fields: dict | None = None):
    """(points, crs): points has id, x, y, z, layer (in ``layers`` order, top to bottom), borehole_id?, source, line.

    ``source``: a table path (CSV, GeoPackage layer, shapefile) or a dict / list ``LAYER=path`` of
    per-layer files. ``crs``: EPSG code or WKT, required unless the layer carries one. ``fields``: the columns of
    some fields where they are not named as usual (``{"z": "ELEV", "layer": "FORMATION"}``; tables only).
    """
    layers = [str(lay).strip() for lay in layers]
    if len(layers) < 2 or len(set(layers)) != len(layers):
        raise InputError(f"layers {layers}: give at least two distinct layer names, top to bottom", hint=f"e.g. {option('layers', ['LS', 'AU', 'AD', 'AQ'])}")
    found_crs = None
    if isinstance(source, dict) or (isinstance(source, (list, tuple)) and all(is_layer_file(s) for s in source)):
        frames = _per_layer_files(source, swap_xy)
    else:
        table, found_crs = _one_table(source, swap_xy, fields)
        frames = [table]
    pts = pd.concat(frames, ignore_index=True)
    _check_layers(pts, layers, min_points)
    out_crs = _contacts_crs(crs, found_crs, pts["source"].iloc[0])
    pts["layer"] = pd.Categorical(pts["layer"], categories=layers, ordered=True)
    pts = pts.sort_values(["layer", "id"], kind="stable").reset_index(drop=True)
    pts["layer"] = pts["layer"].astype(str)
    return pts, out_crs
