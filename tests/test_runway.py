"""Runway earthworks: the spec's closed-form cases T1-T7, the synthetic runway T8, frame recovery, ICAO templates,
diagrams and bad input."""

from __future__ import annotations

import json
from decimal import Decimal, getcontext
from fractions import Fraction

import numpy as np
import pytest
from click.testing import CliRunner

from gistools.errors import GistoolsError
from gistools.cli.main import cli
from gistools.runway.earthworks import (balance_points, brueckner, compensate, dissertation_strip_areas, heron, heron_kahan,
                                        section_areas, station_volumes, strip_areas)
from gistools.runway.icao import VALID_CODES, template
from gistools.runway.synthetic import BEARING, synthetic_runway, to_world
from gistools.products.runway import RunwaySettings, area_diagram, brueckner_diagram, compute_earthworks


def exact_area(a: float, b: float, c: float) -> float:
    """The exact area of the triangle whose sides are these binary floats (rational Heron, 50-digit sqrt)."""
    a, b, c = Fraction(a), Fraction(b), Fraction(c)
    p = (a + b + c) / 2
    q = p * (p - a) * (p - b) * (p - c)
    getcontext().prec = 50
    return float((Decimal(q.numerator) / Decimal(q.denominator)).sqrt())


def test_t1_heron_and_kahan():
    assert heron_kahan(3, 4, 5) == 6.0
    assert heron_kahan(1e8, 1e8, 1e-3) == pytest.approx(50000.0, rel=1e-12)
    assert abs(heron(1e8, 1e8, 1e-3) - 50000.0) > 0.5  # the classic form loses it (49 999.36)
    assert heron_kahan(1, 2, 3) == 0.0
    assert np.isnan(heron_kahan(1, 2, 4))
    # Kahan's example: 10.0 for the decimal sides; for the binary floats the exact area is 10.000000077...,
    # which the stable form gets to 1e-12 and the classic one misses by 3e-8
    a, b, c = 100000.0, 99999.99979, 0.00029
    truth = exact_area(a, b, c)
    assert truth == pytest.approx(10.0, rel=1e-7)
    assert heron_kahan(a, b, c) == pytest.approx(truth, rel=1e-12)
    assert abs(heron(a, b, c) / truth - 1) > 1e-8


def test_t2_strip_areas():
    cut, fill = strip_areas(0.5, 1.0, 10)
    assert (float(cut), float(fill)) == (7.5, 0.0)
    cut, fill = strip_areas(1.0, -1.0, 10)
    assert (float(cut), float(fill)) == (2.5, 2.5)
    unsigned = dissertation_strip_areas(np.array([0.0]), np.array([10.0]), np.array([1.0]), np.array([-1.0]),
                                        np.array([0.0]), np.array([0.0]))
    assert unsigned[0] == pytest.approx(10.0, rel=1e-12)


def test_t3_prismatic_cut():
    x = np.arange(0, 2900.001, 10.0)
    y = np.arange(-150, 150.001, 10.0)
    d = np.full((len(x), len(y)), 0.5)
    _, _, a_cut, a_fill = section_areas(y, d)
    assert np.allclose(a_cut, 150.0, rtol=1e-12) and not a_fill.any()
    cut, fill = station_volumes(x, a_cut - a_fill)
    assert cut.sum() == pytest.approx(435000.0, rel=1e-12) and np.allclose(cut, 1500.0) and not fill.any()
    assert np.allclose(brueckner(x, a_cut), 150.0 * x, rtol=1e-12)


def test_t4_camber_only_both_templates():
    for kind, drops_at, per_side, per_side_10m in (("icao", (22.5, 30, 75, 150), 250.03125, 250.125),
                                                   ("dissertation", (45, 52.5, 75, 150), 223.875, 224.0)):
        tpl = template("4E", "precision", kind)
        expect = {"icao": (0.3375, 0.525, 1.65, 3.525), "dissertation": (0.675, 0.8625, 1.425, 3.3)}[kind]
        np.testing.assert_allclose(tpl.drop(np.asarray(drops_at)), expect, rtol=1e-12)
        with_breaks = np.unique(np.concatenate([np.arange(-150, 150.001, 10.0), tpl.breakpoints, -np.asarray(tpl.breakpoints)]))
        for offsets, side in ((with_breaks, per_side), (np.arange(-150, 150.001, 10.0), per_side_10m)):
            d = tpl.drop(offsets)[None, :]  # ground flat at the centre line height: all cut
            _, _, a_cut, a_fill = section_areas(offsets, d)
            assert a_cut[0] == pytest.approx(2 * side, rel=1e-12) and a_fill[0] == 0
    x = np.arange(0, 1000.001, 10.0)
    assert station_volumes(x, np.full(len(x), 500.0625))[0].sum() == pytest.approx(500062.5, rel=1e-12)


