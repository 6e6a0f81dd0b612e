"""Plain-text point files: one ``ID X Y Z`` row per line (whitespace, comma or semicolon separated)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError

__all__ = ["read_id_xyz", "read_cloud"]


def _is_number(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def _is_finite(v: str) -> bool:
    return np.isfinite(float(v))


def read_id_xyz(path, names: str = "ID X Y Z") -> tuple[np.ndarray, np.ndarray]:
    """(rows (n, 4) float64, file line of each row). A header line and ``#`` comments are skipped;
    a row without 4 values or with a value that is not a number is refused naming the file and line."""
    p = Path(path)
    if not p.is_file():
        raise DataFileError("file not found", path=p, hint="Check the path")
    rows, lines = [], []
    for n, raw in enumerate(p.read_text(encoding="utf-8-sig", errors="replace").splitlines(), start=1):
        parts = raw.replace(",", " ").replace(";", " ").split()
        if not parts or raw.lstrip().startswith("#"):
            continue
        if len(parts) != 4:
            raise InputError(f"line {n}: {len(parts)} values, expected 4 ({names})", path=p, hint=f"One point per line: {names}")
        if not all(_is_number(v) for v in parts):
            if not rows and n == 1:
                continue  # a header
            bad = next(v for v in parts if not _is_number(v))
            raise InputError(f"line {n}: {bad!r} is not a number", path=p, hint="Fix or remove that row")
        if not all(_is_finite(v) for v in parts):
            bad = next(v for v in parts if not _is_finite(v))
            raise InputError(f"line {n}: {bad!r} is not a finite number", path=p, hint="Fix or remove that row")
        rows.append([float(v) for v in parts])
        lines.append(n)
    if not rows:
        raise InputError("no points", path=p, hint=f"One point per line: {names}")
    return np.asarray(rows, np.float64), np.asarray(lines)


def read_cloud(path) -> tuple[np.ndarray, np.ndarray]:
    """(ids, xyz (n, 3) float64) of ``ID X Y Z`` rows (text or CSV, header optional) or of a LAS/LAZ file
    (ids 1..n): the structure's input cloud."""
    p = Path(path)
    if not p.is_file():
        raise DataFileError("file not found", path=p, hint="Check the path")
    if p.suffix.lower() in (".las", ".laz"):
        import laspy

        try:
            las = laspy.read(p)
        except Exception as err:
            raise DataFileError(f"cannot read as LAS/LAZ ({err})", path=p, hint="Re-export the file") from None
        xyz = np.column_stack([las.x, las.y, las.z]).astype(np.float64)
        return np.arange(1, len(xyz) + 1), xyz
    a, _ = read_id_xyz(p)
    return a[:, 0].astype(np.int64), a[:, 1:4]
