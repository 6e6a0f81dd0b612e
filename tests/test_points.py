"""gistools points: the dissertation's LAS To Multipoint, run for non-ground and ground."""

import geopandas as gpd
import laspy
import numpy as np
from click.testing import CliRunner

from gistools.cli.main import cli


def test_points_non_ground_and_ground(sample_tiles, tmp_path):
    tile = sample_tiles[0]
    las = laspy.read(tile)
    cls, rn = np.asarray(las.classification), np.asarray(las.return_number)
    r = CliRunner().invoke(cli, ["points", str(tile), "--classes", "1,2", "--returns", "first", "--out", str(tmp_path / "ng"),
                                 "--chunk-size", "20000"])
    assert r.exit_code == 0, r.output
    ng = gpd.read_file(tmp_path / "ng" / f"{tile.stem}.gpkg", layer="points")
    want = np.isin(cls, [1, 2]) & (rn == 1)
    assert len(ng) == want.sum() and ng.crs.to_epsg() == 2882
    assert set(ng.columns) >= {"x", "y", "z", "class", "return_number", "intensity", "geometry"}
    assert np.allclose(np.sort(ng["z"]), np.sort(np.asarray(las.z)[want]))
    assert np.allclose(ng.geometry.x, ng["x"]) and set(ng["return_number"]) == {1}
    r = CliRunner().invoke(cli, ["points", str(tile), "--classes", "2", "--out", str(tmp_path / "g")])
    g = gpd.read_file(tmp_path / "g" / f"{tile.stem}.gpkg", layer="points")
    assert len(g) == np.count_nonzero(cls == 2) and set(g["class"]) == {2}
    assert set(g["return_number"]) >= {1, 2}  # any return: last returns under vegetation too


def test_points_as_geoparquet(sample_tiles, tmp_path):
    tile = sample_tiles[-1]  # the LAZ tile
    r = CliRunner().invoke(cli, ["points", str(tile), "--classes", "2", "--format", "parquet", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    g = gpd.read_parquet(tmp_path / f"{tile.stem}.parquet")
    las = laspy.read(tile)
    assert len(g) == np.count_nonzero(np.asarray(las.classification) == 2) and g.crs.to_epsg() == 2882