def test_t5_balanced_profile():
    x = np.arange(0, 2000.001, 10.0)
    area = 150 * np.sin(2 * np.pi * x / 1000)
    b = brueckner(x, area)
    assert b[x == 500][0] == pytest.approx(47730.77, abs=0.01)
    assert b[x == 1000][0] == pytest.approx(0, abs=1e-6) and b[-1] == pytest.approx(0, abs=1e-6)
    cut, fill = station_volumes(x, area)
    assert cut.sum() == pytest.approx(95461.55, abs=0.01) and fill.sum() == pytest.approx(95461.55, abs=0.01)
    np.testing.assert_allclose(balance_points(x, b), [0, 1000, 2000], atol=1e-6)


def test_t6_t7_sign_change_and_transverse_compensation():
    cut, fill = station_volumes([0, 20], [30, -10])
    assert (cut[0], fill[0]) == (225.0, 25.0)
    assert compensate(40, 15) == 25.0 and compensate(40, 15, f_cut=1.2) == pytest.approx(33.0)


def closed_form(length, cut=0.2, wave=0.5, width=300.0):
    x = np.linspace(0, length, 2_000_001)
    a = width * (cut + wave * np.sin(2 * np.pi * x / 1000))
    dx = x[1] - x[0]
    return float(np.sum(np.maximum(a, 0)) * dx), float(np.sum(np.maximum(-a, 0)) * dx)


def test_t8_synthetic_runway_checks_frame_and_volumes():
    points, truth = synthetic_runway(8)
    ew = compute_earthworks(points, RunwaySettings())
    assert set(zip(ew.removed["id"], ew.removed["reason"])) == set(zip(truth["id"], truth["reason"]))
    assert len(ew.points) == len(points) - 6  # 4 + 1 anomalies, 1 duplicate; nothing else
    assert ew.spacing == pytest.approx(10.0, abs=0.3)
    assert ew.frame.bearing == pytest.approx(BEARING, abs=0.05)
    # chainage of the lights against their true x
    local, _ = synthetic_runway(8, world=False)
    good = ~local["id"].isin(truth["id"]) & (local["type"] == 1)
    ch, _ = ew.frame.local(points.loc[good[: len(points)].to_numpy(), "x"], points.loc[good[: len(points)].to_numpy(), "y"])
    assert np.max(np.abs(ch - local.loc[good, "x"].to_numpy())) < 0.05
    cut, fill = closed_form(ew.frame.line.length)
    assert ew.totals["cut"] == pytest.approx(cut, rel=5e-3)
    assert ew.totals["net"] == pytest.approx(cut - fill, rel=5e-3)
    # the fill is the small difference of two large sums: the lights' height noise (2 cm on ~190 lights) alone
    # moves the design grade by ~1.4 mm, i.e. ~1.9 % of this fill (1 sigma); see the noise-free runs below
    assert ew.totals["fill"] == pytest.approx(fill, rel=2e-2)


def test_t8_with_the_ground_drawn_against_the_surveyed_grade_all_volumes_within_half_a_percent():
    # the same T8 survey, its ground drawn against the grade the (noisy) lights give, i.e. the design the
    # survey defines: cut, fill and net within 0.5 % of the closed form
    points, truth = synthetic_runway(8, design_from="lights")
    ew = compute_earthworks(points, RunwaySettings())  # the spec's grade: the lights' heights interpolated
    assert set(zip(ew.removed["id"], ew.removed["reason"])) == set(zip(truth["id"], truth["reason"]))
    cut, fill = closed_form(ew.frame.line.length)
    for key, value in (("cut", cut), ("fill", fill), ("net", cut - fill)):
        assert ew.totals[key] == pytest.approx(value, rel=5e-3), key


