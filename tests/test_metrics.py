"""gistools metrics against per-cell statistics computed here with pandas / numpy on the merged points (the
sample's four tiles read as one, the shared real files), and heights above ground from a scipy TIN of all the
ground: tiled == untiled, each metric's definition, nodata where a cell has no point."""

from __future__ import annotations

import laspy
import numpy as np
import pandas as pd
import pytest
import rasterio
from click.testing import CliRunner

from conftest import SAMPLE, need_kernel, need_shared, reference_tin_heights
from gistools.cli.main import cli
from gistools.errors import InputError
from gistools.products.metrics import MetricsSettings, metrics_from_tiles

FT = 1200 / 3937  # the sample's US survey foot, in metres


def merged(paths) -> pd.DataFrame:
    """Every point of the tiles, one table (withheld points left out, as every peer does)."""
    parts = []
    for p in paths:
        las = laspy.read(p)
        parts.append(pd.DataFrame({"x": np.asarray(las.x), "y": np.asarray(las.y), "z": np.asarray(las.z),
                                   "i": np.asarray(las.intensity, float), "c": np.asarray(las.classification),
                                   "r": np.asarray(las.return_number), "n": np.asarray(las.number_of_returns),
                                   "w": np.asarray(las.withheld, bool)}))
    df = pd.concat(parts, ignore_index=True)
    return df[~df.w]


def with_heights(df: pd.DataFrame) -> pd.DataFrame:
    """Height above a scipy TIN of every ground (2) and water (9) point of the block (``tied``: in a triangle that
    another valid Delaunay choice splits otherwise)."""
    g = df[df.c.isin([2, 9])].drop_duplicates(["x", "y"])
    h, tied = reference_tin_heights(df.x, df.y, df.z, g.x, g.y, g.z)
    df = df.assign(h=h, tied=tied | np.isnan(h))  # outside the hull gistools extrapolates (as lidR), scipy does not
    assert df.h.notna().mean() > 0.99
    return df


def raster_at(path, df, cs):
    """The raster's value at each cell of the table's key (col, row of the global lattice), NaN for nodata."""
    with rasterio.open(path) as src:
        a = src.read(1, masked=True).filled(np.nan).astype(float)
        col0, top = round(src.transform.c / cs), round(src.transform.f / cs)
    col, row = df.index.get_level_values(0) - col0, top - 1 - df.index.get_level_values(1)
    return a[row, col], a


def keyed(df, cs):
    return df.assign(kx=np.floor(df.x / cs).astype(int), ky=np.floor(df.y / cs).astype(int)).groupby(["kx", "ky"])


def entropy(h, layer):
    if np.isnan(h).any():
        return np.nan, 1
    k = np.floor(np.maximum(h, 0) / layer).astype(int)
    p = np.bincount(k)[np.bincount(k) > 0] / len(k)
    return -(p * np.log(p)).sum(), k.max() + 1


def reference(df, cs, unit_m):
    """Each metric per cell, by pandas' group statistics (quantile: linear interpolation, std: n - 1)."""
    grp = keyed(df, cs)
    two, one, half = 2 / unit_m, 1 / unit_m, 100.0
    first = keyed(df[df.r <= 1], cs)
    ref = pd.DataFrame({
        "count": grp.size().astype(float), "z_min": grp.z.min(), "z_max": grp.z.max(), "z_mean": grp.z.mean(),
        "z_median": grp.z.median(), "z_sd": grp.z.std(), "z_p95": grp.z.quantile(0.95), "z_p10": grp.z.quantile(0.10),
        "i_mean": grp.i.mean(), "i_p50": grp.i.quantile(0.5),
        "z_above100": grp.z.apply(lambda v: (v > half).mean()),
        "hag_p95": grp.h.quantile(0.95), "hag_max": grp.h.max(),
        "hag_above2m": grp.h.apply(lambda v: (v > two).mean()),
        "cover_above2m": first.h.apply(lambda v: (v > two).mean()),
        "fuel_1_3m": grp.h.apply(lambda v: ((v > one) & (v <= 3 * one)).sum() / (v <= 3 * one).sum()
                                 if (v <= 3 * one).any() else np.nan),
        "fhd": grp.h.apply(lambda v: entropy(v.to_numpy(), one)[0]),
        "vci": grp.h.apply(lambda v: (lambda e, n: e / np.log(n) if n > 1 else np.nan)(*entropy(v.to_numpy(), one))),
    })
    ref["z_cv"] = ref.z_sd / ref.z_mean
    ref["tied"] = grp.tied.any()
    ref["density"] = ref["count"] / (cs * unit_m) ** 2
    return ref


