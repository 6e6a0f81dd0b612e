"""gistools' compiled Delaunay kernel against Triangle, scipy and the empty-circle property."""

import os

import numpy as np
import pytest
from scipy.spatial import ConvexHull, cKDTree

from conftest import ROOT, need_kernel

from gistools.grid import cell_centres, snapped_grid
from gistools.lidar import tin
from gistools.lidar.tin import delaunay_triangles, tin_engine, tin_to_grid


def test_an_unknown_engine_is_refused():
    with pytest.raises(ValueError, match="not one of kernel, triangle, qhull"):
        tin_to_grid(np.arange(3.0), np.arange(3.0), np.arange(3.0), snapped_grid((0, 0, 3, 3), 1.0), engine="delaunator")


def test_the_kernel_is_built_where_ci_runs():
    # the install (tools/run.sh: pip install -e .) compiles it; without it TINs fall back to Triangle, 3x slower
    if os.environ.get("CI") and os.environ.get("GISTOOLS_TIN", "") != "triangle":
        assert tin_engine() == "kernel"
    elif tin_engine() != "kernel":
        pytest.skip("the compiled TIN kernel is not built here (no C compiler at install): Triangle is used")


def test_every_declared_entry_point_is_in_the_built_kernel():
    """csrc/gistools_kernel.h declares the kernel once; the built module exports each of its functions."""
    import re

    from gistools import kernel

    need_kernel()
    header = (ROOT / "csrc" / "gistools_kernel.h").read_text()
    declared = sorted(re.findall(r"^(?:int64_t|void|double) (gt_\w+)\(", header, re.M))
    assert len(declared) == 21 and kernel.names() == declared


def test_a_wrong_call_is_a_type_error_not_corrupted_memory():
    from gistools import kernel

    fn = kernel.function("gt_cell_min")
    if fn is None:
        need_kernel()
    flat, z, out = np.zeros(3, np.int64), np.ones(3), np.full(1, np.inf)
    fn(3, flat, z, out)
    assert out[0] == 1.0
    with pytest.raises(TypeError, match="int64_t array needed, got int32"):
        fn(3, flat.astype(np.int32), z, out)
    with pytest.raises(TypeError, match="C-contiguous"):
        fn(3, flat, np.ones(6)[::2], out)
    with pytest.raises(TypeError, match="takes 4 arguments"):
        fn(3, flat, z)
    with pytest.raises(TypeError):
        fn("3", flat, z, out)


def test_the_portable_128_bit_predicate_equals_the_compilers_and_exact_integers(tmp_path):
    """csrc/int128.h: the two-word form (for compilers without __int128, MSVC) and the __int128 form give the sign
    of the in-circle determinant that Python's exact integers give, on random, extreme and cocircular inputs."""
    import shutil
    import subprocess

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler here")
    driver = """#include <stdio.h>
#include "int128.h"
int SIGN(int64_t a, int64_t b, int64_t c, int64_t d, int64_t e, int64_t f) { return incircle_exact_sign(a, b, c, d, e, f); }
"""
    (tmp_path / "native.c").write_text(driver.replace("SIGN", "native_sign"))
    (tmp_path / "portable.c").write_text("#define GISTOOLS_PORTABLE_INT128\n" + driver.replace("SIGN", "portable_sign"))
    (tmp_path / "main.c").write_text("""#include <stdio.h>
#include <stdint.h>
int native_sign(int64_t, int64_t, int64_t, int64_t, int64_t, int64_t);
int portable_sign(int64_t, int64_t, int64_t, int64_t, int64_t, int64_t);
int main(void) {
    long long v[6];
    while (scanf("%lld %lld %lld %lld %lld %lld", v, v + 1, v + 2, v + 3, v + 4, v + 5) == 6)
        printf("%d %d\\n", native_sign(v[0], v[1], v[2], v[3], v[4], v[5]), portable_sign(v[0], v[1], v[2], v[3], v[4], v[5]));
    return 0;
}
""")
    exe = tmp_path / "check"
    subprocess.run([cc, "-O2", "-std=c99", f"-I{ROOT / 'csrc'}", "native.c", "portable.c", "main.c", "-o", str(exe)],
                   cwd=tmp_path, check=True)
    rng = np.random.default_rng(11)
    top = 2**30
    cases = [rng.integers(-top, top + 1, 6) for _ in range(3000)]
    cases += [rng.choice([-top, top, 0, 1, -1, top - 1], 6) for _ in range(1000)]
    for _ in range(1000):  # cocircular: a, b, c, p on one circle about the origin (Pythagorean points)
        r = int(rng.integers(1, 2**14))
        pts = [(r * 5, 0), (r * 3, r * 4), (-r * 4, r * 3), (0, -r * 5), (r * 4, -r * 3)]
        k = rng.permutation(5)[:4]
        (ax, ay), (bx, by), (cx, cy), (px, py) = (pts[i] for i in k)
        cases.append(np.array([ax - px, ay - py, bx - px, by - py, cx - px, cy - py]))
    text = "\n".join(" ".join(str(int(v)) for v in c) for c in cases) + "\n"
    got = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout.split("\n")
    for case, line in zip(cases, got):
        dx, dy, ex, ey, fx, fy = (int(v) for v in case)
        ap, bp, cp = dx * dx + dy * dy, ex * ex + ey * ey, fx * fx + fy * fy
        det = dx * (ey * cp - bp * fy) - dy * (ex * cp - bp * fx) + ap * (ex * fy - ey * fx)
        want = (det > 0) - (det < 0)
        assert line.split() == [str(want), str(want)], (case.tolist(), line, want)
    assert any(line.split()[0] == "0" for line in got[-1000:])  # the cocircular cases reach the exact path


