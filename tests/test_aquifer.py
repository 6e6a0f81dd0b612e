"""The aquifer model against the dissertation's tables, the spec's analytic aquifer and real seismic horizons."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import shapely
from click.testing import CliRunner
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import ConvexHull

from conftest import SHARED_DATA, need_shared
from gistools.aquifer.outliers import find_outliers
from gistools.aquifer.surface import build_surface, densify, height_at, unique_edges
from gistools.grid import affine_apply
from gistools.aquifer.synthetic import E0, N0, surfaces_uv, synthetic_aquifer
from gistools.aquifer.volume import overlay_volume
from gistools.aquifer.walls import unit_mesh
from gistools.mesh import match_rings, mesh_volume
from gistools.cli.main import cli
from gistools.errors import InputError
from gistools.products.aquifer import (AquiferSettings, aquifer_model, aquifer_query, build_model, compute_units, load_model,
                                    query_model)

DESIGN = SHARED_DATA.parent / "design"
LAYERS = ["LS", "AU", "AD", "AQ"]
R = shapely.box(E0 + 5000, N0 + 5000, E0 + 25000, N0 + 25000)
TRIANGLE = shapely.Polygon([(E0 + 5000, N0 + 5000), (E0 + 25000, N0 + 5000), (E0 + 5000, N0 + 25000)])
QUERY = (E0 + 17365.0, N0 + 7638.0)  # the dissertation's query point


def _need_design():
    need_shared(DESIGN, "dissertation fixture test")


def surfaces_of(points):
    return {L: build_surface(L, g["id"], g["x"], g["y"], g["z"]) for L, g in points.groupby("layer")}


# ---------------------------------------------------------------- 3a: the dissertation's tables

@pytest.fixture(scope="module")
def perimeters():
    _need_design()
    ref = pd.read_csv(DESIGN / "aquifer_reference_points.csv")
    per = ref[ref["role"].str.startswith("perimeter")]
    out = {}
    for layer, g in per.groupby("layer"):
        g = g.sort_values("role")
        out[layer] = (build_surface(layer, g["id"], g["east"], g["north"], g["height_m"]), list(g["id"]))
    return out


def test_boundary_rings_in_the_printed_order(perimeters):
    for layer, (s, printed) in perimeters.items():
        ring = [int(i) for i in s.ids[s.ring()]]
        assert sorted(ring) == sorted(printed), layer
        k = ring.index(printed[0])
        forward = ring[k:] + ring[:k]
        backward = [ring[k]] + ring[:k][::-1] + ring[k + 1:][::-1]
        assert printed in (forward, backward), layer


def test_matching_reproduces_the_printed_distances(perimeters):
    expected = pd.read_csv(DESIGN / "aquifer_expected_matching.csv")
    assert len(expected) == 75
    for (a, b), g in expected.groupby(["from_layer", "to_layer"]):
        A, B = perimeters[a][0], perimeters[b][0]
        ra, rb = A.ring(), B.ring()
        i, j, d = match_rings(A.xyz[ra], B.xyz[rb], "3d")
        got = {int(A.ids[ra][ii]): (int(B.ids[rb][jj]), dd) for ii, jj, dd in zip(i, j, d)}
        assert len(got) == len(g)
        for row in g.itertuples():
            to_id, dist = got[int(row.from_id)]
            assert to_id == row.to_id and dist == pytest.approx(row.distance_3d_m, abs=1e-6), (a, b, row.from_id)


def test_boundary_areas_of_section_2(perimeters):
    areas_km2 = {"LS": 686.725, "AU": 701.510, "AD": 521.352, "AQ": 561.239}
    for layer, (s, _) in perimeters.items():
        assert s.outline().area / 1e6 == pytest.approx(areas_km2[layer], abs=1e-3)
    common = shapely.intersection_all([perimeters[L][0].outline() for L in LAYERS])
    assert common.area / 1e6 == pytest.approx(472.234, abs=1e-3)


def test_densification_count_identity():
    rng = np.random.default_rng(7)
    for n in (10, 100, 1000):
        xy = rng.uniform(0, 1000, (n, 2))
        s = build_surface("t", np.arange(n), xy[:, 0], xy[:, 1], rng.normal(size=n))
        h = len(s.ring())
        assert len(unique_edges(s.triangles)) == 3 * n - 3 - h
        for per_edge in (1, 2, 3):
            new = densify(s, per_edge)
            assert len(new) == per_edge * (3 * n - 3 - h)
        # new points lie on the TIN
        z, inside = height_at(s, new[:, 0], new[:, 1])
        assert np.allclose(z[inside], new[inside, 2], atol=1e-9) and inside.mean() > 0.99


# ---------------------------------------------------------------- 3b: the analytic aquifer

def test_outliers_of_the_synthetic_aquifer_are_all_flagged_and_only_they():
    points, truth = synthetic_aquifer(2012)
    assert len(truth) == 36 and (truth["kind"] != "outside_cloud").sum() == 34
    kept, flags = find_outliers(points, LAYERS)
    removed = flags[~flags["kept"]]
    assert set(zip(removed["id"], removed["layer"])) == set(zip(truth["id"], truth["layer"]))
    by_kind = dict(zip(zip(truth["id"], truth["layer"]), truth["kind"]))
    for row in removed.itertuples():  # each for the right reason, with its residual
        assert row.flag == by_kind[(row.id, row.layer)]
        assert np.isfinite(row.residual)
    assert len(kept) == len(points) - 36


@pytest.fixture(scope="module")
def synthetic():
    points, _ = synthetic_aquifer(2012)
    kept, _ = find_outliers(points, LAYERS)
    return surfaces_of(kept)


def test_synthetic_volumes_and_thickness_within_the_spec_tolerances(synthetic):
    S = synthetic
    exact_r = {("LS", "AU"): 1.5e10, ("AU", "AD"): 8.0e8, ("AD", "AQ"): 62000 / 3 * 1e6}
    tol = {("LS", "AU"): 1e-3, ("AU", "AD"): 3e-2, ("AD", "AQ"): 5e-3}
    for pair, exact in exact_r.items():
        v = overlay_volume(S[pair[0]], S[pair[1]], R)
        assert abs(v["volume"] - exact) / exact <= tol[pair], (pair, v["volume"])
        assert v["area"] == pytest.approx(4e8, rel=1e-12)
    exact_t = {("LS", "AU"): 7.1666667e9, ("AU", "AD"): 6.6666667e8, ("AD", "AQ"): 1.0333333e10}
    for pair, exact in exact_t.items():
        v = overlay_volume(S[pair[0]], S[pair[1]], TRIANGLE)
        assert abs(v["volume"] - exact) / exact <= tol[pair] * 2, (pair, v["volume"])
    # thickness at the query point: analytic values and tolerances of the spec
    qz = {L: height_at(S[L], *QUERY)[0][0] for L in LAYERS}
    assert qz["LS"] - qz["AU"] == pytest.approx(33.819, abs=0.3)
    assert qz["AU"] - qz["AD"] == pytest.approx(5.8896, abs=1.0)
    assert qz["AD"] - qz["AQ"] == pytest.approx(50.27966, abs=2.5)
    # surface error on a 50 m grid in R
    u, v = np.meshgrid(np.arange(5, 25.0001, 0.05), np.arange(5, 25.0001, 0.05))
    truth = surfaces_uv(u, v)
    for layer, limit in (("LS", 4), ("AU", 4), ("AD", 4), ("AQ", 7)):
        z, inside = height_at(S[layer], E0 + 1000 * u.ravel(), N0 + 1000 * v.ravel())
        assert inside.all() and np.max(np.abs(z - truth[layer].ravel())) <= limit, layer


def test_seed_2012_tin_values_at_the_query_point(synthetic):
    S = synthetic
    qz = {L: height_at(S[L], *QUERY)[0][0] for L in LAYERS}
    assert qz["LS"] - qz["AU"] == pytest.approx(33.689, abs=5e-4)
    assert qz["AU"] - qz["AD"] == pytest.approx(5.890, abs=5e-4)
    assert qz["AD"] - qz["AQ"] == pytest.approx(49.356, abs=5e-4)


def test_planar_variant_is_exact():
    points, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    S = surfaces_of(points)
    r = {("LS", "AU"): 1.5e10, ("AU", "AD"): 2.4e9, ("AD", "AQ"): 2.06e10}
    tri = {("LS", "AU"): 7.1666666666666667e9, ("AU", "AD"): 1.2e9, ("AD", "AQ"): 1.0233333333333333e10}
    for pair in r:
        up, lo = S[pair[0]], S[pair[1]]
        assert overlay_volume(up, lo, R)["volume"] == pytest.approx(r[pair], rel=1e-9)
        assert overlay_volume(up, lo, TRIANGLE)["volume"] == pytest.approx(tri[pair], rel=1e-9)
        rng = np.random.default_rng(1)
        uv = rng.uniform(0.5, 29.5, (200, 2))
        truth = surfaces_uv(uv[:, 0], uv[:, 1], planar=True)
        za, _ = height_at(up, E0 + 1000 * uv[:, 0], N0 + 1000 * uv[:, 1])
        zb, _ = height_at(lo, E0 + 1000 * uv[:, 0], N0 + 1000 * uv[:, 1])
        np.testing.assert_allclose(za - zb, truth[pair[0]] - truth[pair[1]], atol=1e-6)
        # closed unit: watertight, consistently wound, volume = overlay volume over the square
        import trimesh

        verts, faces = unit_mesh(up, lo)
        mesh = trimesh.Trimesh(verts - verts.mean(axis=0), faces, process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent
        assert len(faces) - len(up.triangles) - len(lo.triangles) == len(up.ring()) + len(lo.ring())
        whole = overlay_volume(up, lo)["volume"]
        assert mesh.volume == pytest.approx(whole, rel=1e-9) and mesh_volume(verts, faces) == pytest.approx(whole, rel=1e-9)


def test_knn_mean_on_a_plane_is_the_plane_at_the_neighbours_centroid():
    points, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    g = points[points["layer"] == "LS"]
    s = build_surface("LS", g["id"], g["x"], g["y"], g["z"])
    z, inside = height_at(s, *QUERY, method="knn", k=10)
    from scipy.spatial import cKDTree

    _, idx = cKDTree(np.column_stack([g["x"], g["y"]])).query([QUERY], 10)
    cu = (g["x"].to_numpy()[idx[0]].mean() - E0) / 1000
    cv = (g["y"].to_numpy()[idx[0]].mean() - N0) / 1000
    assert z[0] == pytest.approx(surfaces_uv(cu, cv, planar=True)["LS"], abs=1e-9) and inside[0]
    zi, _ = height_at(s, *QUERY, method="idw", k=10)
    assert np.isfinite(zi[0]) and abs(zi[0] - z[0]) < 20


def test_model_outputs_meshes_and_report(tmp_path):
    import geopandas as gpd
    import rasterio
    import trimesh

    points, _ = synthetic_aquifer(2012)
    points.to_csv(tmp_path / "contacts.csv", index=False)
    result = CliRunner().invoke(cli, ["aquifer", "model", str(tmp_path / "contacts.csv"), "--layers", "LS,AU,AD,AQ",
                                      "--crs", "EPSG:3003", "--out", str(tmp_path / "m"), "-q"])
    assert result.exit_code == 0, result.output
    rep = json.loads((tmp_path / "m" / "report.json").read_text())
    assert rep["crs"] == "EPSG:3003"
    assert {L: rep["layers"][L]["flagged"] for L in LAYERS} == {"LS": 0, "AU": 18, "AD": 12, "AQ": 6}
    assert all(rep["layers"][L]["boundary_area"] == pytest.approx(9e8) for L in LAYERS)
    assert set(rep["units"]) == {"LS/AU", "AU/AD", "AD/AQ"}
    for name, u in rep["units"].items():
        assert set(u) >= {"volume", "volume_positive", "volume_negative", "thickness_min", "thickness_mean", "thickness_max"}
        mesh = trimesh.load(rep["outputs"]["meshes"][name], process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent
        if u["crossing_volume"] == 0:  # surfaces do not cross: the closed solid of the two TINs holds their overlay
            assert abs(mesh.volume) == pytest.approx(u["volume_raw"], rel=1e-9)
        with rasterio.open(rep["outputs"]["thickness"][name]) as src:
            t = src.read(1, masked=True)
            cell_area = abs(src.transform.a * src.transform.e)
            assert src.crs.to_epsg() == 3003
            assert float(t.mean()) == pytest.approx(u["thickness_mean"], rel=0.01)
        # the exact overlay volumes against an independent sum of the thickness raster's cells (midpoint rule)
        tv = t.filled(0.0).astype(float)
        assert u["volume_positive"] == pytest.approx(tv[tv > 0].sum() * cell_area, rel=0.01)
        assert u["volume_negative"] == pytest.approx(tv[tv < 0].sum() * cell_area, abs=0.01 * u["volume_positive"])
    assert rep["units"]["AD/AQ"]["volume"] == pytest.approx(4.8375e10, rel=5e-3)
    layers = set(gpd.list_layers(tmp_path / "m" / "aquifer.gpkg")["name"])
    assert {"points", "flags", "links", "walls", "tin_LS", "boundary_AQ"} <= layers
    tin = gpd.read_file(tmp_path / "m" / "aquifer.gpkg", layer="tin_AU")
    assert len(tin) == rep["layers"]["AU"]["triangles"] and tin.has_z.all()
    walls = gpd.read_file(tmp_path / "m" / "aquifer.gpkg", layer="walls")
    assert (walls["unit"] == "LS/AU").sum() == rep["units"]["LS/AU"]["wall_triangles"]
    q = CliRunner().invoke(cli, ["aquifer", "query", str(tmp_path / "m"), "--x", str(QUERY[0]), "--y", str(QUERY[1]),
                                 "--json"])
    assert q.exit_code == 0, q.output
    answer = json.loads(q.output)
    assert answer["thickness"]["LS/AU"] == pytest.approx(33.689, abs=5e-4)
    assert answer["heights"]["AQ"]["inside"] is True
    outside = aquifer_query(tmp_path / "m", E0 - 5000, N0 - 5000)
    assert outside["heights"]["LS"] == {"z": None, "inside": False}
    knn = aquifer_query(tmp_path / "m", *QUERY, method="knn")
    assert knn["heights"]["LS"]["z"] is not None and knn["heights"]["LS"]["inside"]


def test_within_polygon_and_four_file_input(tmp_path):
    import geopandas as gpd

    points, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    files = []
    for layer in LAYERS:  # the dissertation's form: ID East North Height, printed North first (swap)
        g = points[points["layer"] == layer]
        path = tmp_path / f"{layer}Input.txt"
        np.savetxt(path, np.column_stack([g["id"], g["y"], g["x"], g["z"]]), fmt=["%d", "%.17g", "%.17g", "%.17g"],
                   header="ID North East Height", comments="")
        files.append(f"{layer}={path}")
    gpd.GeoDataFrame({"name": ["R"]}, geometry=[R], crs=3003).to_file(tmp_path / "area.gpkg", layer="AREA")
    rep = aquifer_model(files, LAYERS, tmp_path / "m", crs="EPSG:3003", swap_xy=True, within=f"{tmp_path / 'area.gpkg'}:AREA",
                        settings=AquiferSettings(figures=False, mesh_format="obj", densify=True))
    dens = pd.read_csv(rep["outputs"]["densified"]["AQ"])
    assert len(dens) == rep["layers"]["AQ"]["densified_points"] and set(dens["layer"]) == {"AQ"}
    truth = surfaces_uv((dens["x"] - E0) / 1000, (dens["y"] - N0) / 1000, planar=True)["AQ"]
    np.testing.assert_allclose(dens["z"], truth, atol=1e-6)  # on the (planar) TIN
    assert rep["units"]["LS/AU"]["volume"] == pytest.approx(1.5e10, rel=1e-9)
    assert rep["units"]["AU/AD"]["volume"] == pytest.approx(2.4e9, rel=1e-9)
    assert rep["units"]["AU/AD"]["thickness_min"] == pytest.approx(6.0, abs=1e-6)
    assert rep["units"]["AU/AD"]["thickness_max"] == pytest.approx(6.0, abs=1e-6)
    assert rep["outputs"]["meshes"]["LS/AU"].endswith(".obj")


@pytest.mark.parametrize("case", ["missing_column", "unknown_layer", "text_z", "too_few"])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, case):
    points, _ = synthetic_aquifer(2012, outliers=False)
    df = points.copy()
    if case == "missing_column":
        df = df.drop(columns="z")
    elif case == "unknown_layer":
        df.loc[5, "layer"] = "XX"
    elif case == "text_z":
        df["z"] = df["z"].astype(object)
        df.loc[7, "z"] = "n/a"
    else:
        df = df[(df["layer"] != "AQ") | (df.index.isin(df.index[df["layer"] == "AQ"][:2]))]
    df.to_csv(tmp_path / "c.csv", index=False)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["aquifer", "model", str(tmp_path / "c.csv"), "--layers", "LS,AU,AD,AQ", "--crs",
                                      "EPSG:3003", "--out", str(out), "-q"])
    assert result.exit_code == 1
    message = result.output.strip()
    assert message.count("\n") == 0 and "Traceback" not in message and "c.csv" in message
    expect = {"missing_column": "no z column", "unknown_layer": "line 7: layer 'XX' is not in --layers",
              "text_z": "line 9: z 'n/a' is not a number", "too_few": "layer AQ has 2 point(s)"}[case]
    assert expect in message
    assert not out.exists()


# ---------------------------------------------------------------- real data: seismic horizons

def test_claudius_horizons_through_the_whole_model(tmp_path):
    need_shared(SHARED_DATA / "aquifer" / "claudius.csv")
    import geopandas as gpd

    raw = pd.read_csv(SHARED_DATA / "aquifer" / "claudius.csv")
    raw = raw[raw["val"].notna()]  # the rows without a horizon value are orientation data
    names = {0.0: "H0", 60.0: "H60", 250.0: "H250", 330.0: "H330"}  # top to base (data README)
    table = pd.DataFrame({"id": np.arange(1, len(raw) + 1), "x": raw["X"], "y": raw["Y"], "z": raw["Z"],
                          "layer": raw["val"].map(names)})
    table.to_csv(tmp_path / "claudius.csv", index=False)
    layers = list(names.values())
    local = ('ENGCRS["local grid (the data name no CRS), metres",EDATUM["unknown"],CS[Cartesian,2],'
             'AXIS["easting (x)",east,ORDER[1],LENGTHUNIT["metre",1]],AXIS["northing (y)",north,ORDER[2],LENGTHUNIT["metre",1]]]')
    rep = aquifer_model(tmp_path / "claudius.csv", layers, tmp_path / "m", crs=local,
                        settings=AquiferSettings(figures=False))
    kept = gpd.read_file(tmp_path / "m" / "aquifer.gpkg", layer="points")
    model = load_model(tmp_path / "m")
    assert len(kept) + sum(rep["layers"][L]["flagged"] for L in layers) == len(table)
    rng = np.random.default_rng(3)
    interp = {}
    for L in layers:
        g = kept[kept["layer"] == L]
        xy = np.column_stack([g["x"], g["y"]])
        assert rep["layers"][L]["boundary_area"] == pytest.approx(ConvexHull(xy).volume, rel=1e-9)
        # seismic picks lie on a grid, where the Delaunay triangulation is not unique (co-circular points):
        # scipy gets the same coordinates gistools triangulates, centred on the layer's mean
        centre = xy.mean(axis=0)
        interp[L] = (LinearNDInterpolator(xy - centre, g["z"].to_numpy()), centre)
    for up, lo in zip(layers[:-1], layers[1:]):
        name = f"{up}/{lo}"
        # thickness at sampled points against scipy's linear interpolation of the same points
        gx = kept.loc[kept["layer"] == up, "x"]
        gy = kept.loc[kept["layer"] == up, "y"]
        qx, qy = rng.uniform(gx.min(), gx.max(), 50), rng.uniform(gy.min(), gy.max(), 50)
        def at(layer, x, y):
            f, c = interp[layer]
            return f(x - c[0], y - c[1])

        expect = at(up, qx, qy) - at(lo, qx, qy)
        got = np.array([query_model(model, x, y)["thickness"][name] or np.nan for x, y in zip(qx, qy)])
        ok = np.isfinite(expect)
        assert ok.sum() > 20
        np.testing.assert_allclose(got[ok], expect[ok], atol=1e-6)
        # volume against a fine-grid integration over the common footprint
        foot = shapely.intersection(shapely.convex_hull(shapely.multipoints(kept.loc[kept["layer"] == up, ["x", "y"]].to_numpy())),
                                    shapely.convex_hull(shapely.multipoints(kept.loc[kept["layer"] == lo, ["x", "y"]].to_numpy())))
        w, s, e, n = foot.bounds
        cell = 5.0
        X, Y = np.meshgrid(np.arange(w + cell / 2, e, cell), np.arange(s + cell / 2, n, cell))
        t = at(up, X, Y) - at(lo, X, Y)
        grid_volume = np.nansum(t) * cell * cell
        assert rep["units"][name]["volume"] == pytest.approx(grid_volume, rel=5e-3), name
        assert rep["units"][name]["thickness_min"] <= np.nanmin(t) + 1e-6
        assert rep["units"][name]["thickness_max"] >= np.nanmax(t) - 1e-6
        import trimesh

        mesh = trimesh.load(rep["outputs"]["meshes"][name], process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent


def test_clip_polygon_and_concave_outline_cut_the_surfaces(tmp_path):
    import geopandas as gpd

    from gistools.aquifer.surface import mask_outside

    points, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    g = points[points["layer"] == "LS"]
    s = build_surface("LS", g["id"], g["x"], g["y"], g["z"])
    # an L-shaped outline with a hole: the dissertation's concave / hole rule
    outline = shapely.Polygon([(E0, N0), (E0 + 30000, N0), (E0 + 30000, N0 + 15000), (E0 + 15000, N0 + 15000),
                               (E0 + 15000, N0 + 30000), (E0, N0 + 30000)],
                              [[(E0 + 3000, N0 + 3000), (E0 + 8000, N0 + 3000), (E0 + 8000, N0 + 8000), (E0 + 3000, N0 + 8000)]])
    cut = mask_outside(s, outline)
    assert len(cut.triangles) < len(s.triangles) and len(cut.rings) == 2  # outer ring and the hole
    assert cut.outline().area == pytest.approx(outline.area, rel=0.05)
    z, inside = height_at(cut, [E0 + 5500, E0 + 25000, E0 + 10000], [N0 + 5500, N0 + 25000, N0 + 10000])
    assert list(inside) == [False, False, True] and np.isnan(z[:2]).all()
    gpd.GeoDataFrame({"n": [1]}, geometry=[outline], crs=3003).to_file(tmp_path / "clip.gpkg", layer="clip")
    pts = tmp_path / "p.csv"
    points.to_csv(pts, index=False)
    rep = aquifer_model(pts, LAYERS, tmp_path / "m", crs="EPSG:3003", clip=f"{tmp_path / 'clip.gpkg'}:clip",
                        settings=AquiferSettings(figures=False))
    # planar surfaces: the unit's volume is its (clipped) area times the exact mean thickness
    area = rep["units"]["LS/AU"]["area"]
    assert area == pytest.approx(rep["layers"]["LS"]["boundary_area"] - 25e6, rel=0.05)
    assert rep["units"]["AU/AD"]["volume"] == pytest.approx(6.0 * rep["units"]["AU/AD"]["area"], rel=1e-9)
    import trimesh

    for name in rep["units"]:  # walls close the outer outline and the hole
        mesh = trimesh.load(rep["outputs"]["meshes"][name], process=False)
        assert mesh.is_watertight and mesh.is_winding_consistent and rep["units"][name]["mesh_closed"]
    concave = aquifer_model(pts, LAYERS, tmp_path / "c", crs="EPSG:3003",
                            settings=AquiferSettings(figures=False, concave_ratio=0.3))
    assert all(concave["layers"][L]["boundary_area"] <= 9e8 + 1 for L in LAYERS)


def test_contacts_with_other_column_names_read_through_the_chosen_fields(tmp_path):
    """QGIS's field pickers and --fields: a table whose columns are named otherwise reads as the usual one."""
    from gistools.io.contacts import read_contacts

    points, _ = synthetic_aquifer(2012, planar=True, outliers=False)
    points.to_csv(tmp_path / "usual.csv", index=False)
    points.rename(columns={"z": "ELEV", "layer": "FORM", "id": "PID"}).to_csv(tmp_path / "other.csv", index=False)
    layers = ["LS", "AU", "AD", "AQ"]
    usual, _ = read_contacts(tmp_path / "usual.csv", layers, crs="EPSG:3003")
    other, _ = read_contacts(tmp_path / "other.csv", layers, crs="EPSG:3003", fields={"z": "ELEV", "layer": "FORM", "id": "PID"})
    assert np.array_equal(usual[["id", "x", "y", "z"]].to_numpy(), other[["id", "x", "y", "z"]].to_numpy())
    with pytest.raises(InputError, match="the z field 'HEIGHT' is not a column"):
        read_contacts(tmp_path / "other.csv", layers, crs="EPSG:3003", fields={"z": "HEIGHT", "layer": "FORM"})
    r = CliRunner().invoke(cli, ["aquifer", "model", str(tmp_path / "other.csv"), "--layers", ",".join(layers), "--crs",
                                 "EPSG:3003", "--fields", "z=ELEV,layer=FORM,id=PID", "--no-figures", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output


def test_a_unit_that_pinches_out_has_no_negative_thickness_and_its_analytic_volume(tmp_path):
    """AU/AD of the synthetic aquifer thins to 0 at v = 15 km (T = max(0, 12 - 0.8 v) m) and its base has fewer boreholes
    than its top: the two TINs cross (the raw order reports -7.7 m). The stratigraphic order (the isopach of the
    boreholes) keeps thickness >= 0 and the analytic volume, 30 km x the integral of T over v = 2.7e9 m3, within 1 %;
    the other two units (linear and quadratic thickness) against their analytic volumes too."""
    points, _ = synthetic_aquifer(2012)
    points.to_csv(tmp_path / "contacts.csv", index=False)
    points = tmp_path / "contacts.csv"
    layers = ["LS", "AU", "AD", "AQ"]
    analytic = {"LS/AU": 9e8 * 37.5, "AU/AD": 30e3 * 1e3 * (12 * 15 - 0.4 * 15 ** 2), "AD/AQ": 9e8 * (50 + 0.05 * 75)}
    model = build_model(points, layers, crs="EPSG:3003")
    compute_units(model, AquiferSettings())
    for name, volume in analytic.items():
        u = model.units[name]
        assert u["thickness_method"] == "isopach" and u["volume"]["volume"] == pytest.approx(volume, rel=0.01), name
        assert u["thickness_min"] >= 0 and np.nanmin(u["thickness"][0]) >= 0
    assert model.units["AU/AD"]["crossing_area"] > 1e8 and model.units["AU/AD"]["crossing_volume"] > 1e7  # reported
    raw = build_model(points, layers, crs="EPSG:3003", settings=AquiferSettings(order="raw"))
    compute_units(raw, AquiferSettings(order="raw"))
    assert raw.units["AU/AD"]["thickness_min"] < -5 and raw.units["AU/AD"]["volume"]["volume_negative"] < 0
    grid_t, grid = raw.units["AU/AD"]["thickness"]
    r, c = np.unravel_index(np.nanargmin(grid_t), grid_t.shape)  # where the raw TINs cross the most
    x, y = affine_apply(grid.transform, (c + 0.5, r + 0.5))
    assert query_model(raw, x, y)["thickness"]["AU/AD"] < -5
    ordered = query_model(model, x, y)
    assert ordered["thickness"]["AU/AD"] == 0 and ordered["heights"]["AD"]["z_raw"] > ordered["heights"]["AD"]["z"]