NAMES = ("count", "density", "z_min", "z_max", "z_mean", "z_median", "z_sd", "z_cv", "z_p95", "z_p10", "i_mean", "i_p50",
         "z_above100", "hag_p95", "hag_max", "hag_above2m", "cover_above2m", "fuel_1_3m", "fhd", "vci")


def check(out, report, df, cs, unit_m, names=NAMES, unsure=0.002):
    ref = reference(df, cs, unit_m)
    tied = ref.tied.to_numpy()
    assert tied.mean() < unsure  # cells with a point in a tied triangle: heights there may differ by the TIN's choice
    for name in names:
        got, grid = raster_at(out / f"{name}.vrt", ref, cs)
        want = ref[name].to_numpy()
        if name.startswith(("hag", "cover", "fuel", "fhd", "vci")):
            got, want = got[~tied], want[~tied]
        scale = np.nanmax(np.abs(want)) if np.isfinite(want).any() else 1.0
        np.testing.assert_allclose(got, want, rtol=2e-6, atol=2e-6 * scale, equal_nan=True, err_msg=name)
        # no value in a cell without points (nor where the metric has none), a value where it has one
        have, expect = np.isfinite(grid).sum(), np.isfinite(ref[name].to_numpy()).sum()
        assert expect <= have <= expect + (tied.sum() if len(got) < len(tied) else 0), name
    return ref


def test_metrics_of_the_sample_equal_pandas_on_the_merged_tiles(tmp_path, sample_tiles):
    """Four tiles with their neighbours' points == one table of every point, for every metric, edges included."""
    out = tmp_path / "m"
    report = metrics_from_tiles(SAMPLE, out, MetricsSettings(cell_size="7ft", metrics=NAMES))
    assert report["counts"] == {"ok": 4, "skipped": 0, "failed": 0}
    cs = report["units"]["cell_size"]
    assert cs == pytest.approx(7.0)  # ft on a US survey foot CRS is its own foot
    df = with_heights(merged(sample_tiles))
    ref = check(out, report, df, cs, FT)
    assert len(ref) > 10_000
    # 7 ft cells straddle the tile edges: those cells hold points of two tiles, and the two tiles' rasters agree
    edges = sorted({laspy.open(p).header.maxs[0] for p in sample_tiles})[:-1]
    straddling = [kx for kx in ref.index.get_level_values(0) if kx * cs < edges[0] < (kx + 1) * cs]
    assert straddling


def test_metrics_on_the_real_files(tmp_path, real_tile):
    """Megaplot (metres, forest) and Autzen (international feet, suburbs): the same definitions hold."""
    out = tmp_path / "m"
    report = metrics_from_tiles(real_tile, out, MetricsSettings(cell_size="5m", metrics=NAMES))
    assert report["counts"]["ok"] == 1
    unit_m = 1.0 if "megaplot" in str(real_tile).lower() else 0.3048
    check(out, report, with_heights(merged([real_tile])), report["units"]["cell_size"], unit_m, unsure=0.05)


def test_filters_returns_and_normalized_names(tmp_path, sample_tiles):
    """--classes, --returns first and --normalized (z_max -> hag_max) select what pandas selects."""
    out = tmp_path / "m"
    report = metrics_from_tiles(SAMPLE, out, MetricsSettings(cell_size="20ft", metrics=("count", "z_max"), normalized=True,
                                                             classes=(1,), returns="first"))
    assert report["metrics"] == ["count", "hag_max"]
    df = with_heights(merged(sample_tiles))
    df = df[(df.c == 1) & (df.r <= 1)]
    check(out, report, df, report["units"]["cell_size"], FT, names=("count", "hag_max"))