def test_the_portable_kernel_triangulates_as_the_int128_kernel(tmp_path):
    """The whole kernel built with the two-word 128-bit form (as on MSVC) gives the same triangles as the
    __int128 build, point for point, on lattices (every quad cocircular: the exact path decides), rings of
    cocircular points, repeats and random points over the kernel's whole 2^30 span."""
    import importlib.util
    import subprocess
    import sys

    need_kernel()
    from gistools._kernel import ffi as native_ffi, lib as native

    # built in a fresh interpreter: QGIS, loaded by other tests of a session, puts a `long` into builtins, which
    # makes cffi's build code try Python 2's cStringIO
    script = f"""
import runpy
from cffi import FFI
build = runpy.run_path({str(ROOT / "csrc" / "kernel_build.py")!r})
ffi = FFI()
ffi.cdef(build["declarations"]())
ffi.set_source("_kernel_portable", '#include "gistools_kernel.h"',
               sources=[{str(ROOT / "csrc")!r} + "/" + s for s in build["SOURCES"]], include_dirs=[{str(ROOT / "csrc")!r}],
               define_macros=[("GISTOOLS_PORTABLE_INT128", None)], extra_compile_args=build["FLAGS"])
print(ffi.compile(tmpdir={str(tmp_path)!r}))
"""
    built = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()[-1]
    spec = importlib.util.spec_from_file_location("_kernel_portable", built)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    portable, pffi = module.lib, module.ffi

    def triangles(lib, f, x, y):
        tris, repeats = np.empty(6 * len(x), np.int32), np.zeros(1, np.int64)
        m = lib.gt_delaunay(len(x), f.from_buffer("int64_t[]", x), f.from_buffer("int64_t[]", y),
                            f.from_buffer("int32_t[]", tris), f.from_buffer("int64_t[]", repeats))
        return tris[: 3 * m].copy(), int(repeats[0])

    rng = np.random.default_rng(5)
    gx, gy = np.meshgrid(np.arange(60), np.arange(60))
    angles = rng.uniform(0, 2 * np.pi, 400)
    cases = {
        "lattice": (gx.ravel() * 1000, gy.ravel() * 1000),
        "lattice with repeats": (np.r_[gx.ravel(), gx.ravel()[:50]] * 7, np.r_[gy.ravel(), gy.ravel()[:50]] * 7),
        "random over 2^30": (rng.integers(0, 2**30, 5000), rng.integers(0, 2**30, 5000)),
        "cocircular ring": (np.rint(2**29 + 2**28 * np.cos(angles)), np.rint(2**29 + 2**28 * np.sin(angles))),
    }
    for name, (x, y) in cases.items():
        x, y = np.ascontiguousarray(x, np.int64), np.ascontiguousarray(y, np.int64)
        a, b = triangles(native, native_ffi, x, y), triangles(portable, pffi, x, y)
        assert len(a[0]) > 0 and np.array_equal(a[0], b[0]) and a[1] == b[1], name
    sys.modules.pop("_kernel_portable", None)


