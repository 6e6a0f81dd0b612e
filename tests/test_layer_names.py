"""Layers named as users name them: ``file.gpkg:LAYER``, QGIS's ``file.gpkg|layername=LAYER`` / ``|layerid=N``,
Windows paths with a drive letter; one parser (gistools.io.vector.split_layer_spec) for every layer input."""

from __future__ import annotations

import json
import sys
from pathlib import Path, PureWindowsPath

import geopandas as gpd
import pyogrio
import pytest
from click.testing import CliRunner

from gistools.cli.main import cli
from gistools.errors import InputError
from gistools.io.vector import absolute_spec, read_layer, split_layer_spec

from conftest import SAMPLE

B = SAMPLE / "breaklines.gpkg"


def _split_windows(text):
    path, layer = split_layer_spec(text)
    return str(PureWindowsPath(str(path))), layer


@pytest.mark.parametrize("text, path, layer", [
    (r"C:\data\b.gpkg", r"C:\data\b.gpkg", None),
    (r"C:\data\b.gpkg:ROADS", r"C:\data\b.gpkg", "ROADS"),
    ("C:/data/b.gpkg:ROADS", r"C:\data\b.gpkg", "ROADS"),
    (r"C:\data\b.gpkg|layername=ROADS", r"C:\data\b.gpkg", "ROADS"),
    (r"D:\b.gpkg|layername=ROADS:2020", r"D:\b.gpkg", "ROADS:2020"),
    (r"C:\data\roads.shp", r"C:\data\roads.shp", None),
    (r"C:\data\b.gpkg|layerid=3", r"C:\data\b.gpkg", 3),
    (r"\\server\share\b.gpkg:ROADS", r"\\server\share\b.gpkg", "ROADS"),
    (r"C:\data\b.gpkg|layername=ROADS|geometrytype=LineString", r"C:\data\b.gpkg", "ROADS"),
])
def test_windows_paths_keep_their_drive_and_give_their_layer(text, path, layer):
    assert _split_windows(text) == (path, layer)


@pytest.mark.parametrize("text, path, layer", [
    ("b.gpkg", "b.gpkg", None),
    ("b.gpkg:ROADS", "b.gpkg", "ROADS"),
    ("b.gpkg|layername=ROADS", "b.gpkg", "ROADS"),
    ("b.gpkg|LayerName=ROADS", "b.gpkg", "ROADS"),
    ("b.gpkg|layerid=0", "b.gpkg", 0),
    ("/data/b.gpkg:ROADS:2020", "/data/b.gpkg", "ROADS:2020"),
    ("c.gpkg:ROADS", "c.gpkg", "ROADS"),  # a one-letter file name is not a drive
])
def test_posix_and_relative_names(text, path, layer):
    assert split_layer_spec(text) == (Path(path), layer)


def test_every_form_reads_the_same_features_as_geopandas():
    want = gpd.read_file(B, layer="ROADBREAKLINE")
    index = [name for name, _ in pyogrio.list_layers(B)].index("ROADBREAKLINE")
    for spec in (f"{B}:ROADBREAKLINE", f"{B}|layername=ROADBREAKLINE", f"{B}|layerid={index}"):
        got = read_layer(spec, ("line",), "--roads")
        assert len(got) == len(want) and got.geometry.equals(want.geometry), spec
    assert absolute_spec(f"{B}|layerid={index}") == f"{B.resolve()}|layerid={index}"
    assert absolute_spec(f"{B}|layername=ROADBREAKLINE") == f"{B.resolve()}:ROADBREAKLINE"


def test_a_qgis_filter_is_refused_not_ignored():
    with pytest.raises(InputError, match="subset"):
        read_layer(f"{B}|layername=ROADBREAKLINE|subset=\"id\" = 1")


def _shrub(out, roads):
    result = CliRunner().invoke(cli, ["shrub", str(SAMPLE), "--out", str(out), "-q", "--no-map", "--roads", roads])
    assert result.exit_code == 0, result.output
    return json.loads((out / "report.json").read_text())


def test_cli_takes_the_qgis_form_on_the_command_line(tmp_path):
    import subprocess

    out = tmp_path / "qgis_form"
    # the shell command as users type it, in a subprocess (the "|" quoted)
    run = subprocess.run([sys.executable, "-m", "gistools.cli.main", "shrub", "sample_tiles", "--out", str(out), "-q",
                          "--no-map", "--roads", "sample_tiles/breaklines.gpkg|layername=ROADBREAKLINE"],
                         cwd=SAMPLE.parent, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    qgis_form = json.loads((out / "report.json").read_text())["class_area"]
    colon_form = _shrub(tmp_path / "colon_form", f"{B}:ROADBREAKLINE")["class_area"]
    no_roads = CliRunner().invoke(cli, ["shrub", str(SAMPLE), "--out", str(tmp_path / "none"), "-q", "--no-map"])
    assert no_roads.exit_code == 0, no_roads.output
    none = json.loads((tmp_path / "none" / "report.json").read_text())["class_area"]
    assert none["road"] == 0 and qgis_form["road"] > 0
    assert qgis_form == colon_form


def test_contacts_and_survey_csvs_named_as_qgis_names_them(tmp_path):
    from gistools.aquifer.synthetic import synthetic_aquifer
    from gistools.io.contacts import read_contacts
    from gistools.io.survey import read_survey
    from gistools.runway.synthetic import synthetic_runway

    points, _ = synthetic_aquifer(2012)
    points.to_csv(tmp_path / "contacts.csv", index=False)
    plain, _ = read_contacts(tmp_path / "contacts.csv", ["LS", "AU", "AD", "AQ"], crs="EPSG:3003")
    qgis, _ = read_contacts(f"{tmp_path / 'contacts.csv'}|layername=contacts", ["LS", "AU", "AD", "AQ"], crs="EPSG:3003")
    assert len(plain) == len(points) and (plain[["x", "y", "z"]].to_numpy() == qgis[["x", "y", "z"]].to_numpy()).all()
    survey, _ = synthetic_runway(8)
    survey.to_csv(tmp_path / "survey.csv", index=False)
    a, _ = read_survey(tmp_path / "survey.csv")
    b, _ = read_survey(f"{tmp_path / 'survey.csv'}|layername=survey")
    assert len(a) == len(survey) and a.equals(b)


def test_the_aquifer_command_takes_a_contacts_layer_in_qgis_form(tmp_path):
    # "file.gpkg|layername=contacts" holds "=": it is one table, not the dissertation's LAYER=path files
    import geopandas as gpd
    import shapely as shp

    from gistools.aquifer.synthetic import synthetic_aquifer

    points, _ = synthetic_aquifer(2012)
    gdf = gpd.GeoDataFrame(points, geometry=shp.points(points["x"], points["y"]), crs=3003)
    gdf.to_file(tmp_path / "contacts.gpkg", layer="contacts")
    for form, out in ((f"{tmp_path / 'contacts.gpkg'}|layername=contacts", "qgis"), (f"{tmp_path / 'contacts.gpkg'}:contacts", "colon")):
        run = CliRunner().invoke(cli, ["aquifer", "model", form, "--layers", "LS,AU,AD,AQ", "--out", str(tmp_path / out),
                                       "-q", "--no-figures"])
        assert run.exit_code == 0, run.output
    a, b = (json.loads((tmp_path / o / "report.json").read_text())["units"] for o in ("qgis", "colon"))
    assert a == b and len(a) == 3