@pytest.mark.parametrize("name, words", [("z_p101", "percentile 101 is outside 0-100"), ("z_foo", "'foo' is not one of"),
                                         ("q_mean", "not a metric name"), ("fuel_3_1m", "is empty"),
                                         ("cover_above2parsecs", "parsecs")])
def test_bad_metric_names_are_one_line_naming_the_metric(tmp_path, name, words):
    with pytest.raises(InputError, match=words) as err:
        metrics_from_tiles(SAMPLE, tmp_path / "m", MetricsSettings(metrics=("count", name)))
    assert name in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "m").exists()  # refused before any output
    run = CliRunner().invoke(cli, ["metrics", str(SAMPLE), "--out", str(tmp_path / "c"), "--metrics", f"count,{name}"])
    assert run.exit_code == 1 and "Traceback" not in run.output and name in run.output
    assert len(run.output.strip().splitlines()) == 1


def test_metrics_rerun_keeps_tiles_and_overwrite_redoes_them(tmp_path):
    out = tmp_path / "m"
    metrics_from_tiles(SAMPLE, out, MetricsSettings(metrics=("count",)))
    again = metrics_from_tiles(SAMPLE, out, MetricsSettings(metrics=("count",)))
    assert again["counts"] == {"ok": 0, "skipped": 4, "failed": 0} and (out / "count.vrt").is_file()
    assert metrics_from_tiles(SAMPLE, out, MetricsSettings(metrics=("count",)), overwrite=True)["counts"]["ok"] == 4


def test_shared_data_present_for_metrics():
    need_shared()


@pytest.mark.parametrize("engine", ["kernel", "numpy"])
def test_values_sorted_by_cell_equal_numpys_lexsort(engine, monkeypatch):
    """The percentiles' grouping (the kernel's counting sort, or two numpy sorts): numpy.lexsort's order, NaN last."""
    from gistools import kernel
    from gistools.lidar import metrics

    if engine == "kernel" and not kernel.loaded():
        pytest.fail("the compiled kernel is not built here") if __import__("os").environ.get("CI") else pytest.skip("no kernel")
    if engine == "numpy":
        monkeypatch.setattr(metrics, "_CELL_SORT", None)
    rng = np.random.default_rng(5)
    for n, ncells in ((0, 4), (1, 1), (57, 3), (20_000, 900), (50_000, 7)):  # short cells and long ones (qsort)
        cell = rng.integers(0, ncells, n)
        v = rng.normal(size=n).round(1)  # ties
        v[::31] = np.nan
        out, start = metrics.cell_sorted(cell, v, ncells)
        np.testing.assert_array_equal(out, v[np.lexsort((v, cell))])
        np.testing.assert_array_equal(start, np.concatenate([[0], np.cumsum(np.bincount(cell, minlength=ncells))]))