def test_the_kernel_compiles_for_windows_without_int128(tmp_path):
    """The C is portable: every part cross-compiles for Windows (MinGW-w64) with -Wall -Werror and the two-word
    128-bit form (as MSVC, which has no __int128, builds it), and the DLL exports every declared entry point."""
    import shutil
    import subprocess

    cc = shutil.which("x86_64-w64-mingw32-gcc")
    if cc is None:
        if os.environ.get("CI"):
            pytest.fail("CI must check the Windows build: tools/run.sh test installs gcc-mingw-w64-x86-64")
        pytest.skip("no MinGW-w64 cross compiler here (apt-get install gcc-mingw-w64-x86-64)")
    objects = []
    for part in ("tin", "morphology", "grid", "scan"):
        obj = tmp_path / f"{part}.o"
        subprocess.run([cc, "-O2", "-std=c99", "-Wall", "-Wextra", "-Wno-unused-parameter", "-Werror",
                        "-DGISTOOLS_PORTABLE_INT128", "-c", str(ROOT / "csrc" / f"{part}.c"), "-o", str(obj)], check=True)
        objects.append(str(obj))
    dll = tmp_path / "kernel.dll"
    subprocess.run([cc, "-shared", "-o", str(dll), *objects], check=True)
    exports = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True, text=True).stdout
    header = (ROOT / "csrc" / "gistools_kernel.h").read_text()
    import re

    for name in re.findall(r"^(?:int64_t|void|double) (gt_\w+)\(", header, re.M):
        assert re.search(rf"\b{name}\b", exports), name


def test_the_version_line_says_which_engine_runs():
    from click.testing import CliRunner

    from gistools import kernel
    from gistools.cli.main import cli

    text = CliRunner().invoke(cli, ["--version"]).output
    assert "gistools, version" in text and kernel.engine() in text
    assert ("compiled C kernel" in text) == kernel.loaded()


pytestmark_kernel = pytest.mark.skipif(tin.tin_engine() != "kernel" and not os.environ.get("CI"),
                                       reason="the compiled TIN kernel is not built (CI builds it: there the tests run)")


def _check_delaunay(x, y, tris):
    """Every triangle counter-clockwise or clockwise consistently, no point strictly inside a circumcircle,
    and the triangles tile the convex hull (areas sum to the hull's)."""
    p = np.column_stack([x, y])
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert (cross < 0).all() or (cross > 0).all()
    hull = ConvexHull(p)
    assert np.abs(cross).sum() / 2 == pytest.approx(hull.volume, rel=1e-9)
    # circumcircles
    d = 2 * cross
    al, bl, cl = (v[:, 0] ** 2 + v[:, 1] ** 2 for v in (a, b, c))
    ux = (al * (b[:, 1] - c[:, 1]) + bl * (c[:, 1] - a[:, 1]) + cl * (a[:, 1] - b[:, 1])) / d
    uy = (al * (c[:, 0] - b[:, 0]) + bl * (a[:, 0] - c[:, 0]) + cl * (b[:, 0] - a[:, 0])) / d
    r = np.hypot(a[:, 0] - ux, a[:, 1] - uy)
    tree = cKDTree(p)
    inside = tree.query_ball_point(np.column_stack([ux, uy]), r * (1 - 1e-9))
    vertex_xy = {(x[v], y[v]) for v in np.unique(tris)}
    for k, pts in enumerate(inside):
        extra = [q for q in pts if q not in tris[k] and (x[q], y[q]) not in vertex_xy]  # repeats of a vertex aside
        assert not extra, f"triangle {k} is not Delaunay: points {extra} inside"


@pytestmark_kernel
def test_random_points_give_triangles_identical_to_triangle():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(400000, 401500, 20000), rng.uniform(1.8e6, 1.8e6 + 900, 20000)
    ours = delaunay_triangles(x, y, engine="kernel")
    theirs = delaunay_triangles(x, y, engine="triangle")
    assert {tuple(sorted(t)) for t in ours.tolist()} == {tuple(sorted(t)) for t in theirs.tolist()}
    _check_delaunay(x, y, ours)