def test_t8_over_many_surveys_every_anomaly_found_no_good_light_removed_volumes_unbiased():
    # T8 drawn with 12 other seeds: 196 lights with 2 cm noise put a good light beyond robust z 3.5 about one run
    # in ten (seed 23: 7.6 cm off the line); --min-offset (10 cm) keeps such lights. Volumes: each survey's own
    # errors spread by ~0.2 % (ground noise, and the noisy lights' grade kinks between the 10 m survey lines);
    # the 10 m grid misses the template's kink at 22.5 m, a -0.31 % bias of the net (spec T4's regression note);
    # the mean over the seeds is within 0.5 % for cut, fill and net
    errors = []
    for seed in (0, 5, 7, 11, 17, 21, 23, 29, 31, 37, 41, 43):
        points, truth = synthetic_runway(seed, design_from="lights")
        ew = compute_earthworks(points, RunwaySettings())
        assert set(zip(ew.removed["id"], ew.removed["reason"])) == set(zip(truth["id"], truth["reason"])), seed
        cut, fill = closed_form(ew.frame.line.length)
        errors.append([ew.totals["cut"] / cut - 1, ew.totals["fill"] / fill - 1, ew.totals["net"] / (cut - fill) - 1])
    errors = np.array(errors)
    assert np.all(np.abs(errors) < 0.012)
    assert np.all(np.abs(errors.mean(axis=0)) < 5e-3), errors.mean(axis=0)


@pytest.mark.parametrize("grid,kinks,tol", [(2.0, False, 5e-3), (10.0, False, 5e-3), (15.0, False, 1.5e-2), (15.0, True, 5e-3)])
def test_t8_without_noise_volumes_on_dense_and_sparse_grids(grid, kinks, tol):
    # a 15 m survey cannot see the ground's kinks at the template breakpoints (22.5, 30, 75 m): its TIN cuts
    # the corners by up to 4 cm there (0.6 % of the cut, 1.2 % of the net); surveyed along them it is within 0.5 %
    points, _ = synthetic_runway(8, noise=False, outliers=False, grid=grid, breakpoint_lines=kinks)
    ew = compute_earthworks(points, RunwaySettings(spacing=10.0))
    cut, fill = closed_form(ew.frame.line.length)
    assert ew.totals["cut"] == pytest.approx(cut, rel=tol)
    assert ew.totals["fill"] == pytest.approx(fill, rel=tol)
    assert ew.totals["net"] == pytest.approx(cut - fill, rel=tol)


def test_exact_pipeline_when_the_kinks_are_surveyed():
    points, _ = synthetic_runway(8, noise=False, outliers=False, wave=0.0, cut=0.5, breakpoint_lines=True)
    ew = compute_earthworks(points, RunwaySettings(spacing=15.0, profile_window=1))
    assert np.allclose(ew.area_cut, 150.0, rtol=1e-9) and not ew.area_fill.any()
    assert ew.totals["cut"] == pytest.approx(150.0 * ew.frame.line.length, rel=1e-9)
    np.testing.assert_allclose(ew.brueckner, 150.0 * ew.stations, rtol=1e-9, atol=1e-6)


def test_frame_recovery_same_volumes_in_local_and_monte_mario_coordinates():
    world, _ = synthetic_runway(9, world=True)
    local, _ = synthetic_runway(9, world=False)
    a = compute_earthworks(world, RunwaySettings(spacing=10.0))
    b = compute_earthworks(local, RunwaySettings(spacing=10.0))
    for key in ("cut", "fill", "net"):
        # equal to 1e-5: on a regular survey grid the Delaunay diagonals of co-circular points follow the last bits
        assert a.totals[key] == pytest.approx(b.totals[key], rel=1e-5)
    np.testing.assert_allclose(a.stations, b.stations, atol=1e-6)
    assert b.frame.bearing == pytest.approx(90.0, abs=0.05)  # local x runs east
    assert a.frame.bearing == pytest.approx(BEARING, abs=0.05)
    x0, y0 = to_world(0.0, 0.0)
    assert np.hypot(*(np.asarray(a.frame.world([0.0], [0.0])).ravel() - [x0, y0])) < 0.05


