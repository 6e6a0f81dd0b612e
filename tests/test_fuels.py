"""gistools fuels against a synthetic stand's known answers (cone and half-ellipsoid crowns, Beer-Lambert returns),
against independent numpy counts on the real tiles (heights above a scipy TIN of the ground), tiled == untiled, and
the landscape: the .lcp read back by GDAL equals the GeoTIFF, slope and aspect equal gdaldem's."""

from __future__ import annotations

import subprocess

import laspy
import numpy as np
import pytest
import rasterio

from conftest import SAMPLE, reference_tin_heights
from gistools.errors import InputError
from gistools.products.fuels import FuelsSettings, fuels_from_tiles
from gistools.synthetic import make_stand, stand_points, stand_truth, write_stand

BANDS = ("elevation", "slope", "aspect", "fuel_model", "canopy_cover", "canopy_height", "canopy_base_height",
         "canopy_bulk_density")


@pytest.fixture(scope="module")
def stand(tmp_path_factory):
    """A 5 x 4 stand of 30 m cells (one bare) as one file and as 2 x 2 tiles split mid-cell, both run."""
    folder = tmp_path_factory.mktemp("stand")
    st = make_stand(shape=(5, 4), seed=7)
    pts = stand_points(st, seed=1)
    tiles = write_stand(st, pts, folder)
    whole = fuels_from_tiles(folder / "stand.las", folder / "whole")
    tiled = fuels_from_tiles(tiles, folder / "tiled")
    return st, stand_truth(st), folder, whole, tiled


def at_cells(path, st):
    with rasterio.open(path) as src:
        a = src.read(1, masked=True).filled(np.nan)
        out = []
        for col, row, *_ in st.cells:
            r, c = src.index(st.origin[0] + (col + 0.5) * st.cell, st.origin[1] + (row + 0.5) * st.cell)
            out.append(a[r, c])
    return np.array(out)