@pytestmark_kernel
@pytest.mark.parametrize("case", ["lattice", "quantised", "repeats", "circle", "clustered"])
def test_degenerate_inputs_give_a_delaunay_triangulation(case):
    rng = np.random.default_rng(11)
    if case == "lattice":  # every quad cocircular, many collinear triples
        g = np.arange(60.0)
        x, y = (a.ravel() for a in np.meshgrid(g, g))
    elif case == "quantised":  # LAS-like 0.01 ft steps on large coordinates (a few positions repeat)
        x = np.round(rng.uniform(0, 60, 30000), 2) + 412345.0
        y = np.round(rng.uniform(0, 60, 30000), 2) + 1812345.0
    elif case == "repeats":
        x, y = rng.uniform(0, 100, 5000), rng.uniform(0, 100, 5000)
        x, y = np.r_[x, x[:1000], x[:10]], np.r_[y, y[:1000], y[:10]]
    elif case == "circle":  # all points on one circle, plus its centre
        t = np.linspace(0, 2 * np.pi, 360, endpoint=False)
        x, y = np.r_[np.cos(t) * 100, 0.0], np.r_[np.sin(t) * 100, 0.0]
    else:  # dense clusters far apart
        c = rng.uniform(0, 1e5, (20, 2))
        p = (c[:, None, :] + rng.normal(0, 0.5, (20, 500, 2))).reshape(-1, 2)
        x, y = p[:, 0], p[:, 1]
    tris = delaunay_triangles(x, y)
    if case == "lattice":  # quantisation may split cocircular quads either way, never leave a gap
        assert len(tris) == 2 * 59 * 59
    _check_delaunay(x, y, tris)
    # every distinct position is a vertex, once (repeats: one of them)
    assert len(np.unique(tris)) == len(np.unique(np.column_stack([x, y]), axis=0))


@pytestmark_kernel
def test_collinear_and_tiny_inputs_give_no_area():
    assert len(delaunay_triangles(np.arange(2.0), np.arange(2.0))) == 0
    assert len(delaunay_triangles(np.zeros(5), np.zeros(5))) == 0
    g = snapped_grid((0, 0, 10, 10), 1.0)
    dem = tin_to_grid(np.arange(10.0), np.arange(10.0), np.arange(10.0), g)
    assert np.isnan(dem).all()  # a line covers no cell centre's triangle


@pytestmark_kernel
@pytest.mark.parametrize("max_edge", [None, 9.0])
def test_kernel_grid_equals_the_triangle_engine(max_edge):
    rng = np.random.default_rng(5)
    x = np.r_[rng.uniform(0, 300, 40000), rng.uniform(300, 600, 800)]  # a sparse half: long edges there
    y = np.r_[rng.uniform(0, 300, 40000), rng.uniform(0, 300, 800)]
    z = np.sin(x / 17) + 0.01 * y + rng.normal(0, 0.05, x.size)
    g = snapped_grid((-10, -10, 610, 310), 2.0)
    ours = tin_to_grid(x, y, z, g, max_edge=max_edge, engine="kernel")
    theirs = tin_to_grid(x, y, z, g, max_edge=max_edge, engine="triangle")
    assert np.array_equal(np.isnan(ours), np.isnan(theirs))
    assert np.nanmax(np.abs(ours - theirs)) < 1e-9
    assert np.isfinite(ours).sum() > 0.4 * ours.size


@pytest.mark.parametrize("max_edge", [None, 9.0])
def test_the_qhull_fallback_grid_equals_the_kernel_and_merges_repeats(max_edge):
    # the fallback where neither the kernel nor Triangle (no build for Python 3.14) is there
    rng = np.random.default_rng(6)
    x = np.round(np.r_[rng.uniform(0, 300, 30000), rng.uniform(300, 600, 600)], 2)
    y = np.round(np.r_[rng.uniform(0, 300, 30000), rng.uniform(0, 300, 600)], 2)
    x, y = np.r_[x, x[:500]], np.r_[y, y[:500]]  # 500 repeated positions (overlapping flight lines)
    z = np.sin(x / 17) + 0.01 * y
    z[-500:] += 1.0  # the repeats' mean is their first's z + 0.5
    g = snapped_grid((-10, -10, 610, 310), 2.0)
    ours = tin_to_grid(x, y, z, g, max_edge=max_edge, engine="qhull")
    reference = tin_to_grid(x, y, z, g, max_edge=max_edge, engine=tin_engine() if tin_engine() != "qhull" else "qhull")
    assert np.array_equal(np.isnan(ours), np.isnan(reference))
    assert np.nanmax(np.abs(ours - reference)) < 1e-9
    flat = snapped_grid((0, 0, 300, 300), 2.0)  # on a plane, repeats or not, the TIN is the plane
    zp = 3 + 0.02 * x - 0.01 * y
    plane = tin_to_grid(x, y, zp, flat, engine="qhull")
    cx, cy = cell_centres(flat)
    assert np.isfinite(plane).sum() > 0.9 * plane.size
    assert np.nanmax(np.abs(plane - (3 + 0.02 * cx[None, :] - 0.01 * cy[:, None]))) < 1e-9


