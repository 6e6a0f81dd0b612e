import pyproj
import pytest

from gistools.errors import InputError
from gistools.units import FOOT, US_SURVEY_FOOT, LinearUnit, horizontal_unit, length_to_crs_units, vertical_unit

FTUS = LinearUnit("US survey foot", US_SURVEY_FOOT)
FT = LinearUnit("foot", FOOT)
M = LinearUnit("metre", 1.0)


def test_units_read_from_crs():
    assert horizontal_unit(pyproj.CRS.from_epsg(2882)).metres == pytest.approx(US_SURVEY_FOOT, abs=1e-12)
    assert horizontal_unit(pyproj.CRS.from_epsg(2881)).short == "ftUS"
    assert horizontal_unit(pyproj.CRS.from_epsg(26917)).short == "m"
    assert horizontal_unit(pyproj.CRS.from_epsg(2992)).short == "ft"  # Oregon Lambert, international feet
    compound = pyproj.CRS.from_user_input("EPSG:26917+5703")  # UTM 17N + NAVD88 height (m)
    assert vertical_unit(compound).short == "m"
    ftus_height = pyproj.CRS.from_user_input("EPSG:2882+6360")  # + NAVD88 height (ftUS)
    assert vertical_unit(ftus_height).short == "ftUS"


def test_geographic_crs_is_refused():
    with pytest.raises(InputError, match="geographic"):
        horizontal_unit(pyproj.CRS.from_epsg(4326))


@pytest.mark.parametrize(
    "text, unit, expected",
    [
        ("5ft", FTUS, 5.0),  # ft means the CRS's own foot
        ("5ft", FT, 5.0),
        ("5", FTUS, 5.0),  # bare number: map units
        (5, M, 5.0),
        ("1.5m", M, 1.5),
        ("1m", FTUS, 3937 / 1200),
        ("6m", FTUS, 19.685),  # exactly 19.685 ftUS; the dissertation's 19.658 is a typo
        ("6m", FT, 19.685039370078737),
        ("1m", FT, 1 / 0.3048),
        ("5ft", M, 1.524),  # on a metre CRS ft is the international foot
        ("5ftUS", M, 5 * US_SURVEY_FOOT),
        ("10 feet", FT, 10.0),
    ],
)
def test_length_to_crs_units(text, unit, expected):
    assert length_to_crs_units(text, unit) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("bad", ["five feet", "5 parsecs", "", "m5"])
def test_bad_lengths_name_the_fix(bad):
    with pytest.raises(InputError) as err:
        length_to_crs_units(bad, M, name="cell size")
    assert "cell size" in str(err.value)


def test_vertical_unit_from_geotiff_keys(tmp_path):
    """Horizontal ftUS (EPSG:2882) with z in metres (VerticalCSTypeGeoKey 5703, NAVD88 height m)."""
    import numpy as np

    from gistools.io.points import read_tile_info, write_tile

    pts = {"x": np.array([430000.0, 430010.0]), "y": np.array([1810000.0, 1810010.0]), "z": np.array([10.0, 11.0]),
           "classification": np.array([2, 2], np.uint8), "return_number": np.array([1, 1], np.uint8),
           "number_of_returns": np.array([1, 1], np.uint8)}
    crs = pyproj.CRS.from_epsg(2882)
    write_tile(tmp_path / "m.las", pts, crs, version="1.2", point_format=1, vertical_epsg=5703)
    write_tile(tmp_path / "f.las", pts, crs, version="1.2", point_format=1, vertical_epsg=6360)
    write_tile(tmp_path / "none.las", pts, crs, version="1.2", point_format=1)
    assert read_tile_info(tmp_path / "m.las").z_unit.short == "m"
    assert read_tile_info(tmp_path / "f.las").z_unit.short == "ftUS"
    assert read_tile_info(tmp_path / "none.las").z_unit.short == "ftUS"  # the horizontal unit
    from gistools.errors import CRSMismatchError
    from gistools.io.points import common_crs

    with pytest.raises(CRSMismatchError, match="z is in metre"):
        common_crs([read_tile_info(tmp_path / "f.las"), read_tile_info(tmp_path / "m.las")])


def _shrub(args, tmp_path, name, crs=None):
    import geopandas as gpd
    from click.testing import CliRunner

    from conftest import SAMPLE
    from gistools.cli.main import cli

    roads = f"{SAMPLE / 'breaklines.gpkg'}:ROADBREAKLINE"
    if crs is not None:  # the same lines, their coordinates read in the tiles' other CRS
        gdf = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="ROADBREAKLINE").set_crs(crs, allow_override=True)
        gdf.to_file(tmp_path / f"roads_{name}.gpkg", layer="ROADS", driver="GPKG")
        roads = f"{tmp_path / f'roads_{name}.gpkg'}:ROADS"
        args = [*args, "--crs", crs]
    out = tmp_path / name
    run = CliRunner().invoke(cli, ["shrub", str(SAMPLE), "--out", str(out), "-q", "--no-map", "--roads", roads, *args])
    assert run.exit_code == 0, run.output
    import json

    return json.loads((out / "report.json").read_text()), run.output


def test_defaults_read_naturally_in_the_datas_unit(tmp_path):
    """With no options, a CRS in feet gets the dissertation's 5 ft cells, 25 ft radius, 60 ft roads and 0.2 ft snap;
    a metre CRS (the same coordinates read as UTM metres) 1.5 m, 7.5 m, 18 m and 0.06 m; the console says so."""
    feet, said = _shrub([], tmp_path, "feet")
    assert feet["cell_size"] == 5.0 and feet["horizontal_unit"] == "US survey foot"
    assert feet["density_radius"] == 25.0
    assert "cell size 5 ftUS" in said and "radius 25 ftUS" in said
    metres, said = _shrub([], tmp_path, "metres", crs="EPSG:32617")
    assert metres["cell_size"] == 1.5 and metres["horizontal_unit"] == "metre"
    assert metres["density_radius"] == 7.5
    settings = metres["settings"]
    assert (settings["max_road_width"], settings["snap"], settings["radius"]) == ("18m", "0.06m", "7.5m")
    assert "cell size 1.5 m" in said and "radius 7.5 m" in said
    # a length given keeps its value whatever the unit
    given, _ = _shrub(["--cell-size", "5ft", "--radius", "25ft"], tmp_path, "given", crs="EPSG:32617")
    assert given["cell_size"] == pytest.approx(1.524) and given["density_radius"] == pytest.approx(7.62)
