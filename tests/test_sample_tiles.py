"""The committed sample_tiles/ are what tools/make_sample_tiles.py writes, and look like the Levy delivery."""

from __future__ import annotations

import subprocess
import sys

import geopandas as gpd
import laspy
import numpy as np

from conftest import ROOT, SAMPLE


def test_sample_is_deterministic_and_matches_the_generator(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "tools" / "make_sample_tiles.py"), "--out", str(tmp_path / "s")],
                   check=True, capture_output=True)
    for committed in sorted(SAMPLE.glob("*.la[sz]")):
        a, b = laspy.read(committed), laspy.read(tmp_path / "s" / committed.name)
        for dim in ("X", "Y", "Z", "classification", "return_number", "number_of_returns", "intensity"):
            assert np.array_equal(np.asarray(getattr(a, dim)), np.asarray(getattr(b, dim))), (committed.name, dim)


def test_sample_tiles_are_shaped_like_levy(sample_tiles):
    assert sum(p.suffix == ".laz" for p in sample_tiles) == 1
    total = sum(p.stat().st_size for p in SAMPLE.iterdir())
    assert total < 10e6
    for p in sample_tiles:
        las = laspy.read(p)
        assert str(las.header.version) == "1.1" and las.header.point_format.id == 1
        assert las.header.parse_crs().to_epsg() == 2882
        assert set(np.unique(las.classification)) <= {1, 2, 9}
        assert las.return_number.max() <= 4 and las.number_of_returns.max() <= 4
        w, s, e, n = las.header.mins[0], las.header.mins[1], las.header.maxs[0], las.header.maxs[1]
        first = np.count_nonzero(las.return_number == 1)
        spacing = np.sqrt((e - w) * (n - s) / first)
        assert 3.8 < spacing < 4.2  # about 4 ft between pulses


def test_breaklines_and_truth_layers(sample_tiles):
    layers = set(gpd.list_layers(SAMPLE / "breaklines.gpkg")["name"])
    assert {"FOOTPRINT", "ROADBREAKLINE", "HYDROGRAPHICFEATURE", "WATERBODY", "WETLAND"} <= layers
    fp = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="FOOTPRINT")
    assert fp.crs.to_epsg() == 2882 and sorted(fp["TILE_ID"]) == sorted(int(p.stem) for p in sample_tiles)
    assert np.isclose(fp.union_all().area, 2000.0 * 2000.0)
    water = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="WATERBODY")
    assert any(len(g.interiors) == 1 for g in water.geometry if g.geom_type == "Polygon")  # the pond's island
    roads = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="ROADBREAKLINE")
    assert len(roads) >= 4 and set(roads.geom_type) == {"LineString"}
    truth = gpd.read_file(SAMPLE / "truth.gpkg", layer="SHRUB_TRUTH")
    combos = set(zip(truth["cover"], truth["band"]))
    assert combos == {(c, b) for c in ("light", "medium", "heavy") for b in ("B1", "B2", "B3")}
    wet = gpd.read_file(SAMPLE / "breaklines.gpkg", layer="WETLAND").union_all()
    assert truth.intersects(wet).any()  # vegetation inside wetland


def test_shrub_heights_fall_in_their_bands(sample_run):
    """The nDSM over each truth patch's shrub returns sits in the patch's band (heights in ftUS)."""
    from gistools.io.raster import read_raster
    from rasterio.features import geometry_mask

    out, _ = sample_run
    ndsm, grid, _ = read_raster(out / "ndsm.vrt")
    truth = gpd.read_file(SAMPLE / "truth.gpkg", layer="SHRUB_TRUTH")
    ft = 3937 / 1200
    bands = {"B1": (0, 1 * ft), "B2": (1 * ft, 2 * ft), "B3": (2 * ft, 6 * ft)}
    for _, patch in truth.iterrows():
        inside = ~geometry_mask([patch.geometry.buffer(-6)], grid.shape, grid.transform)
        h = ndsm[inside & np.isfinite(ndsm)]
        shrub = h[h > 0.5]
        lo, hi = bands[patch["band"]]
        assert len(shrub) > 10
        assert lo - 0.3 <= np.median(shrub) <= hi + 0.3, (patch["cover"], patch["band"], np.median(shrub))


def test_gistools_examples_writes_the_committed_sample_block(tmp_path):
    # `gistools examples` generates sample_tiles/ where no checkout is at hand: the same points as the files in git
    import laspy
    import numpy as np

    from gistools.datasets.examples import write_sample_block

    write_sample_block(tmp_path, breaklines=False)
    for tile in ("35712.las", "35713.las", "35812.las", "35813.laz"):
        ours, committed = laspy.read(tmp_path / tile), laspy.read(SAMPLE / tile)
        for dim in ("X", "Y", "Z", "classification", "return_number", "number_of_returns"):
            assert np.array_equal(np.asarray(ours[dim]), np.asarray(committed[dim])), (tile, dim)
