"""report.json: one schema (gistools/schemas/report.schema.json) for every command, checked with jsonschema, and
each command run on a folder appends its line to ``runs``."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from conftest import SAMPLE


SCHEMA = json.loads((Path(__file__).resolve().parent.parent / "gistools" / "schemas" / "report.schema.json").read_text())
BREAKLINES = SAMPLE / "breaklines.gpkg"


def valid_record(folder: Path) -> dict:
    """The folder's report.json, after jsonschema found it valid against the one schema."""
    record = json.loads((Path(folder) / "report.json").read_text())
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    jsonschema.Draft202012Validator(SCHEMA).validate(record)
    return record


def test_the_schema_rejects_a_record_without_its_envelope():
    """The control: a record as batch commands wrote it before (no schema, version, warnings) fails the check."""
    old = {"tool": "gistools ground", "crs": "EPSG:2882", "settings": {}, "tiles": [{"name": "a", "status": "ok"}],
           "counts": {"ok": 1, "skipped": 0, "failed": 0}, "seconds": 1.0}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.Draft202012Validator(SCHEMA).validate(old)
    with pytest.raises(jsonschema.ValidationError):  # a tile status outside the three words
        jsonschema.Draft202012Validator(SCHEMA).validate(
            {**old, "schema": "gistools-report/1", "version": "0", "warnings": [], "runs": [{"tool": "gistools ground",
             "finished": "x", "seconds": 1}], "tiles": [{"name": "a", "status": "done"}]})


def test_the_chain_and_its_deliverables_share_one_record(tmp_path):
    """The shrub chain, then a web map, a scene, a map book and the map into its folder: one valid record, five
    runs."""
    from gistools.deliver.mapbook import map_book
    from gistools.deliver.scene import scene_glb
    from gistools.products.shrub import map_from_classes, shrub_from_tiles
    from gistools.deliver.webmap import web_map

    out = tmp_path / "chain"
    shrub_from_tiles(SAMPLE, out, roads=f"{BREAKLINES}:ROADBREAKLINE", hydro=f"{BREAKLINES}:HYDROGRAPHICFEATURE",
                     waterbodies=f"{BREAKLINES}:WATERBODY", make_map=False)
    record = valid_record(out)
    assert record["tool"] == "gistools shrub" and record["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    web_map(out)
    scene_glb(out)
    map_book(out, tile_index=f"{BREAKLINES}:FOOTPRINT")
    map_from_classes(out)
    record = valid_record(out)
    assert [r["tool"] for r in record["runs"]][-5:] == ["gistools shrub", "gistools webmap", "gistools scene",
                                                         "gistools mapbook", "gistools map"]


@pytest.mark.parametrize("command", ["rasters", "ground", "normalize", "metrics", "chm", "fuels", "points"])
def test_every_tile_command_writes_the_one_record(command, tmp_path):
    from gistools.products.chm import ChmSettings, chm_from_tiles
    from gistools.products.fuels import fuels_from_tiles
    from gistools.products.ground import ground_from_tiles
    from gistools.products.metrics import MetricsSettings, metrics_from_tiles
    from gistools.products.normalize import normalize_from_tiles
    from gistools.products.points import points_from_tiles
    from gistools.products.rasters import rasters_from_tiles

    run = {"rasters": lambda o, **kw: rasters_from_tiles(SAMPLE, o, **kw),
           "ground": lambda o, **kw: ground_from_tiles(SAMPLE, o, **kw),
           "normalize": lambda o, **kw: normalize_from_tiles(SAMPLE, o, **kw),
           "metrics": lambda o, **kw: metrics_from_tiles(SAMPLE, o, MetricsSettings(metrics=("count", "z_max")), **kw),
           "chm": lambda o, **kw: chm_from_tiles(SAMPLE, o, ChmSettings(cell_size="5ft"), **kw),
           "fuels": lambda o, **kw: fuels_from_tiles(SAMPLE, o, **kw),
           "points": lambda o, **kw: points_from_tiles(SAMPLE, o, **kw)}[command]
    out = tmp_path / command
    run(out)
    first = valid_record(out)
    assert first["tool"] == f"gistools {command}" and len(first["tiles"]) == 4
    assert all(t["status"] == "ok" for t in first["tiles"]), first["tiles"]
    run(out, overwrite=True)  # a rerun appends its line, the earlier one kept
    again = valid_record(out)
    assert [r["tool"] for r in again["runs"]] == [f"gistools {command}"] * 2
    assert again["runs"][0] == first["runs"][0]


def test_aquifer_runway_and_structure_write_the_one_record(tmp_path):
    import geopandas as gpd
    import shapely

    from gistools.aquifer.synthetic import synthetic_aquifer
    from gistools.runway.synthetic import synthetic_runway
    from gistools.structure.fixtures import building
    from gistools.products.aquifer import AquiferSettings, aquifer_model
    from gistools.products.runway import RunwaySettings, runway_earthworks
    from gistools.products.structure import structure_model

    points, _ = synthetic_aquifer(2012)
    gpd.GeoDataFrame(points, geometry=shapely.points(points["x"], points["y"]), crs=3003).to_file(
        tmp_path / "contacts.gpkg", layer="contacts")
    aquifer_model(f"{tmp_path / 'contacts.gpkg'}:contacts", ["LS", "AU", "AD", "AQ"], tmp_path / "aquifer",
                  settings=AquiferSettings(figures=False))
    survey, _ = synthetic_runway(8)
    gpd.GeoDataFrame(survey, geometry=shapely.points(survey["x"], survey["y"]), crs=3003).to_file(
        tmp_path / "s.gpkg", layer="survey")
    runway_earthworks(f"{tmp_path / 's.gpkg'}:survey", tmp_path / "runway", RunwaySettings(spacing=10.0))
    pts, _ = building("F3")
    src = tmp_path / "f3.txt"
    src.write_text("\n".join(f"{i} {x} {y} {z}" for i, x, y, z in pts.itertuples(index=False)))
    structure_model(src, tmp_path / "structure", h=8, d=15, t=4)
    for command in ("aquifer model", "runway", "structure"):
        record = valid_record(tmp_path / command.split()[0])
        assert record["tool"] == f"gistools {command}" and record["counts"]["ok"] == 1
        assert record["settings"] and [r["tool"] for r in record["runs"]] == [f"gistools {command}"]


def test_terrain_and_viewshed_write_the_one_record(sample_run, tmp_path):
    from gistools.products.terrain import terrain_from_dem
    from gistools.products.viewshed import viewshed_from_surface

    out, _ = sample_run
    terrain_from_dem(out, tmp_path / "t", products=("slope",))
    terrain_from_dem(out, tmp_path / "t", products=("slope",))  # kept: a second line in runs
    record = valid_record(tmp_path / "t")
    assert record["tool"] == "gistools terrain" and len(record["runs"]) == 2 and record["kept"] == ["slope"]
    viewshed_from_surface(out, tmp_path / "v", observers="431000,1811000")
    viewshed_from_surface(out, tmp_path / "v", observers="431000,1811000")
    record = valid_record(tmp_path / "v")
    assert record["tool"] == "gistools viewshed" and [r["counts"]["skipped"] for r in record["runs"]] == [0, 1]