@pytest.mark.parametrize("engine", ["kernel", "numpy"])
def test_cell_statistics_equal_pandas_group_statistics(engine, monkeypatch):
    """Sum, mean, sd, min, max, median and percentiles per cell (the kernel's one pass over each cell's sorted run,
    or numpy's reduceat and gathers) against pandas' group statistics, on cells of 1 to thousands of points; a cell
    holding a NaN gives NaN (but its median and percentiles, which rank the NaN last), on both engines alike."""
    from gistools.lidar import metrics

    if engine == "kernel":
        need_kernel()
    else:
        monkeypatch.setattr(metrics, "_CELL_SORT", None)
        monkeypatch.setattr(metrics, "_CELL_MOMENTS", None)
        monkeypatch.setattr(metrics, "_CELL_PERCENTILE", None)
    names = ["count", "z_sum", "z_mean", "z_sd", "z_cv", "z_min", "z_max", "z_median", "z_p5", "z_p95", "z_p100"]
    specs = [metrics.parse_metric(n) for n in names]
    rng = np.random.default_rng(11)
    for n, ncells in ((1, 3), (57, 3), (20_000, 900), (60_000, 7)):
        cell = rng.integers(0, ncells, n)
        v = rng.normal(30, 12, n).round(2)
        got = metrics.cell_metrics(cell, ncells, specs, z=v)
        g = pd.Series(v).groupby(cell)
        ref = pd.DataFrame({"count": g.size().astype(float), "z_sum": g.sum(), "z_mean": g.mean(), "z_sd": g.std(),
                            "z_min": g.min(), "z_max": g.max(), "z_median": g.median(), "z_p5": g.quantile(0.05),
                            "z_p95": g.quantile(0.95), "z_p100": g.quantile(1.0)}).reindex(range(ncells))
        ref["z_cv"] = ref.z_sd / ref.z_mean
        for name in names:
            np.testing.assert_allclose(got[name], ref[name].to_numpy(float), rtol=1e-12, atol=1e-9, err_msg=name)
        v[::29] = np.nan  # a NaN in a cell
        got = metrics.cell_metrics(cell, ncells, specs, z=v)
        holds = np.bincount(cell[np.isnan(v)], minlength=ncells) > 0
        for name in ("z_sum", "z_mean", "z_sd", "z_max"):
            assert np.isnan(got[name][holds]).all(), name


@pytest.mark.parametrize("cell", ["5ft", "7ft"])
def test_metrics_without_heights_read_only_the_neighbours_whose_points_reach_a_tiles_cells(tmp_path, sample_tiles, cell):
    """Without heights above ground a tile needs only the neighbours' points that fall in its own cells. The merged
    sample cut into 4 tiles on 500 ft lines: with 5 ft cells the cuts are cell edges and no tile reads a neighbour;
    with 7 ft cells, cells straddle the cuts and each tile reads the neighbours across them. Either way the mosaic
    is the merged file's raster, value for value (GDAL reads both)."""
    from gistools.io.points import read_tile_info, write_tile
    from gistools.io.raster import read_raster

    pts = {k: [] for k in ("x", "y", "z", "classification", "return_number", "number_of_returns")}
    for p in sample_tiles:
        las = laspy.read(p)
        for k in pts:
            pts[k].append(np.asarray(getattr(las, k)))
    pts = {k: np.concatenate(v) for k, v in pts.items()}
    pts = {k: v[(pts["x"] % 500 != 0) & (pts["y"] % 500 != 0)] for k, v in pts.items()}  # none on a cut
    crs = read_tile_info(sample_tiles[0]).crs
    cx, cy = 500 * np.round(np.median(pts["x"]) / 500), 500 * np.round(np.median(pts["y"]) / 500)
    tiles, whole = tmp_path / "tiles", tmp_path / "whole"
    write_tile(whole / "all.las", pts, crs, version="1.2", point_format=1)
    for name, m in {"sw": (pts["x"] < cx) & (pts["y"] < cy), "se": (pts["x"] > cx) & (pts["y"] < cy),
                    "nw": (pts["x"] < cx) & (pts["y"] > cy), "ne": (pts["x"] > cx) & (pts["y"] > cy)}.items():
        assert m.sum() > 1000
        write_tile(tiles / f"{name}.las", {k: v[m] for k, v in pts.items()}, crs, version="1.2", point_format=1)
    settings = MetricsSettings(cell_size=cell, metrics=["count", "z_max", "z_mean", "z_sd", "z_p95"])
    report = metrics_from_tiles([tiles], tmp_path / "t", settings)
    metrics_from_tiles([whole], tmp_path / "w", settings)
    read = [sorted(t["neighbours"]) for t in report["tiles"]]
    assert all(r == [] for r in read) if cell == "5ft" else all(len(r) == 3 for r in read), read
    for name in ("count", "z_max", "z_mean", "z_sd", "z_p95"):
        got, g_grid, _ = read_raster(tmp_path / "t" / f"{name}.vrt")
        want, w_grid, _ = read_raster(tmp_path / "w" / f"{name}.vrt")
        assert g_grid.transform == w_grid.transform and got.shape == want.shape, name
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9, equal_nan=True, err_msg=name)
