"""The .glb scene loads in trimesh with the DSM's heights in metres (read here from the rasters), the class colours
where the class raster has them, its origin and CRS in the asset's extras, and stays under the size asked for."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest
import rasterio
import trimesh

from conftest import SAMPLE
from gistools.errors import InputError
from gistools.lidar.shrub import CLASS_STYLE
from gistools.deliver.scene import GROUND_COLOUR, read_extras, scene_glb

FT = 1200 / 3937


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    from gistools.products.shrub import shrub_from_tiles

    out = tmp_path_factory.mktemp("chain")
    b = SAMPLE / "breaklines.gpkg"
    shrub_from_tiles(SAMPLE, out, roads=f"{b}:ROADBREAKLINE", hydro=f"{b}:HYDROGRAPHICFEATURE",
                     waterbodies=f"{b}:WATERBODY", tile_index=f"{b}:FOOTPRINT", make_map=False)
    return out


def read(path):
    with rasterio.open(path) as src:
        return src.read(1, masked=True).astype(float).filled(np.nan), src.transform, src.crs


def test_the_scene_has_the_dsms_heights_in_metres_and_the_class_colours(chain):
    result = scene_glb(chain, exaggeration=2.0)
    mesh = trimesh.load(result["glb"], force="mesh")
    dsm, transform, crs = read(chain / "dsm.vrt")
    dem, _, _ = read(chain / "dem.vrt")
    surface = np.where(np.isfinite(dsm), dsm, dem)
    ok = np.isfinite(surface)
    assert len(mesh.vertices) == ok.sum() and result["step"] == 1
    up = mesh.vertices[:, 1]
    assert up.min() == pytest.approx(np.nanmin(surface) * FT * 2, abs=1e-3)
    assert up.max() == pytest.approx(np.nanmax(surface) * FT * 2, abs=1e-3)
    # x east and z south, in metres from the mosaic's south-west corner
    width, height = dsm.shape[1], dsm.shape[0]
    assert mesh.vertices[:, 0].max() - mesh.vertices[:, 0].min() == pytest.approx((width - 1) * transform.a * FT, rel=1e-5)
    assert -mesh.vertices[:, 2].min() == pytest.approx((height - 0.5) * transform.a * FT, rel=1e-5)
    # colours: the class raster's at each vertex
    classes, _, _ = read(chain / "classes.vrt")
    colours = {tuple(int((GROUND_COLOUR if code == 0 else h)[i:i + 2], 16) for i in (1, 3, 5)): code
               for code, (_n, h) in CLASS_STYLE.items()}
    rgb = [tuple(c) for c in np.asarray(mesh.visual.vertex_colors)[:, :3]]
    got = {}
    for c in rgb:
        got[colours.get(c, -1)] = got.get(colours.get(c, -1), 0) + 1
    want = {}
    for code in classes[ok]:
        k = int(code) if np.isfinite(code) and int(code) in CLASS_STYLE else -1
        want[k] = want.get(k, 0) + 1
    assert got == want and {1, 2, 3, 4, 5} <= set(got)
    extras = read_extras(result["glb"])
    assert pyproj.CRS.from_wkt(extras["crs_wkt"]).equals(pyproj.CRS.from_wkt(crs.to_wkt()), ignore_axis_order=True)
    assert extras["origin_crs"][:2] == [transform.c, transform.f + height * transform.e]
    assert extras["exaggeration"] == 2.0
    assert pyproj.CRS.from_wkt((chain / "scene.prj").read_text()).to_epsg() == 2882
    wld = [float(v) for v in (chain / "scene.wld").read_text().split()]
    assert wld[0] == pytest.approx(1 / FT) and wld[4:] == extras["origin_crs"][:2]


def test_the_scene_is_decimated_to_stay_under_the_size_asked(chain):
    result = scene_glb(chain, max_mb=1.0)
    assert result["step"] >= 3 and result["bytes"] < 1e6
    mesh = trimesh.load(result["glb"], force="mesh")
    assert len(mesh.vertices) == result["vertices"] and len(mesh.faces) == result["faces"]


def test_bad_scene_options_are_refused_before_anything_is_written(chain, tmp_path):
    before = (chain / "scene.glb").read_bytes() if (chain / "scene.glb").exists() else None
    for kw, words in ((dict(exaggeration=0), "^exaggeration 0"), (dict(max_mb=-1), "^max_mb -1"),
                      (dict(surface="ndsm"), "^surface 'ndsm'")):  # a Python call names the argument
        with pytest.raises(InputError, match=words):
            scene_glb(chain, **kw)
    after = (chain / "scene.glb").read_bytes() if (chain / "scene.glb").exists() else None
    assert after == before
    with pytest.raises(InputError, match="Run gistools shrub"):
        scene_glb(tmp_path)


def test_a_scene_gistools_did_not_write_is_kept(chain, tmp_path):
    import shutil

    from gistools.errors import OutputExistsError

    copy = tmp_path / "copy"
    shutil.copytree(chain, copy)
    for f in ("scene.glb", "scene.prj", "scene.wld"):
        (copy / f).unlink(missing_ok=True)
    (copy / "scene.prj").write_text("my own projection file")
    with pytest.raises(OutputExistsError):
        scene_glb(copy)
    assert (copy / "scene.prj").read_text() == "my own projection file" and not (copy / "scene.glb").exists()
    (copy / "scene.prj").unlink()
    scene_glb(copy)
    scene_glb(copy)  # its own scene is replaced