@pytestmark_kernel
@pytest.mark.parametrize("max_distance,halo", [(15.0, 30.0), (60.0, 120.0)])
def test_dem_from_a_thin_halo_equals_the_tin_of_all_points(max_distance, halo):
    # tin_dem_with_halo builds the TIN on the points near the grid and recomputes only cells whose triangle
    # it cannot prove Delaunay for all the points: gaps across the edges, a lake inside, a sparse corner
    from gistools.lidar.gridding import dem_from_ground_points, tin_dem_with_halo

    rng = np.random.default_rng(9)
    x, y = rng.uniform(0, 400, 120000), rng.uniform(0, 400, 120000)
    gap = ((np.hypot(x - 100, y - 42) < 30) | (np.hypot(x - 200, y - 200) < 40) | ((x > 300) & (x < 312))
           | ((x > 330) & (y > 330) & (rng.uniform(size=x.size) < 0.97)))
    x, y = x[~gap], y[~gap]
    z = 50 + 0.05 * x + np.sin(y / 13) + rng.normal(0, 0.05, x.size)
    g = snapped_grid((halo, halo, 400 - halo, 400 - halo), 2.0)
    full = dem_from_ground_points(x, y, z, g, method="tin", max_distance=max_distance)
    fast = tin_dem_with_halo(x, y, z, g, halo=halo, max_distance=max_distance)
    assert np.array_equal(np.isnan(full), np.isnan(fast))
    assert np.nanmax(np.abs(full - fast)) < 1e-9
    assert 0.5 < np.isfinite(fast).mean() < (1.0 if max_distance < 30 else 1.01)  # short limit: the gaps make nodata
    # a block edge: no point beyond the grid on two sides
    g2 = snapped_grid((0, 0, 400 - halo, 400 - halo), 2.0)
    full = dem_from_ground_points(x, y, z, g2, method="tin", max_distance=max_distance)
    fast = tin_dem_with_halo(x, y, z, g2, halo=halo, max_distance=max_distance)
    assert np.array_equal(np.isnan(full), np.isnan(fast)) and np.nanmax(np.abs(full - fast)) < 1e-9


def test_tin_at_points_equals_scipy_and_takes_the_lowest_of_repeats():
    """The kernel's point location (gt_tin_at) against scipy's LinearNDInterpolator on generic points; a query at a
    repeated position gets the lowest z there, searched for or given as a vertex."""
    from scipy.interpolate import LinearNDInterpolator

    from gistools.lidar.tin import tin_at_points

    rng = np.random.default_rng(3)
    x, y = rng.uniform(0, 500, 20_000) + 4e5, rng.uniform(0, 500, 20_000) + 1.8e6
    z = np.sin(x / 30) * 5 + y / 100
    qx, qy = rng.uniform(-10, 510, 50_000) + 4e5, rng.uniform(-10, 510, 50_000) + 1.8e6
    want = LinearNDInterpolator(np.column_stack([x - 4e5, y - 1.8e6]), z)(qx - 4e5, qy - 1.8e6)
    got = tin_at_points(x, y, z, qx, qy)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, atol=1e-7, equal_nan=True)
    # a repeated point with a lower z: the surface takes it, for a query there and for the vertex given
    x2, y2, z2 = np.append(x, x[5]), np.append(y, y[5]), np.append(z, z[5] - 3)
    vertex = np.array([5, -1])
    got = tin_at_points(x2, y2, z2, np.array([x[5], x[5]]), np.array([y[5], y[5]]), vertex=vertex)
    assert got == pytest.approx([z[5] - 3, z[5] - 3])


def test_quantisation_rounds_as_numpy_rint():
    """The kernel's integer coordinates (compiled, AVX2 where the CPU has it): rint((v - v0) * scale), halves to
    even as numpy's rint, and the largest distance to an integer, on LAS-like values and exact halves."""
    from gistools.lidar.tin import _to_integers

    rng = np.random.default_rng(2)
    v = np.concatenate([np.round(rng.uniform(400000, 405000, 100_001), 2), 400000 + np.arange(-8, 9) * 0.5])
    for v0, scale in ((400000.0, 100.0), (400000.0, 2.0), (0.0, 2.0 ** -4)):
        q, worst = _to_integers(v, v0, scale)
        r = (v - v0) * scale
        assert np.array_equal(q, np.rint(r).astype(np.int64))
        assert worst == np.abs(r - np.rint(r)).max()
