"""Plain-text point files: one ``ID X Y Z`` row per line (whitespace, comma or semicolon separated)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError

__all__ = ["read_id_xyz", "read_cloud", "check_text_file", "shown", "MAX_LINE_BYTES"]

MAX_LINE_BYTES = 1_000_000  # a line of a table of points or surveys; a longer one is not such a table


def shown(value, limit: int = 40) -> str:
    """A value as a message quotes it: repr, cut to ``limit`` characters (a 1 GB field is not echoed)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 12]}...' ({len(str(value)):,} characters)"


def check_text_file(path, what: str = "table", chunk: int = 1 << 20) -> None:
    """Refuse, before any parser reads it, a text table that parsers would misread silently: a NUL byte (which
    C parsers take as the end of the value), text that is not UTF-8 (an ANSI / Latin-1 export), a line too long
    for a table of points. Streams the file: memory does not grow with it."""
    import codecs

    p = Path(path)
    decoder = codecs.getincrementaldecoder("utf-8")()
    line, line_bytes = 1, 0
    with open(p, "rb") as f:
        while True:
            block = f.read(chunk)
            nul = block.find(b"\0")
            if nul >= 0:
                line += block.count(b"\n", 0, nul)
                raise InputError(f"line {line} holds a NUL byte (a damaged or binary file)", path=p,
                                 hint=f"Re-export the {what} as plain text, or remove that byte")
            try:
                decoder.decode(block, final=not block)
            except UnicodeDecodeError as err:
                offset = err.start
                line += block.count(b"\n", 0, max(offset, 0))
                raise InputError(f"is not UTF-8 text (byte 0x{block[offset]:02x} on line {line}: an ANSI or Latin-1 "
                                 "export)", path=p, hint=f"Save the {what} as UTF-8 (Excel: CSV UTF-8; QGIS: Encoding "
                                                        "UTF-8), then run again") from None
            if not block:
                return
            newlines = np.flatnonzero(np.frombuffer(block, np.uint8) == 10)
            if newlines.size:
                lengths = np.concatenate([[line_bytes + newlines[0]], np.diff(newlines) - 1])
                too_long = np.flatnonzero(lengths > MAX_LINE_BYTES)
                if too_long.size:
                    _too_long(p, line + int(too_long[0]), what)
                line += int(newlines.size)
                line_bytes = len(block) - int(newlines[-1]) - 1
            else:
                line_bytes += len(block)
            if line_bytes > MAX_LINE_BYTES:
                _too_long(p, line, what)


def _too_long(path: Path, line: int, what: str):
    raise InputError(f"line {line} is longer than {MAX_LINE_BYTES / 1e6:g} MB: not a {what} of one record a line",
                     path=path, hint=f"Check that this is the {what} (a text export, one row a line)")


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
    check_text_file(p, "point file")
    rows, lines = [], []
    for n, raw in enumerate(p.read_text(encoding="utf-8-sig").splitlines(), start=1):
        parts = raw.replace(",", " ").replace(";", " ").split()
        if not parts or raw.lstrip().startswith("#"):
            continue
        if len(parts) != 4:
            raise InputError(f"line {n}: {len(parts)} values, expected 4 ({names})", path=p, hint=f"One point per line: {names}")
        if not all(_is_number(v) for v in parts):
            if not rows and n == 1:
                continue  # a header
            bad = next(v for v in parts if not _is_number(v))
            raise InputError(f"line {n}: {shown(bad)} is not a number", path=p, hint="Fix or remove that row")
        if not all(_is_finite(v) for v in parts):
            bad = next(v for v in parts if not _is_finite(v))
            raise InputError(f"line {n}: {shown(bad)} is not a finite number", path=p, hint="Fix or remove that row")
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
