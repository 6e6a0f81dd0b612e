"""``gistools examples DIR``: example inputs for every command the README shows, from gistools' own generators, so
that each README command runs as printed in DIR (and a test runs them all).

Written: ``sample_tiles/`` (the 2 x 2 block of synthetic LAS / LAZ tiles shaped like the Levy County delivery, with
``breaklines.gpkg``: the checkout's sample_tiles/ is the same block), ``tiles/`` (the same tiles as LAZ),
``contacts.csv`` and ``LSInput.txt`` ... ``AQInput.txt`` (aquifer layer contacts, EPSG:3003 metres; the four
files in the dissertation's North-first form), ``area.gpkg`` (layer AREA), ``survey.csv`` (a runway survey, code 4E),
``cctv.txt`` (building F4's points) and ``scan.txt`` (building F2 as a scanner writes it: columns y x z, z down, turned
90 degrees). Existing files are kept, never overwritten.
"""

from __future__ import annotations

from pathlib import Path

from ..io.atomic import atomic_path

__all__ = ["write_examples", "write_sample_block"]

SAMPLE_TILE = 1000.0  # ftUS
SAMPLE_ORIGIN = (430000.0, 1810000.0)
SAMPLE_TILE_IDS = {(0, 0): 35712, (0, 1): 35713, (1, 0): 35812, (1, 1): 35813}  # row 357 / 358, column 12 / 13


def write_sample_block(out, *, seed: int = 35712, laz=(35813,), breaklines: bool = True):
    """The sample block's tiles into ``out`` (LAS 1.1, point format 1, EPSG:2882 + NAVD88 ftUS; the tiles of ``laz``
    as LAZ) and, with ``breaklines``, ``breaklines.gpkg``; returns (scene, footprints). Deterministic for a seed."""
    import pyproj
    from shapely.geometry import box

    from ..io.points import write_tile
    from ..synthetic import make_scene, scene_points, write_breaklines

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    crs = pyproj.CRS.from_epsg(2882)
    scene = make_scene(SAMPLE_ORIGIN, (2 * SAMPLE_TILE, 2 * SAMPLE_TILE), seed=seed)
    pts = scene_points(scene, scene.bounds, spacing=4.0, seed=seed)
    footprints = []
    for (row, col), tid in SAMPLE_TILE_IDS.items():
        w = SAMPLE_ORIGIN[0] + col * SAMPLE_TILE
        s = SAMPLE_ORIGIN[1] + (1 - row) * SAMPLE_TILE
        m = (pts["x"] >= w) & (pts["x"] < w + SAMPLE_TILE) & (pts["y"] >= s) & (pts["y"] < s + SAMPLE_TILE)
        suffix = ".laz" if tid in laz else ".las"
        if not (out / f"{tid}{suffix}").exists():
            write_tile(out / f"{tid}{suffix}", {k: v[m] for k, v in pts.items()}, crs, version="1.1", point_format=1,
                       offsets=[w, s, 0.0], vertical_epsg=6360)  # NAVD88 height (ftUS), as FDEM deliveries
        footprints.append({"TILE_ID": tid, "FILENAME": f"{tid}{suffix}", "geometry": box(w, s, w + SAMPLE_TILE, s + SAMPLE_TILE)})
    if breaklines and not (out / "breaklines.gpkg").exists():
        write_breaklines(scene, footprints, out / "breaklines.gpkg", crs)
    return scene, footprints


def _text(path: Path, text: str) -> None:
    if not path.exists():
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")


def _aquifer(out: Path) -> None:
    import geopandas as gpd
    import shapely

    from ..aquifer.synthetic import E0, LAYERS, N0, synthetic_aquifer

    points, _ = synthetic_aquifer(2012)
    if not (out / "contacts.csv").exists():
        with atomic_path(out / "contacts.csv") as tmp:
            points.to_csv(tmp, index=False)
    clean, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    for layer in LAYERS:  # the dissertation's form: ID North East Height (North first: --swap-xy)
        g = clean[clean["layer"] == layer]
        rows = "\n".join(f"{int(i)} {float(y)!r} {float(x)!r} {float(z)!r}"  # plain numbers whatever numpy is
                         for i, y, x, z in zip(g["id"], g["y"], g["x"], g["z"]))
        _text(out / f"{layer}Input.txt", "ID North East Height\n" + rows + "\n")
    if not (out / "area.gpkg").exists():
        from ..io.vector import write_layer

        area = shapely.box(E0 + 5000, N0 + 5000, E0 + 25000, N0 + 25000)  # 20 km square inside the contacts
        write_layer(gpd.GeoDataFrame({"name": ["study area"]}, geometry=[area], crs=3003), out / "area.gpkg", "AREA")


def _runway(out: Path) -> None:
    from ..runway.synthetic import synthetic_runway

    if not (out / "survey.csv").exists():
        points, _ = synthetic_runway(8)
        with atomic_path(out / "survey.csv") as tmp:
            points.to_csv(tmp, index=False)


def _structures(out: Path) -> None:
    from ..structure.fixtures import building

    pts, _ = building("F4")
    _text(out / "cctv.txt", "ID X Y Z\n" + "\n".join(f"{i} {float(x)!r} {float(y)!r} {float(z)!r}"
                                                  for i, x, y, z in pts.itertuples(index=False)) + "\n")
    pts, _ = building("F2")
    # as a scanner wrote it: turned -90 degrees about z, z pointing down, y before x (--columns 213 --scales 1,1,-1
    # --rotations 0,0,90 bring it back)
    x, y, z = pts["x"].to_numpy(), pts["y"].to_numpy(), pts["z"].to_numpy()
    xr, yr = y, -x
    rows = "\n".join(f"{i} {float(b)!r} {float(a)!r} {float(-c)!r}" for i, a, b, c in zip(pts["id"], xr, yr, z))
    _text(out / "scan.txt", "ID Y X Z\n" + rows + "\n")


def write_examples(out, *, sample_tiles=None) -> dict:
    """Example inputs for every command into ``out``: ``gistools examples``.

    Writes ``sample_tiles/`` (four LAS / LAZ tiles in EPSG:2882, US survey feet, with ``breaklines.gpkg``), ``tiles/``
    (the same tiles as LAZ), the aquifer contacts (``contacts.csv``, ``LSInput.txt`` ...), ``area.gpkg``, a runway
    survey (``survey.csv``) and building clouds (``cctv.txt``, ``scan.txt``). Existing files are kept, never
    overwritten.

    Parameters
    ----------
    out : str or path
        The folder, made when missing.
    sample_tiles : str or path, optional
        A folder to copy as ``sample_tiles/`` instead of generating it.

    Returns
    -------
    dict
        ``{name: path}`` of what ``out`` holds.

    Examples
    --------
    >>> from gistools import write_examples
    >>> sorted(write_examples("."))[:4]  # doctest: +SKIP
    ['ADInput.txt', 'AQInput.txt', 'AUInput.txt', 'LSInput.txt']
    """
    import shutil

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if sample_tiles is not None and not (out / "sample_tiles").exists():
        shutil.copytree(sample_tiles, out / "sample_tiles")
    else:
        write_sample_block(out / "sample_tiles")
    write_sample_block(out / "tiles", laz=tuple(SAMPLE_TILE_IDS.values()), breaklines=False)
    _aquifer(out)
    _runway(out)
    _structures(out)
    return {p.name: p for p in sorted(out.iterdir())}


if __name__ == "__main__":  # pragma: no cover
    import sys

    print(write_examples(sys.argv[1]))