def test_icao_codes():
    tpl = template("4E")
    assert tpl.breakpoints == (22.5, 30.0, 75.0, 150.0)
    assert [z.slope for z in tpl.zones] == [0.015, 0.025, 0.025, 0.025]
    assert template("4E", "non_instrument").half_width == 75.0
    assert template("2B").zones[0].outer == 11.5 and template("2B").zones[0].slope == 0.02
    assert "4E" in VALID_CODES and "4A" not in VALID_CODES
    result = CliRunner().invoke(cli, ["runway", "whatever.csv", "--code", "4A", "--out", "x"])
    assert result.exit_code == 1 and "'4A' is not valid" in result.output and "1A, 1B" in result.output
    assert result.output.strip().count("\n") == 0


def test_cli_outputs_report_and_diagram_data(tmp_path):
    import geopandas as gpd
    import rasterio

    points, _ = synthetic_runway(8)
    points.to_csv(tmp_path / "survey.csv", index=False)
    result = CliRunner().invoke(cli, ["runway", str(tmp_path / "survey.csv"), "--code", "4E", "--crs", "EPSG:3003",
                                      "--spacing", "10m", "--out", str(tmp_path / "o"), "-q", "--free-haul", "150m"])
    assert result.exit_code == 0, result.output
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["code"] == "4E" and rep["spacing"] == 10.0 and rep["stations"] == 294
    assert rep["removed"] == {"duplicates": 1, "renumbered": 1, "outliers": 5,
                              "by_reason": {"duplicate": 1, "renumbered": 1, "light_off_axis": 4, "light_height": 1}}
    # the generator's ground lies d(x) = 0.2 + 0.5 sin(2 pi x / 1000) m above the design over the whole strip, so a
    # section's cut (fill) area is W max(+-d, 0) and the volumes are their average end areas over the 10 m stations
    # (independent of gistools' sections). The survey noise (0.01 m ground, 0.02 m lights, which set the grade) splits
    # sections near d = 0 into both cut and fill: 0.2 % on cut, 0.55 % on fill; the net is not affected by that split
    x = np.append(np.arange(0.0, rep["length"], 10.0), rep["length"])
    d = 0.2 + 0.5 * np.sin(2 * np.pi * x / 1000.0)
    width = 2 * template("4E").half_width
    trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy 2 / numpy 1
    assert rep["cut"] == pytest.approx(width * trapezoid(np.maximum(d, 0), x), rel=1e-2)
    assert rep["fill"] == pytest.approx(width * trapezoid(np.maximum(-d, 0), x), rel=1e-2)
    assert rep["net"] == pytest.approx(width * trapezoid(d, x), rel=2e-3)
    assert rep["balance_points"][0] == 0.0
    assert rep["totals"]["overhaul"] > 0 and rep["totals"]["haul_moment"] > 0
    assert rep["units"]["overhaul"] == "m3 x m" and rep["free_haul"] == 150.0
    assert f"overhaul beyond the free haul of 150 m: {rep['totals']['overhaul']:,.0f} m3 x m" in \
        CliRunner().invoke(cli, ["runway", str(tmp_path / "survey.csv"), "--code", "4E", "--crs", "EPSG:3003", "--spacing",
                                 "10m", "--out", str(tmp_path / "o2"), "--free-haul", "150m"]).output
    sections = __import__("pandas").read_csv(tmp_path / "o" / "sections.csv")
    assert len(sections) == rep["stations"] * (len(np.unique(sections["y0"])))
    assert sections.groupby("station")["cut"].sum().max() > 0
    stations = gpd.read_file(tmp_path / "o" / "runway.gpkg", layer="stations")
    assert len(stations) == rep["stations"] and stations.crs.to_epsg() == 3003
    line = gpd.read_file(tmp_path / "o" / "runway.gpkg", layer="centre_line").geometry.iloc[0]
    assert line.length == pytest.approx(rep["length"])
    removed = gpd.read_file(tmp_path / "o" / "runway.gpkg", layer="removed")
    assert len(removed) == 7
    with rasterio.open(tmp_path / "o" / "design_surface.tif") as src:
        z = src.read(1, masked=True)
        assert src.crs.to_epsg() == 3003 and 225 < float(z.min()) and float(z.max()) < 238
    for name in ("area_diagram", "brueckner"):
        for ext in ("png", "pdf"):
            assert (tmp_path / "o" / f"{name}.{ext}").stat().st_size > 1000
    # the plotted arrays (of the same survey, read back from the CSV)
    from gistools.io.survey import read_survey

    ew = compute_earthworks(read_survey(tmp_path / "survey.csv")[0], RunwaySettings(spacing=10.0))
    fig = area_diagram(ew)
    xy = fig.axes[0].lines[0].get_xydata()
    np.testing.assert_allclose(xy[:, 0], ew.stations)
    np.testing.assert_allclose(xy[:, 1], ew.area_cut - ew.area_fill)
    fig = brueckner_diagram(ew)
    curve, marks = fig.axes[0].lines[0].get_xydata(), fig.axes[0].lines[1].get_xydata()
    np.testing.assert_allclose(curve[:, 1], ew.brueckner)
    assert curve[-1, 1] == pytest.approx(rep["net"], rel=1e-9)
    np.testing.assert_allclose(marks[:, 0], rep["balance_points"])


