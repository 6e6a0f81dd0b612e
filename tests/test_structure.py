"""Structure reconstruction on the spec's generated buildings F1-F4 (checks A1-A9), the corrupted variant and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
import trimesh
from click.testing import CliRunner

from gistools.cli.main import cli
from gistools.structure.analysis import check_points, estimate_parameters, voxel_orders
from gistools.structure.envelope import sown_footprint, winding_number
from gistools.structure.fixtures import EULER, VOLUMES, building
from gistools.products.structure import reconstruct

ADOPTED = dict(h=8.0, d=15.0, t=4.0)


def topology(s):
    chain_chain = sum(a.kind == b.kind == "chain" for _, a, _, b in s.pairs)
    return {"levels": len(s.levels), "clusters": len(s.clusters), "sowns": sorted(c.z for c in s.clusters if c.kind == "sown"),
            "chains": sum(c.kind == "chain" for c in s.clusters), "chain_chain": chain_chain,
            "sown_chain": len(s.pairs) - chain_chain}


def test_a1_voxel_orders_and_estimated_parameters():
    pts, _ = building("F4")
    counts, k_opt, _ = voxel_orders(pts[["x", "y", "z"]].to_numpy())
    assert k_opt == 6 and {k: v for k, v in counts.items() if v} == {3: 3, 4: 376, 5: 1293, 6: 1944}
    assert sum(counts.values()) == len(pts) == 3616
    p = estimate_parameters(pts)
    assert p.h == pytest.approx(7.969, abs=5e-4) and p.d == pytest.approx(17.678, abs=5e-4) and p.t == 4.0


@pytest.mark.parametrize("variant", [{}, {"jitter": 0.3}, {"shuffle": True}, {"jitter": 0.3, "shuffle": True}])
def test_a2_a7_f4_topology_and_envelope(variant):
    pts, _ = building("F4", **variant)
    s = reconstruct(pts, **ADOPTED)
    assert topology(s) == {"levels": 52, "clusters": 83, "sowns": [0.0, 45.0, 205.0, 235.0], "chains": 79,
                           "chain_chain": 74, "sown_chain": 9}
    mesh = trimesh.Trimesh(s.vertices, s.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume
    assert mesh.euler_number == 0 and len(s.faces) == 2 * (len(s.vertices) - 0)
    tol = 1e-6 if not variant.get("jitter") else 1e-2
    assert mesh.volume == pytest.approx(VOLUMES["F4"], rel=tol)


@pytest.mark.parametrize("name", ["F1", "F2", "F3"])
@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_a7_f1_f3_closed_volumes_and_euler(name, jitter):
    pts, _ = building(name, jitter=jitter)
    s = reconstruct(pts, **ADOPTED)
    mesh = trimesh.Trimesh(s.vertices, s.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume
    assert mesh.euler_number == EULER[name]
    assert mesh.volume == pytest.approx(VOLUMES[name], rel=1e-6 if not jitter else 1e-2)
    if name == "F3":  # 2 clusters per chain level (outer and courtyard loops), 1 per sown level
        assert [len(cs) for _, cs in s.levels] == [1, 2, 2, 2, 2, 2, 1]


def test_a4_a5_loops_holes_and_roof_triangles():
    pts, _ = building("F3")
    sown = pts[pts["z"] == 0][["x", "y"]].to_numpy()
    foot = sown_footprint(sown)
    assert len(foot.interiors) == 1 and foot.area == pytest.approx(200 * 200 - 80 * 80, rel=1e-9)
    jittered, _ = building("F3", jitter=0.3)
    jf = sown_footprint(jittered[np.isclose(jittered["z"], 0)][["x", "y"]].to_numpy())
    assert jf.area == pytest.approx(33600, rel=0.02)
    # F2: the roof triangles cover the L exactly and none crosses the notch
    pts, _ = building("F2")
    s = reconstruct(pts, **ADOPTED)
    v, f = s.vertices, s.faces
    top = f[np.all(np.isclose(v[f][:, :, 2], 30.0), axis=1)]
    polys = shapely.polygons(np.concatenate([v[top][:, :, :2], v[top][:, :1, :2]], axis=1))
    L = shapely.Polygon([(0, 0), (200, 0), (200, 100), (100, 100), (100, 200), (0, 200)])
    assert shapely.area(polys).sum() == pytest.approx(L.area, rel=1e-9)
    assert shapely.covers(L.buffer(1e-6), polys).all() and (shapely.area(polys) > 1e-9).all()


def test_a8_non_stellar_and_courtyard_are_outside():
    pts, _ = building("F4")
    s = reconstruct(pts, **ADOPTED)
    between = np.column_stack([np.linspace(65, 135, 8), np.full(8, 40.0), np.full(8, 100.0)])
    inside_tower = np.array([[40.0, 40.0 + 0.5 * 10, 100.0], [160.0, 45.0, 100.0], [100.0, 50.0, 20.0]])
    w = winding_number(s.vertices, s.faces, np.vstack([between, inside_tower]))
    np.testing.assert_allclose(w[:8], 0.0, atol=1e-6)
    np.testing.assert_allclose(w[8:], 1.0, atol=1e-6)
    pts, _ = building("F3")
    s = reconstruct(pts, **ADOPTED)
    w = winding_number(s.vertices, s.faces, [[100, 100, z] for z in (2.5, 15, 27.5)] + [[30, 30, 15]])
    np.testing.assert_allclose(w, [0, 0, 0, 1], atol=1e-6)


def test_a9_invariance_to_row_order_and_ids():
    a = reconstruct(building("F4")[0], **ADOPTED)
    b = reconstruct(building("F4", shuffle=True, seed=7)[0], **ADOPTED)
    assert topology(a) == topology(b)
    assert trimesh.Trimesh(a.vertices, a.faces).volume == pytest.approx(trimesh.Trimesh(b.vertices, b.faces).volume, rel=1e-12)
    assert len(a.faces) == len(b.faces)


def test_a3_corrupted_variant_logs_exactly_the_planted_changes():
    pts, planted = building("F4", corrupt=True)
    kept, log = check_points(pts)
    counts = log["change"].value_counts().to_dict()
    assert counts == {"duplicate": 5, "renumbered": 3, "near_duplicate": 4, "outlier": 5}
    assert set(log.loc[log["change"] == "outlier", "id"]) == set(planted.loc[planted["change"] == "outlier", "id"])
    for change in ("duplicate", "renumbered", "near_duplicate", "outlier"):
        assert sorted(log.loc[log["change"] == change, "id"]) == sorted(planted.loc[planted["change"] == change, "id"]), change
    clean, _ = building("F4")
    kept_clean, log_clean = check_points(clean)
    assert len(log_clean) == 0 and len(kept_clean) == len(clean)


def test_cli_report(tmp_path):
    pts, _ = building("F4")
    src = tmp_path / "f4.txt"
    src.write_text("ID X Y Z\n" + "\n".join(f"{i} {x} {y} {z}" for i, x, y, z in pts.itertuples(index=False)))
    result = CliRunner().invoke(cli, ["structure", str(src), "--out", str(tmp_path / "o"), "-q", "--height-interval", "8",
                                      "--distance", "15", "--tolerance", "4"])
    assert result.exit_code == 0, result.output
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert {k: rep[k] for k in ("levels", "clusters", "sowns", "chains", "matched_pairs", "watertight", "euler")} == \
        {"levels": 52, "clusters": 83, "sowns": 4, "chains": 79, "matched_pairs": 83, "watertight": True, "euler": 0}
    assert rep["volume"] == pytest.approx(3_352_000, rel=1e-9) and rep["triangles"] > 0 and rep["surface_area"] > 0
    assert rep["parameters"] == {"height_interval": 8.0, "distance": 15.0, "tolerance": 4.0}
    mesh = trimesh.load(tmp_path / "o" / "structure.ply", process=False)
    assert mesh.is_watertight and mesh.volume == pytest.approx(3_352_000, rel=1e-9)
    assert trimesh.load(tmp_path / "o" / "structure.obj", process=False).is_watertight
    # estimated parameters (no overrides) give the same structure
    result = CliRunner().invoke(cli, ["structure", str(src), "--out", str(tmp_path / "e"), "-q"])
    rep = json.loads((tmp_path / "e" / "report.json").read_text())
    assert rep["parameters"]["height_interval"] == pytest.approx(7.969, abs=5e-4) and rep["clusters"] == 83


@pytest.mark.parametrize("case,expect", [("two_levels", "2 level(s)"), ("text", "line 3: 'abc' is not a number"),
                                         ("one_point", "1 point(s)")])
def test_bad_input_is_one_line(tmp_path, case, expect):
    src = tmp_path / "bad.txt"
    if case == "two_levels":
        src.write_text("\n".join(f"{i} {i % 5 * 10} {i // 5 * 10} {0 if i < 25 else 5}" for i in range(50)))
    elif case == "text":
        src.write_text("1 0 0 0\n2 10 0 0\n3 abc 0 0\n")
    else:
        src.write_text("1 0 0 0\n")
    result = CliRunner().invoke(cli, ["structure", str(src), "--out", str(tmp_path / "o")])
    assert result.exit_code == 1 and expect in result.output and result.output.strip().count("\n") == 0
    assert not (tmp_path / "o").exists()


def test_a10_catmull_rom_and_heron():
    from gistools.runway.earthworks import heron_kahan
    from gistools.structure.envelope import catmull_rom_loop

    assert heron_kahan(3, 4, 5) == 6.0
    R = 10.0
    ang = np.pi / 2 + np.arange(5) * 2 * np.pi / 5
    pentagon = np.column_stack([R * np.cos(ang), R * np.sin(ang)])
    pts, lines = catmull_rom_loop(pentagon)
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), R / np.cos(np.radians(36)), rtol=1e-12)
    mid = (pentagon + np.roll(pentagon, -1, axis=0)) / 2  # on the rays through the side midpoints
    np.testing.assert_allclose(mid[:, 0] * pts[:, 1] - mid[:, 1] * pts[:, 0], 0, atol=1e-9)
    assert len(lines) == 5 and all(kind in ("x", "y") for kind, _, _ in lines)
    collinear = np.array([[0, 0], [10, 0], [20, 0], [30, 0], [30, 10], [0, 10]], float)
    pts, _ = catmull_rom_loop(collinear)
    assert np.isnan(pts[1]).all()  # lines through (10, 0) and (20, 0) are parallel: no intersection


def test_las_input_and_catmull_rom_output(tmp_path):
    import geopandas as gpd
    import laspy

    pts, _ = building("F1")
    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = [0.001, 0.001, 0.001]
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts["x"].to_numpy(), pts["y"].to_numpy(), pts["z"].to_numpy()
    las.write(tmp_path / "f1.las")
    result = CliRunner().invoke(cli, ["structure", str(tmp_path / "f1.las"), "--out", str(tmp_path / "o"), "-q",
                                      "--loop-mode", "catmull-rom"])
    assert result.exit_code == 0, result.output
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["volume"] == pytest.approx(72_000, rel=1e-6) and rep["euler"] == 2 and rep["watertight"]
    lines = gpd.read_file(tmp_path / "o" / "structure.gpkg", layer="catmull_rom_lines")
    assert len(lines) == sum(len(g) for g in gpd.read_file(tmp_path / "o" / "structure.gpkg", layer="loops").geometry.apply(
        lambda g: list(g.coords)[:-1]))


def test_outlines_digitised_by_their_corners():
    """Chain levels with only the corners of an L (sides 100 and 200 m) and full plates at floor and roof."""
    import pandas as pd

    from gistools.structure.fixtures import P, lattice_points

    rows = []
    corners = np.asarray(P.exterior.coords)[:-1]
    for z in range(0, 31, 5):
        for x, y in (lattice_points(P) if z in (0, 30) else corners):
            rows.append((len(rows) + 1, x, y, float(z)))
    s = reconstruct(pd.DataFrame(rows, columns=["id", "x", "y", "z"]), h=8, d=150, t=4)
    assert [c.kind for c in s.clusters] == ["sown"] + ["chain"] * 5 + ["sown"]
    assert all(len(c.rings[0]) == 6 for c in s.clusters if c.kind == "chain")
    mesh = trimesh.Trimesh(s.vertices, s.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.euler_number == 2
    assert mesh.volume == pytest.approx(900_000, rel=1e-9)