def apex_shortfall_cdf(cells, s, *, density=20.0, k=0.5, lma=0.141):
    """P(the highest return of a cone cell lies less than ``s`` metres below the apex), from the sampling alone:
    pulses a Poisson process of ``density`` per m2, the crown surface ``(top - base) r / R`` below the apex at
    distance r, the first return an exponential depth of rate k x LAD below it (the stand's Beer-Lambert returns);
    the cell's n trees alike. ``cells``: rows of stand.cells; ``s``: metres (one per cell)."""
    out = []
    for (_c, _r, base, top, radius, spacing, rho, _shape), si in zip(cells, s):
        n = int(30.0 // spacing) ** 2
        mu = k * rho / lma
        r = np.linspace(0.0, radius, 4001)
        gap = np.clip(si - (top - base) * r / radius, 0.0, None)
        hit = 2 * np.pi * r * np.where(gap > 0, 1 - np.exp(-mu * gap), 0.0)
        out.append(1 - np.exp(-density * n * np.sum((hit[1:] + hit[:-1]) / 2) * (r[1] - r[0])))
    return np.array(out)


def stand_answers(seed, folder):
    st = make_stand(shape=(5, 4), seed=seed)
    write_stand(st, stand_points(st, seed=1), folder, tiles=(1, 1))
    fuels_from_tiles(folder / "stand.las", folder / "out")
    return st, stand_truth(st), {k: at_cells(folder / "out" / f"{k}.vrt", st) for k in ("cbh", "cbd", "cover", "height")}


@pytest.mark.parametrize("seed", [1, 2, 3, 7, 11])
def test_the_stand_s_known_answers(seed, tmp_path):
    """The acceptance on stands of several seeds: CBH (FVS's rule on the exact profile, which reads sparse crowns
    above their geometric base or not at all) within 1 m in >= 90 % of the canopy cells, CBD within 25 %, cover
    within 2 points of percent, height within 0.5 m of the domes' tops; the bare cell 0 everywhere. A cone's apex
    is narrower than the pulses' spacing: its highest return is never above it and lies below it by what the
    sampling allows (the 0.1 % - 99.9 % range of :func:`apex_shortfall_cdf`): 0.33 m on average, more than 0.5 m in
    one cone cell of eight at 20 pulses per m2, so the 0.5 m line does not hold for cones."""
    st, truth, got = stand_answers(seed, tmp_path)
    canopy = st.cells[:, 5] > 0
    assert np.mean(np.abs(got["cbh"] - truth["cbh"])[canopy] <= 1.0) >= 0.9
    assert np.all(np.abs(got["cbd"][canopy] / truth["cbd"][canopy] - 1) <= 0.25)
    assert np.all(np.abs(got["cover"] - truth["cover"]) <= 2.0)
    dome = canopy & (st.cells[:, 7] == 1)
    assert np.all(np.abs(got["height"] - truth["height"])[dome] <= 0.5)
    cone = canopy & (st.cells[:, 7] == 0)
    shortfall = (truth["height"] - got["height"])[cone]
    assert np.all(shortfall >= -0.05)
    p = apex_shortfall_cdf(st.cells[cone], shortfall)
    assert np.all((p > 0.001) & (p < 0.999)), p
    for k in got:
        assert np.all(got[k][~canopy] == 0), k


def test_tiled_equals_untiled(stand):
    """Four tiles split mid-cell, each with its neighbours' points, give the one file's rasters and landscape."""
    _, _, folder, whole, tiled = stand
    assert tiled["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    for name in whole["mosaics"]:
        with rasterio.open(whole["mosaics"][name]) as a, rasterio.open(tiled["mosaics"][name]) as b:
            assert a.transform == b.transform and a.shape == b.shape
            np.testing.assert_allclose(b.read(1), a.read(1), rtol=1e-6, atol=1e-6, err_msg=name)
    with rasterio.open(folder / "whole" / "landscape.tif") as a, rasterio.open(folder / "tiled" / "landscape.tif") as b:
        np.testing.assert_array_equal(a.read(), b.read())


def test_the_lcp_opens_in_gdal_and_equals_the_geotiff(stand):
    """8 int16 bands, the GeoTIFF's georeferencing and values; LANDFIRE's encodings of the float layers."""
    st, _, folder, whole, _ = stand
    out = folder / "whole"
    with rasterio.open(out / "landscape.lcp") as lcp, rasterio.open(out / "landscape.tif") as tif:
        assert lcp.driver == "LCP" and lcp.count == 8 and set(lcp.dtypes) == {"int16"}
        assert lcp.transform == tif.transform and lcp.shape == tif.shape and lcp.crs == tif.crs
        assert tif.descriptions == BANDS
        np.testing.assert_array_equal(lcp.read(), tif.read())
        land = tif.read()
    info = subprocess.run(["gdalinfo", str(out / "landscape.lcp")], capture_output=True, text=True, check=True).stdout
    rows, cols = land.shape[1:]
    assert "LCP/FARSITE" in info and f"Size is {cols}, {rows}" in info and "Pixel Size = (30.0000" in info
    for words in ("LATITUDE=37", "LINEAR_UNIT=Meters", "ELEVATION_UNIT_NAME=Meters", "SLOPE_UNIT_NAME=Degrees",
                  "ASPECT_UNIT_NAME=Azimuth degrees", "CANOPY_COV_UNIT_NAME=Percent", "CANOPY_HT_UNIT_NAME=Meters x 10",
                  "CBH_UNIT_NAME=Meters x 10", "CBD_UNIT_NAME=kg/m^3 x 100", "WGS 84 / UTM zone 10N"):
        assert words in info, words
    with rasterio.open(out / "cover.vrt") as src:
        empty = src.read(1, masked=True).mask  # cells without a return: -9999 in every band
    assert empty.any() and np.all(land[:, empty] == -9999)
    for band, name, scale in ((0, "elevation", 1), (4, "cover", 1), (5, "height", 10), (6, "cbh", 10), (7, "cbd", 100)):
        with rasterio.open(out / f"{name}.vrt") as src:
            want = np.rint(src.read(1).astype(float) * scale)
        np.testing.assert_array_equal(land[band][~empty], want[~empty].astype(np.int16), err_msg=name)
    assert set(np.unique(land[3][~empty])) == {121}  # no shrub under the stand: light shrub, GS1


def test_slope_and_aspect_equal_gdaldem(stand, tmp_path):
    """Horn's slope and aspect of the elevation mosaic equal gdaldem's on the interior cells."""
    _, _, folder, _, _ = stand
    out = folder / "whole"
    with rasterio.open(out / "landscape.tif") as src:
        land = src.read()
    for what, band in (("slope", 1), ("aspect", 2)):
        target = tmp_path / f"{what}.tif"
        subprocess.run(["gdaldem", what, str(out / "elevation.vrt"), str(target), "-alg", "Horn", "-q"], check=True)
        with rasterio.open(target) as src:
            ref = src.read(1)
        np.testing.assert_array_equal(land[band][1:-1, 1:-1], np.rint(ref[1:-1, 1:-1]).astype(np.int16), err_msg=what)


def reference_fuels(path, cs, unit_m, pulses=20, dz_m=1.0, floor_m=2.0, k=0.5, lma=0.141, window=3, thr=0.012):
    """Per cell (kx, ky): cover, CBD and CBH by loops over the points, heights above a scipy TIN of the ground; the
    cell split into q x q columns, q = round(sqrt(first returns / pulses)); each voxel (column x layer) by Pimont et
    al.'s bias-corrected estimator (returns / path - sum of the paths ended by a last return / path**2), the cell's
    layer the mean of the voxels some pulse reaches."""
    las = laspy.read(path)
    x, y, z = np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)
    c, r, n = np.asarray(las.classification), np.asarray(las.return_number), np.asarray(las.number_of_returns)
    g = np.isin(c, (2, 9))
    gx, gy, gz = x[g], y[g], z[g]
    _, first_of = np.unique(np.column_stack([gx, gy]), axis=0, return_index=True)
    h, tied = reference_tin_heights(x, y, z, gx[first_of], gy[first_of], gz[first_of])
    tied |= np.isnan(h)  # outside the ground's hull scipy has no height (gistools extrapolates, as lidR): left out
    h = np.round(np.nan_to_num(h), 9)  # as gistools: a return on a layer's boundary falls on one side whatever the TIN's last bits
    dz, floor = dz_m / unit_m, floor_m / unit_m
    kx, ky = np.floor(x / cs).astype(int), np.floor(y / cs).astype(int)
    hv = np.where(g, -np.inf, np.maximum(h, 0))
    out = {}
    for key in set(zip(kx, ky)):
        m = (kx == key[0]) & (ky == key[1])
        first = m & (r <= 1)
        cover = 100.0 * np.count_nonzero(first & ~g & (h > floor)) / np.count_nonzero(first)
        layers = int(np.floor(hv[m & ~g].max(initial=0) / dz)) + 1
        q = max(1, int(np.rint(np.sqrt(np.count_nonzero(first) / pulses))))
        cx = np.minimum(np.floor((x / cs - key[0]) * q), q - 1)
        cy = np.minimum(np.floor((y / cs - key[1]) * q), q - 1)
        lads = []
        pts = np.flatnonzero(m)
        for cc in set(zip(cx[pts], cy[pts])):
            mm = pts[(cx[pts] == cc[0]) & (cy[pts] == cc[1])]
            veg_h, lasts = hv[mm][~g[mm]], hv[mm][r[mm] >= n[mm]]
            lad = np.full(layers, np.nan)
            for i in range(layers):
                events = np.count_nonzero(np.floor(veg_h / dz) == i)
                exposure = np.clip((i + 1) * dz - lasts, 0, dz).sum()
                ended_here = lasts[(lasts >= i * dz) & (lasts < (i + 1) * dz)]
                cut = ((i + 1) * dz - ended_here).sum()
                if np.count_nonzero(lasts < (i + 1) * dz):
                    lad[i] = (events / exposure - cut / exposure ** 2) / (k * unit_m) if exposure > 0 else 0.0
            lads.append(lad)
        lads = np.array(lads)
        seen = np.isfinite(lads).sum(axis=0)
        bulk = np.where(seen > 0, np.nansum(lads, axis=0) / np.maximum(seen, 1), 0.0) * lma
        bulk[np.arange(layers) * dz < floor - 1e-9] = 0
        smooth = np.convolve(np.concatenate([np.zeros(1), bulk, np.zeros(1)]), np.ones(window) / window, "valid")
        smooth[np.arange(layers) * dz < floor - 1e-9] = 0
        over = np.flatnonzero(smooth > thr)
        out[key] = (cover, smooth.max(initial=0), (over[0] + 0.5) * dz if len(over) else 0.0, tied[m].any())
    return out


@pytest.mark.parametrize("unit_m", [0.3048, 1.0], ids=["autzen", "megaplot"])
def test_real_tiles_equal_an_independent_count(tmp_path, unit_m, autzen, megaplot):
    """Cover = the share of first returns above 2 m, and CBD / CBH from the same profile formula, computed here
    per cell with loops and heights from a scipy TIN, equal gistools fuels' (cells with a point in a tied TIN
    triangle left out)."""
    path = autzen if unit_m < 1 else megaplot
    report = fuels_from_tiles(path, tmp_path / "f")
    cs = report["units"]["cell_size"]
    assert cs == pytest.approx(100.0 if unit_m < 1 else 30.0)
    ref = reference_fuels(path, cs, unit_m)
    checked = 0
    for name, i in (("cover", 0), ("cbd", 1), ("cbh", 2)):
        with rasterio.open(tmp_path / "f" / f"{name}.vrt") as src:
            a = src.read(1)
            for (kx, ky), values in ref.items():
                if values[3]:
                    continue
                row, col = src.index((kx + 0.5) * cs, (ky + 0.5) * cs)
                assert a[row, col] == pytest.approx(values[i], rel=1e-5, abs=1e-6), (name, kx, ky)
                checked += 1
    assert checked >= 0.7 * 3 * len(ref)  # Autzen: 58 of its 71 cells, Megaplot 52 of 72 (edge cells outside the hull)
    assert sum(v[1] > 0.012 and not v[3] for v in ref.values()) >= 5  # canopy cells among them


def test_bad_settings_are_refused_before_any_output(tmp_path):
    with pytest.raises(InputError, match="fuel-model raster"):
        fuels_from_tiles(SAMPLE, tmp_path / "f", FuelsSettings(fuel_raster=str(tmp_path / "none.tif")))
    with pytest.raises(InputError):
        fuels_from_tiles(SAMPLE, tmp_path / "f", FuelsSettings(cbh_threshold=-1))
    assert not (tmp_path / "f").exists()


def test_a_fuel_raster_is_sampled_at_the_cell_centres(tmp_path):
    """A user's fuel-model raster (another lattice) gives band 4 its code at each cell centre."""
    from rasterio.transform import from_origin

    raster = tmp_path / "fbfm.tif"
    codes = np.array([[101, 102], [165, 183]], np.int16)
    with rasterio.open(raster, "w", driver="GTiff", width=2, height=2, count=1, dtype="int16", crs="EPSG:2882",
                       transform=from_origin(430000, 1812000, 1000, 1000)) as dst:
        dst.write(codes, 1)
    report = fuels_from_tiles(SAMPLE, tmp_path / "f", FuelsSettings(fuel_raster=str(raster)))
    with rasterio.open(report["landscape"]["tif"]) as src:
        fuel, t = src.read(4), src.transform
    rows, cols = np.mgrid[0:fuel.shape[0], 0:fuel.shape[1]]
    xs, ys = rasterio.transform.xy(t, rows.ravel(), cols.ravel())
    want = codes[(np.asarray(ys) < 1811000).astype(int), (np.asarray(xs) >= 431000).astype(int)].reshape(fuel.shape)
    valid = fuel != -9999
    assert valid.mean() > 0.9
    np.testing.assert_array_equal(fuel[valid], want[valid])


def test_feet_data_keep_their_units_and_the_landscape_is_metric(tmp_path):
    """The sample (US survey feet): 100 ft cells, heights in feet in the layers, metres in the landscape; the .lcp
    says its linear unit is the foot; the command line writes the same as the library, in one line."""
    from click.testing import CliRunner

    from gistools.cli.main import cli

    ftus = 1200 / 3937
    run = CliRunner().invoke(cli, ["fuels", str(SAMPLE), "--out", str(tmp_path / "c"), "-q"])
    assert run.exit_code == 0, run.output
    assert len(run.output.strip().splitlines()) == 1 and "landscape" in run.output
    report = fuels_from_tiles(SAMPLE, tmp_path / "f")
    assert report["units"]["cell_size"] == pytest.approx(100.0) and report["units"]["layer"] == pytest.approx(1 / ftus)
    out = tmp_path / "f"
    with rasterio.open(out / "landscape.tif") as src, rasterio.open(tmp_path / "c" / "landscape.tif") as cli_tif:
        land = src.read()
        np.testing.assert_array_equal(land, cli_tif.read())
        assert src.res == (100.0, 100.0)
    with rasterio.open(out / "cover.vrt") as src:
        empty = src.read(1, masked=True).mask
    for band, name, scale in ((0, "elevation", ftus), (5, "height", 10 * ftus), (6, "cbh", 10 * ftus)):
        with rasterio.open(out / f"{name}.vrt") as src:
            want = np.rint(src.read(1).astype(float) * scale)
        np.testing.assert_array_equal(land[band][~empty], want[~empty].astype(np.int16), err_msg=name)
    assert land[5][~empty].max() > 50  # shrubs and trees several metres tall
    assert set(np.unique(land[3][~empty])) <= {121, 142, 145} and len(np.unique(land[3][~empty])) >= 2
    info = subprocess.run(["gdalinfo", str(out / "landscape.lcp")], capture_output=True, text=True, check=True).stdout
    assert "LINEAR_UNIT=Feet" in info and "LATITUDE=29" in info


def test_the_web_map_holds_the_canopy_base_classes(stand):
    """fuels_map.html: one polygon set per CBH class whose areas add up to the cells of that class in cbh.vrt
    (counted here), the gistools web map's page (its generator mark, Leaflet inlined, no basemap request)."""
    import json
    import re

    _, _, folder, whole, _ = stand
    page = (folder / "whole" / "fuels_map.html").read_text()
    assert whole["landscape"]["web_map"] == str(folder / "whole" / "fuels_map.html")
    assert "gistools web map" in page and "tile.openstreetmap" not in page
    data = json.loads(re.search(r"var data = (.*?), classes = ", page, re.S).group(1))
    assert data["type"] == "FeatureCollection"
    with rasterio.open(folder / "whole" / "cbh.vrt") as src:
        cbh = src.read(1, masked=True).filled(0)
    want = {1: np.count_nonzero((cbh > 0) & (cbh < 4)), 2: np.count_nonzero((cbh >= 4) & (cbh < 8)),
            3: np.count_nonzero(cbh >= 8)}
    areas = {}
    for f in data["features"]:
        p = f["properties"]
        areas[p["class_code"]] = areas.get(p["class_code"], 0.0) + p["area"]
    assert {k: round(v / 900.0) for k, v in areas.items()} == {k: v for k, v in want.items() if v}