@pytest.mark.parametrize("case,expect", [
    ("missing", "no z column"), ("text", "line 5: x 'abc' is not a number"), ("type", "line 3: type 3 is not 1"),
])
def test_bad_survey_is_refused_in_one_line(tmp_path, case, expect):
    points, _ = synthetic_runway(8, outliers=False)
    df = points.copy()
    if case == "missing":
        df = df.drop(columns="z")
    elif case == "text":
        df["x"] = df["x"].astype(object)
        df.loc[3, "x"] = "abc"
    else:
        df.loc[1, "type"] = 3
    df.to_csv(tmp_path / "s.csv", index=False)
    result = CliRunner().invoke(cli, ["runway", str(tmp_path / "s.csv"), "--crs", "EPSG:3003", "--out", str(tmp_path / "o")])
    assert result.exit_code == 1 and expect in result.output and "s.csv" in result.output
    assert result.output.strip().count("\n") == 0 and not (tmp_path / "o").exists()


def test_dissertation_area_method_is_unsigned():
    points, _ = synthetic_runway(8, noise=False, outliers=False)
    exact = compute_earthworks(points, RunwaySettings(spacing=10.0))
    diss = compute_earthworks(points, RunwaySettings(spacing=10.0, area_method="dissertation"))
    assert not diss.area_fill.any() and (diss.area_cut >= 0).all()
    assert diss.totals["cut"] > exact.totals["cut"]  # fills counted as cut, crossings by their hull
    assert diss.totals["fill"] == 0


def test_spacing_in_feet_gives_what_metres_give(tmp_path):
    points, _ = synthetic_runway(8)
    points.to_csv(tmp_path / "survey.csv", index=False)
    reports = []
    for spacing in ("30ft", "9.144m"):
        out = tmp_path / spacing
        result = CliRunner().invoke(cli, ["runway", str(tmp_path / "survey.csv"), "--code", "4E", "--crs", "EPSG:3003",
                                          "--spacing", spacing, "--out", str(out), "-q"])
        assert result.exit_code == 0, result.output
        reports.append(json.loads((out / "report.json").read_text()))
    assert reports[0]["spacing"] == pytest.approx(9.144, abs=1e-12)
    for key in ("spacing", "stations", "cut", "fill", "net"):
        assert reports[0][key] == pytest.approx(reports[1][key], rel=1e-12), key


def test_a_survey_with_other_column_names_reads_through_the_chosen_fields(tmp_path):
    from gistools.io.survey import read_survey

    points, _ = synthetic_runway(8)
    points.to_csv(tmp_path / "usual.csv", index=False)
    points.rename(columns={"type": "KIND", "z": "ELEV"}).to_csv(tmp_path / "other.csv", index=False)
    usual, _ = read_survey(tmp_path / "usual.csv")
    other, _ = read_survey(tmp_path / "other.csv", {"type": "KIND", "z": "ELEV"})
    assert usual.equals(other)
    with pytest.raises(GistoolsError, match="the type field 'CODE' is not a column"):
        read_survey(tmp_path / "other.csv", {"type": "CODE"})
