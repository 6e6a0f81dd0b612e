"""Finding tiles on disk and naming their outputs."""

from __future__ import annotations

import glob
from pathlib import Path

from ..errors import InputError
from .vpc import VPC_SUFFIX, read_vpc

__all__ = ["find_tiles", "LAS_SUFFIXES"]

LAS_SUFFIXES = (".las", ".laz")


def _link_target(path: Path) -> str:
    try:
        return f"it points to {path.readlink()}"
    except OSError as err:
        return str(err.strerror or err)


def _folder_tiles(folder: Path) -> list[Path]:
    """The LAS/LAZ files of a folder; a link to a tile that is not there (a disk not mounted, a loop) is refused."""
    tiles = sorted(f for f in folder.iterdir() if f.suffix.lower() in LAS_SUFFIXES)
    broken = [f for f in tiles if f.is_symlink() and not f.exists()]
    if broken:
        raise InputError(f"{broken[0]}: a link to a tile that is not there ({_link_target(broken[0])})"
                         + (f", and {len(broken) - 1} more" if len(broken) > 1 else ""),
                         hint="Mount the disk it points to, or remove the link")
    return [f for f in tiles if f.is_file()]


def find_tiles(inputs) -> list[Path]:
    """LAS/LAZ (and COPC) files from files, folders (their *.las / *.laz, not recursive), glob patterns and
    virtual point clouds (``.vpc``: the files it lists).

    Explicit files are kept whatever their suffix (so a bad file is reported, not
    silently skipped). Raises InputError when nothing matches or two tiles share a name. An area of services or
    of local data (``gistools.Area``) gives its tiles, fetched into its cache.
    """
    if hasattr(inputs, "local_tiles"):
        return [Path(p).resolve() for p in inputs.local_tiles()]
    if isinstance(inputs, (str, Path)):
        inputs = [inputs]
    found: list[Path] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found += _folder_tiles(p)
        elif p.is_file() and p.suffix.lower() == VPC_SUFFIX:
            found += [item["path"] for item in read_vpc(p)]
        elif p.is_file():
            found.append(p)
        else:
            matches = sorted(Path(m) for m in glob.glob(str(item)))
            if not matches:
                raise InputError(f"{item}: no such file, folder or matching tile", hint="Check the path or the glob pattern")
            found += [m for m in matches if m.is_file()]
    unique = list(dict.fromkeys(f.resolve() for f in found))
    if not unique:
        raise InputError(f"{', '.join(map(str, inputs))}: no .las or .laz tiles found", hint="Give tile files or a folder holding them")
    names: dict[str, Path] = {}
    for f in unique:
        key = f.stem.casefold()  # A.laz and a.laz: one output file on Windows' and macOS's disks
        if key in names:
            raise InputError(
                f"two tiles share the name {f.stem!r}: {names[key]} and {f}" if names[key].stem == f.stem else
                f"tiles {names[key].name} and {f.name} differ only in case: their outputs would be one file on "
                f"Windows and macOS disks ({names[key]} and {f})",
                hint="Outputs are named after tiles; run the folders separately or rename one",
            )
        names[key] = f
    return unique
