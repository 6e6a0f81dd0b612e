"""The Windows ABI executed, not only compiled: gistools' C kernel built with MinGW-w64 and run under Wine gives the
native build's results bit for bit, on every entry point of csrc/gistools_kernel.h.

tests/windows/driver.c replays recorded calls (each entry point's numbers and input arrays, from a file) and writes
what each call returned and left in its arrays. The calls themselves (thunks.h) are written here from the header,
so the driver follows it. The driver is built twice: natively (gcc, csrc/kernel_build.py's flags: the build Python
loads) and as a statically linked .exe (x86_64-w64-mingw32-gcc -O2, the two-word 128-bit arithmetic MSVC builds),
run under wine64 in a fresh prefix. Both replay the same calls; their outputs must be equal byte for byte.

CASES makes the calls, from a sample tile's points and grids made of them: realistic sizes, ties, NaNs where a
function takes them, negative zeros. Every entry point the header declares needs a case: a new one without one
fails. Without wine64 or the MinGW compiler the Wine run is skipped (it fails instead in CI, where tools/run.sh
installs both).
"""

from __future__ import annotations

import os
import re
import shutil
import struct
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import laspy
import numpy as np
import pytest

from conftest import ROOT, SAMPLE, need_kernel

CSRC = ROOT / "csrc"
HEADER = CSRC / "gistools_kernel.h"
DRIVER = ROOT / "tests" / "windows" / "driver.c"
MINGW = "x86_64-w64-mingw32-gcc"


# ------------------------------------------------------------------------------------------------ the header

@dataclass(frozen=True)
class Param:
    name: str
    ctype: str  # the element type of a pointer, else the scalar type
    pointer: bool
    const: bool


def entry_points() -> dict[str, tuple[str, list[Param]]]:
    """Every entry point of the header: name -> (return type, parameters)."""
    text = re.sub(r"/\*.*?\*/", "", HEADER.read_text(), flags=re.S)
    found = {}
    for ret, name, args in re.findall(r"^(\w+)\s+(gt_\w+)\s*\(([^;]*)\)\s*;", text, re.M):
        params = []
        for arg in " ".join(args.split()).split(","):
            m = re.fullmatch(r"(const )?(\w+) ?(\*)? ?(\w+)", arg.strip())
            assert m, f"{name}: cannot read the parameter {arg!r}"
            params.append(Param(m[4], m[2], bool(m[3]), bool(m[1])))
        found[name] = (ret, params)
    declared = set(re.findall(r"\b(gt_\w+)\s*\(", text))
    assert declared == set(found), f"prototypes not read: {sorted(declared - set(found))}"
    return found


SCALARS = {"int64_t": "i", "int32_t": "i", "double": "d"}
RETURNS = {"void", "int64_t", "double"}
DTYPES = {"double": np.float64, "float": np.float32, "int64_t": np.int64, "int32_t": np.int32, "uint8_t": np.uint8,
          "char": np.uint8}


def thunks(points) -> str:
    """thunks.h: one call_NAME per entry point (the arguments cast to the header's types) and the table THUNKS."""
    lines = ["/* written by tests/test_kernel_windows.py from csrc/gistools_kernel.h */"]
    for name, (ret, params) in points.items():
        args = ", ".join(f"({'const ' if p.const else ''}{p.ctype} *)a[{k}].p" if p.pointer
                         else f"({p.ctype})a[{k}].{SCALARS[p.ctype]}" for k, p in enumerate(params))
        body = f"{name}({args});" if ret == "void" else f"{ret} r = {name}({args}); memcpy(ret, &r, sizeof r);"
        lines.append(f"static void call_{name}(Arg *a, unsigned char *ret) {{ (void)ret; {body} }}")
    lines.append("static const Thunk THUNKS[] = {")
    lines += [f'    {{"{name}", {len(params)}, call_{name}}},' for name, (_, params) in points.items()]
    lines.append("};")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------------ the calls

@dataclass(frozen=True)
class View:
    """A pointer `offset` bytes into the array given as the argument named `of` (strided LAS record fields)."""
    of: str
    offset: int


CASES = {}  # entry point -> a function of the shared data giving its calls (dicts: parameter name -> value)


def case(name):
    def register(fn):
        CASES[name] = fn
        return fn
    return register


def encode(name: str, params: list[Param], args: dict) -> bytes:
    """One call in the driver's format, each value checked against its parameter."""
    assert set(args) == {p.name for p in params}, f"{name}: arguments {sorted(args)} are not the header's"
    out = [struct.pack("<i", len(name)), name.encode(), struct.pack("<i", len(params))]
    position = {p.name: k for k, p in enumerate(params)}
    for p in params:
        v = args[p.name]
        if not p.pointer:
            kind = SCALARS[p.ctype]
            assert isinstance(v, int if kind == "i" else float), f"{name} {p.name}: {type(v).__name__}"
            out.append(struct.pack("<iq" if kind == "i" else "<id", ord(kind), v))
        elif v is None:
            out.append(struct.pack("<i", ord("n")))
        elif isinstance(v, View):
            assert position[v.of] < position[p.name], f"{name} {p.name}: a view of a later argument"
            out.append(struct.pack("<iiq", ord("v"), position[v.of], v.offset))
        else:
            assert isinstance(v, np.ndarray) and v.dtype == DTYPES[p.ctype], f"{name} {p.name}: {p.ctype} array"
            data = np.ascontiguousarray(v).tobytes()
            out.append(struct.pack("<iq", ord("a"), len(data)) + data)
    return b"".join(out)


def decode(blob: bytes, calls) -> list[tuple[bytes, dict[str, bytes]]]:
    """The driver's output: per call, (the 8 return bytes, {array parameter: its bytes after the call})."""
    results, at = [], 0
    for _, params, args in calls:
        ret, at = blob[at:at + 8], at + 8
        arrays = {}
        for p in params:
            if p.pointer and isinstance(args[p.name], np.ndarray):
                (n,) = struct.unpack_from("<q", blob, at)
                arrays[p.name], at = blob[at + 8:at + 8 + n], at + 8 + n
        results.append((ret, arrays))
    assert at == len(blob), "the driver wrote more than the calls"
    return results


def _signed_zeros(rng, v, share=0.5):
    """v with its zeros given random signs (numpy writes 0.0)."""
    v = v.copy()
    zero = v == 0
    v[zero] = np.where(rng.random(int(zero.sum())) < share, -0.0, 0.0)
    return v


def _nans(rng, v, every):
    """v with every `every`-th value NaN, of several bit patterns (sign, payload)."""
    v = v.copy()
    bits = np.array([0x7FF8000000000000, 0xFFF8000000000000, 0x7FF8000000000123, 0xFFF0000000000001 | 1 << 51],
                    np.uint64).view(np.float64)
    v[::every] = bits[rng.integers(0, len(bits), len(v[::every]))]
    return v


class Data:
    """A sample tile's points (LAS integers and coordinates) and grids made of them, shared by the cases."""

    def __init__(self):
        las = laspy.read(SAMPLE / "35712.las")
        self.rng = np.random.default_rng(2024)
        self.X, self.Y, self.Z = (np.asarray(las.points.array[f]) for f in "XYZ")
        self.scales, self.offsets = np.asarray(las.header.scales), np.asarray(las.header.offsets)
        self.x, self.y, self.z = (np.asarray(a, np.float64) for a in (las.x, las.y, las.z))
        self.cls = np.asarray(las.classification, np.uint8)
        self.rn = np.asarray(las.return_number, np.uint8)
        self.n = len(self.x)
        # a 5 ft grid a little inside the tile's points (some fall outside)
        self.cell = 5.0
        self.col0 = int(np.floor(self.x.min() / self.cell)) + 2
        self.row_top = int(np.ceil(self.y.max() / self.cell)) - 2
        self.width = int(np.ceil(self.x.max() / self.cell)) - self.col0 - 2
        self.height = self.row_top - int(np.floor(self.y.min() / self.cell)) - 2
        col = np.floor(self.x / self.cell) - self.col0
        row = (self.row_top - 1) - np.floor(self.y / self.cell)
        inside = (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)
        self.flat = np.where(inside, row * self.width + col, -1).astype(np.int64)
        self.ncells = self.width * self.height
        # the lowest ground point per cell: NaN where none (gaps), finite where filled
        ground = (self.cls == 2) & inside
        zmin = np.full(self.ncells, np.inf)
        np.minimum.at(zmin, self.flat[ground], self.z[ground])
        zmin[np.isinf(zmin)] = np.nan
        self.gaps = zmin.reshape(self.height, self.width)
        self.gaps[60:75, 40:70] = np.nan  # a hole wider than a few rings
        filled = self.gaps.copy()
        filled[np.isnan(filled)] = np.nanmean(filled)
        self.surface = filled
        g = np.flatnonzero(self.cls == 2)
        self.ground = g[self.rng.permutation(len(g))[:12_000]]  # ground points in random order

    def triangles(self, x, y):
        """scipy's Delaunay triangles (int32) of points: a TIN as the callers have one."""
        from scipy.spatial import Delaunay

        return np.ascontiguousarray(Delaunay(np.column_stack([x, y])).simplices, np.int32)


def _pattern(n, dtype):
    """Scratch or output arrays with deterministic contents (what the call leaves in them is compared too)."""
    return np.frombuffer(np.arange(n * np.dtype(dtype).itemsize, dtype=np.uint8).tobytes(), dtype)


@case("gt_quantise")
def _(d):
    yield dict(n=d.n, v=d.x, v0=float(d.x.min()), scale=100.0, out=_pattern(d.n, np.int64))  # the LAS lattice
    scale = 2.0 ** -(int(np.ceil(np.log2(float(np.ptp(d.y))))) - 30)
    yield dict(n=d.n, v=d.y, v0=0.0, scale=scale, out=_pattern(d.n, np.int64))  # the power-of-two quantum
    halves = np.array([-2.5, -1.5, -0.5, -0.0, 0.0, 0.5, 1.5, 2.5, 3.5, 1e15 + 0.5, -(2.0 ** 52) - 0.5])
    v = np.concatenate([halves, d.rng.normal(0, 1e6, 5000).round(1)])
    yield dict(n=len(v), v=v, v0=0.0, scale=1.0, out=_pattern(len(v), np.int64))  # ties to even


def _delaunay_inputs(d):
    gx, gy = np.meshgrid(np.arange(60), np.arange(60))
    angles = d.rng.uniform(0, 2 * np.pi, 400)
    ix = np.rint((d.x - d.x.min()) * 100).astype(np.int64)
    iy = np.rint((d.y - d.y.min()) * 100).astype(np.int64)
    rep = d.rng.integers(0, d.n, 300)
    yield np.r_[ix, ix[rep]], np.r_[iy, iy[rep]]  # a tile on its 0.01 ft lattice, with repeats
    yield np.r_[gx.ravel(), gx.ravel()[:50]] * 7, np.r_[gy.ravel(), gy.ravel()[:50]] * 7  # cocircular, repeated
    yield (np.rint(2**29 + 2**28 * np.cos(angles)).astype(np.int64),
           np.rint(2**29 + 2**28 * np.sin(angles)).astype(np.int64))  # a ring
    yield d.rng.integers(0, 2**30, 5000), d.rng.integers(0, 2**30, 5000)
    yield np.arange(10, dtype=np.int64) * 3, np.arange(10, dtype=np.int64) * 5  # collinear: no triangle


@case("gt_delaunay")
def _(d):
    for x, y in _delaunay_inputs(d):
        x, y = np.ascontiguousarray(x, np.int64), np.ascontiguousarray(y, np.int64)
        yield dict(n=len(x), xin=x, yin=y, triangles=_pattern(6 * len(x), np.int32), repeats=np.zeros(1, np.int64))


def _grid_uv(d, x, y):
    return x / d.cell - d.col0, d.row_top - y / d.cell


@case("gt_rasterize")
def _(d):
    g = d.ground
    u, v = _grid_uv(d, d.x[g], d.y[g])
    tri = d.triangles(u, v)
    box = np.array([20.0, 15.0, d.width - 25.0, d.height - 10.0])
    for max_edge2, with_box in ((-1.0, True), (9.0, True), (4.0, False)):
        yield dict(ntri=len(tri), tri=tri, u=u, v=v, z=d.z[g], width=d.width, height=d.height, max_edge2=max_edge2,
                   out=np.full(d.ncells, np.nan), box=box if with_box else None,
                   exact=np.zeros(d.ncells, np.uint8) if with_box else None)


@case("gt_tin_grid")
def _(d):
    g = np.r_[d.ground, d.ground[:500]]  # repeats: their z joins the mean of the copy in the TIN
    z = d.z[g] + np.r_[np.zeros(len(d.ground)), d.rng.normal(0, 0.3, 500)]
    ix = np.rint((d.x[g] - d.x.min()) * 100).astype(np.int64)
    iy = np.rint((d.y[g] - d.y.min()) * 100).astype(np.int64)
    u, v = _grid_uv(d, d.x[g], d.y[g])
    box = np.array([30.0, 20.0, d.width - 30.0, d.height - 20.0])
    for max_edge2, with_box in ((-1.0, True), (16.0, False)):
        yield dict(n=len(g), ix=ix, iy=iy, u=u, v=v, z=z, width=d.width, height=d.height, max_edge2=max_edge2,
                   out=np.full(d.ncells, np.nan), repeats=np.zeros(1, np.int64), box=box if with_box else None,
                   exact=np.zeros(d.ncells, np.uint8) if with_box else None)


@case("gt_tin_at")
def _(d):
    g = d.ground
    x0, y0 = float(d.x[g].min()), float(d.y[g].min())
    vx, vy, vz = d.x[g] - x0, d.y[g] - y0, d.z[g]
    tri = d.triangles(vx, vy)
    k = d.rng.integers(0, len(tri), 3000)
    a, b = tri[k, 0], tri[k, 1]
    qx = np.concatenate([d.rng.uniform(-20, vx.max() + 20, 20_000), vx[:500], (vx[a] + vx[b]) / 2, [np.nan, 1.0]])
    qy = np.concatenate([d.rng.uniform(-20, vy.max() + 20, 20_000), vy[:500], (vy[a] + vy[b]) / 2, [5.0, np.nan]])
    yield dict(ntri=len(tri), tri=tri, vx=vx, vy=vy, vz=vz, nv=len(vx), nq=len(qx), qx=qx, qy=qy,
               out=_pattern(len(qx), np.float64))  # in, outside, on vertices and on edges (two triangles), NaN


@case("gt_plane_residuals")
def _(d):
    g = d.ground
    x, y = d.x[g] - d.x[g].min(), d.y[g] - d.y[g].min()
    tri = d.triangles(x, y)
    yield dict(n=len(g), x=x, y=y, z=d.z[g], ntri=len(tri), tri=tri, sums=_pattern(9 * len(g), np.float64),
               out=_pattern(len(g), np.float64))


@case("gt_cross_filter")
def _(d):
    s = d.surface
    for grid in (s, s[:, :1].copy(), s[:1].copy()):
        rows, cols = grid.shape
        for is_max, iterations in ((0, 0), (1, 1), (0, 4), (1, 7)):
            yield dict(in_=grid.ravel(), out=_pattern(grid.size, np.float64), work=_pattern(grid.size, np.float64),
                       rows=rows, cols=cols, is_max=is_max, iterations=iterations)


@case("gt_fill_rings")
def _(d):
    z = d.gaps - np.nanmedian(d.gaps)
    flat = z.ravel()
    flat[::97] = np.where(np.isnan(flat[::97]), np.nan, -0.0)  # negative zeros among the values
    for rings in (3, 1000):
        yield dict(z=z.ravel(), prev=_pattern(z.size, np.float64), rows=z.shape[0], cols=z.shape[1], rings=rings)


@case("gt_progressive")
def _(d):
    s = d.surface
    for max_radius in (3, 9):  # 9: the 45-degree squares from radius 6
        yield dict(z=s.ravel(), obj=np.zeros(s.size, np.uint8), work=_pattern(4 * s.size, np.float64), rows=s.shape[0],
                   cols=s.shape[1], cell=d.cell, slope_z=0.15, max_radius=max_radius)


@case("gt_fill_front")
def _(d):
    z = d.gaps
    cap = int(np.isnan(z).sum())
    for rings in (0, 2, 1000):
        yield dict(z=z.ravel(), rows=z.shape[0], cols=z.shape[1], rings=rings, cap=cap,
                   work=_pattern(2 * cap, np.int64), mark=_pattern(z.size, np.uint8), vals=_pattern(cap, np.float64))


@case("gt_bilinear")
def _(d):
    s = d.surface
    for surf in (s, s[:1].copy(), s[:, :1].copy()):
        yield dict(surf=surf.ravel(), rows=surf.shape[0], cols=surf.shape[1], n=d.n, x=d.x, y=d.y, cell=d.cell,
                   col0=d.col0, row_top=d.row_top, out=_pattern(d.n, np.float64))  # points beyond the grid clamp


@case("gt_slope_threshold")
def _(d):
    s = d.surface
    for grid in (s, s[:1].copy(), s[:, :1].copy()):
        yield dict(z=grid.ravel(), rows=grid.shape[0], cols=grid.shape[1], cell=d.cell, z_per_xy=1.0, threshold=0.5,
                   scalar=1.25, out=_pattern(grid.size, np.float64))


@case("gt_raised_patches")
def _(d):
    z = d.gaps.copy()
    z[100:108, 100:110] += 12.0  # a roof: ground points on a building
    z[99, 98:112] = z[108, 98:112] = np.nan  # walls without points around it
    z[50:53, 150:152] = np.inf  # not finite: empty
    for step in (0.5, 2.0):
        yield dict(z=z.ravel(), rows=z.shape[0], cols=z.shape[1], reach=2, step=step, cell=d.cell, patch=60.0,
                   floor_cells=100, work=_pattern(8 * z.size, np.int64), roof=_pattern(z.size, np.uint8))


@case("gt_cell_index")
def _(d):
    edges = np.arange(d.col0, d.col0 + d.width + 1) * d.cell  # on cell edges: floor decides
    x = np.concatenate([d.x, edges, [np.nan, np.inf, -np.inf, -0.0, 0.0]])
    y = np.concatenate([d.y, np.full(len(edges), (d.row_top - 3) * d.cell), [d.y[0], d.y[0], d.y[0], -0.0, np.nan]])
    yield dict(n=len(x), x=x, y=y, cell=d.cell, col0=d.col0, row_top=d.row_top, width=d.width, height=d.height,
               out=_pattern(len(x), np.int64))


@case("gt_cell_min")
def _(d):
    on = d.flat >= 0
    z = _nans(d.rng, _signed_zeros(d.rng, (d.z[on] - 300).round(0)), 53)  # ties, signed zeros, NaNs (never less)
    out = np.full(d.ncells, np.inf)
    out[::7] = 0.0
    yield dict(n=len(z), flat=d.flat[on], z=z, out=out)


@case("gt_cell_mean")
def _(d):
    on = d.flat >= 0
    z = _signed_zeros(d.rng, (d.z[on] - 300).round(1))
    yield dict(n=len(z), flat=d.flat[on], z=z, on=(d.cls[on] == 2).astype(np.uint8), ncells=d.ncells,
               sum=_pattern(d.ncells, np.float64), count=_pattern(d.ncells, np.int64), out=_pattern(d.ncells, np.float64))


def _cell_sort_inputs(d):
    """(cell, values, ncells): a few points a cell (insertion sorts) and thousands (merge sorts), ties, signed
    zeros, NaNs of several bit patterns."""
    on = d.flat >= 0
    v = _nans(d.rng, _signed_zeros(d.rng, (d.z[on] - 300).round(0)), 31)
    yield d.flat[on], v, d.ncells
    coarse = (d.flat[on] // d.width // 10) * 10 + (d.flat[on] % d.width) // 10  # 50 ft cells
    yield coarse, v, int(coarse.max()) + 1
    n = 50_000
    yield d.rng.integers(0, 7, n), _nans(d.rng, _signed_zeros(d.rng, d.rng.normal(size=n).round(1)), 31), 7
    yield np.zeros(0, np.int64), np.zeros(0), 4


@case("gt_cell_sort")
def _(d):
    for cell, v, ncells in _cell_sort_inputs(d):
        yield dict(n=len(v), cell=np.ascontiguousarray(cell, np.int64), v=v, ncells=ncells,
                   start=_pattern(ncells + 1, np.int64), pos=_pattern(ncells, np.int64), out=_pattern(len(v), np.float64))


def _cell_runs(d):
    """(ncells, start, values): values grouped by cell and sorted in each, as gt_cell_sort leaves them."""
    from gistools.lidar.metrics import cell_sorted

    for cell, v, ncells in _cell_sort_inputs(d):
        out, start = cell_sorted(cell, v, ncells)
        yield ncells, start, out


@case("gt_cell_moments")
def _(d):
    for ncells, start, v in _cell_runs(d):
        longest = int(np.diff(start).max(initial=1))
        yield dict(ncells=ncells, start=start, v=v, sum=_pattern(ncells, np.float64), ssd=_pattern(ncells, np.float64),
                   sq=_pattern(max(longest, 1), np.float64))


@case("gt_cell_percentile")
def _(d):
    for ncells, start, v in _cell_runs(d):
        for p in (0.0, 37.5, 95.0, 100.0):
            yield dict(ncells=ncells, start=start, v=v, p=p, out=_pattern(ncells, np.float64))


def _bare():
    from gistools.lidar.accumulate import is_groundish

    return is_groundish.view(np.uint8).copy()


@case("gt_max_with_class")
def _(d):
    on = d.flat >= 0
    z = (d.z[on] - 300).round(0)  # ties between classes
    dsm = np.full(d.ncells, -np.inf)
    dsm[::5] = 10.0  # earlier calls' maxima: some tie
    for cls in (d.cls[on], d.rng.choice(np.array([1, 2, 5, 9], np.uint8), int(on.sum()))):
        yield dict(n=len(z), cell=d.flat[on], z=z, cls=cls, bare=_bare(), ncells=d.ncells, dsm=dsm,
                   top=np.full(d.ncells, 255, np.uint8), cm=_pattern(d.ncells, np.float64),
                   tc=_pattern(d.ncells, np.uint8))


@case("gt_scan_chunk")
def _(d):
    from gistools.lidar.accumulate import surface_classes

    n, size = d.n, 34  # 34-byte records (LAS format 3): X, Y, Z unaligned in every other record
    records = np.zeros((n, size), np.uint8)
    for k, a in enumerate((d.X, d.Y, d.Z)):
        records[:, 4 * k:4 * k + 4] = np.ascontiguousarray(a, np.int32).view(np.uint8).reshape(n, 4)
    cls = d.cls.copy()
    cls[::211] = 9  # some water
    cls[::307] = 7  # some noise (not in the DSM)
    rn = d.rn.copy()
    rn[::101] = 0  # not recorded: taken as first
    withheld = (d.rng.random(n) < 0.01).astype(np.uint8)
    so = np.r_[d.scales, d.offsets].astype(np.float64)
    gp = np.array([d.cell, d.col0, d.row_top, d.width, d.height], np.float64)
    b = 40.0
    edges = np.array([d.x.min() + b, d.x.max() - b, d.y.min() + b, d.y.max() - b])
    nc = d.ncells
    for top, first, ground, index in ((True, True, True, True), (False, True, True, False), (True, False, False, False)):
        yield dict(
            n=n, X=records.ravel(), xstride=size, Y=View("X", 4), ystride=size, Z=View("X", 8), zstride=size,
            so=so, gp=gp, cell=_pattern(n, np.int64), cls=cls, rn=rn, withheld=withheld,
            surface=surface_classes(None).view(np.uint8).copy(), bare=_bare(), ncells=nc, dsm=np.full(nc, -np.inf),
            top=np.full(nc, 255, np.uint8) if top else None, cm=_pattern(nc, np.float64) if top else None,
            tc=_pattern(nc, np.uint8) if top else None, by_class=np.zeros(256, np.int64),
            by_return=np.zeros(16, np.int64), bare_first=np.zeros(nc, np.int64) if first else None,
            first_cell=_pattern(n if first else 0, np.int32), first_z=_pattern(n if first else 0, np.float32),
            gclass=2, wclass=9, gcount=np.zeros(nc, np.int64) if ground else None,
            wcount=np.zeros(nc, np.int64) if ground else None, edges=edges, grec=_pattern(3 * n, np.int32),
            gidx=_pattern(n, np.int64) if index else None, hrec=_pattern(3 * n, np.int32), hside=_pattern(n, np.uint8),
            boxes=np.array([[np.inf, np.inf, -np.inf, -np.inf]] * 5).ravel(), counts=_pattern(4, np.int64))


def _calls(data):
    """[(entry point, its parameters, the arguments)] for every case; `in` is a Python word: in_ stands for it."""
    points = entry_points()
    calls = []
    for name, make in CASES.items():
        params = points[name][1]
        for args in make(data):
            args = {("in" if k == "in_" else k): v for k, v in args.items()}
            calls.append((name, params, args))
    return calls


# ------------------------------------------------------------------------------------------------ the builds

def _missing(what: str, install: str):
    if os.environ.get("CI"):
        pytest.fail(f"CI must run the kernel under Wine: {what} is missing (tools/run.sh test installs {install})")
    pytest.skip(f"{what} is missing here: the Windows build cannot be run (apt-get install {install})")


def _wine() -> str | None:
    """Debian's wine64 loader: on the PATH, or where Debian 12's wine64 package puts it (without the wine package)."""
    debian = "/usr/lib/wine/wine64"
    return shutil.which("wine64") or (debian if os.access(debian, os.X_OK) else None)


def _native_flags() -> tuple[list[str], list[str]]:
    """csrc/kernel_build.py's flags (the build Python loads) and sources."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_gistools_kernel_build", CSRC / "kernel_build.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.FLAGS, [str(CSRC / s) for s in module.SOURCES]


@pytest.fixture(scope="module")
def calls():
    return _calls(Data())


@pytest.fixture(scope="module")
def replayed(calls):
    """Both builds of the driver run on the same calls: {"native": outputs, "wine": outputs, "seconds": ...}."""
    wine, mingw, gcc = _wine(), shutil.which(MINGW), shutil.which("gcc")
    if wine is None:
        _missing("wine64", "wine64")
    if mingw is None:
        _missing(MINGW, "gcc-mingw-w64-x86-64")
    if gcc is None:
        _missing("gcc", "gcc")
    t0 = time.perf_counter()
    # the builds, the calls and their outputs (~0.2 GB), and Wine's prefix (~0.7 GB once set up): removed below
    work = Path(tempfile.mkdtemp(prefix="gistools-windows-"))
    prefix = work / "wine"
    prefix.mkdir()
    (work / "thunks.h").write_text(thunks(entry_points()))
    (work / "calls.bin").write_bytes(b"".join(encode(name, params, args) for name, params, args in calls))
    env = {**os.environ, "WINEPREFIX": str(prefix), "WINEDEBUG": "-all", "WINEDLLOVERRIDES": "mscoree,mshtml="}
    env.pop("DISPLAY", None)
    beside = Path(wine).parent / "wineserver"  # the server of this Wine
    server = str(beside) if os.access(beside, os.X_OK) else shutil.which("wineserver")
    boot = None
    try:
        # Wine sets its prefix up (a few seconds, once) while the two builds compile
        boot = subprocess.Popen([wine, "wineboot", "--init"], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        flags, sources = _native_flags()
        common = ["-std=c99", "-Wall", f"-I{CSRC}", f"-I{work}", str(DRIVER), *sources, "-lm"]
        builds = {
            "native": subprocess.Popen([gcc, *flags, *common, "-o", str(work / "driver")], stdout=subprocess.PIPE,
                                       stderr=subprocess.STDOUT, text=True),
            "wine": subprocess.Popen([mingw, "-O2", "-ffp-contract=off", "-DGISTOOLS_PORTABLE_INT128", "-static",
                                      *common, "-o", str(work / "driver.exe")], stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True),
        }
        for name, build in builds.items():
            log = build.communicate()[0]
            assert build.returncode == 0, f"the {name} build of the driver failed:\n{log}"
        run = {"native": [str(work / "driver")], "wine": [wine, "driver.exe"]}
        out = {}
        t1 = time.perf_counter()
        native = subprocess.run([*run["native"], "calls.bin", "native.out"], cwd=work, capture_output=True, text=True)
        assert native.returncode == 0, f"the native driver failed: {native.stderr}"
        out["native seconds"] = time.perf_counter() - t1
        boot_log = boot.communicate(timeout=120)[0]
        assert boot.returncode == 0, f"Wine could not set up its prefix: {boot_log!r}"
        t1 = time.perf_counter()
        # relative paths: Wine maps the working directory to a drive, and the .exe opens them as they are
        ran = subprocess.run([*run["wine"], "calls.bin", "wine.out"], cwd=work, env=env, capture_output=True, timeout=300)
        assert ran.returncode == 0, f"the MinGW build failed under Wine ({ran.returncode}): {ran.stderr!r}"
        out["wine seconds"] = time.perf_counter() - t1
        for name in ("native", "wine"):
            out[name] = (work / f"{name}.out").read_bytes()
    finally:
        if server:
            subprocess.run([server, "-k"], env=env, capture_output=True)  # this prefix's server and programs only
        if boot is not None and boot.poll() is None:
            boot.kill()
            boot.wait()
        shutil.rmtree(work, ignore_errors=True)
    out["seconds"] = time.perf_counter() - t0
    print(f"\nWindows ABI run: {len(calls)} calls, {len(out['native']) / 1e6:.1f} MB of outputs; native "
          f"{out['native seconds']:.2f} s, Wine {out['wine seconds']:.2f} s, {out['seconds']:.1f} s in all")
    return out


# ------------------------------------------------------------------------------------------------ the tests

def test_every_entry_point_of_the_header_has_a_case():
    """A new entry point needs its calls here: the Wine run checks only what it calls."""
    points = entry_points()
    assert len(points) >= 19
    assert not set(points) - set(CASES), f"entry points without a case in CASES: {sorted(set(points) - set(CASES))}"
    assert not set(CASES) - set(points), f"cases of no entry point: {sorted(set(CASES) - set(points))}"
    assert {ret for ret, _ in points.values()} <= RETURNS
    for ret, params in points.values():
        assert all(p.ctype in (DTYPES if p.pointer else SCALARS) for p in params)


def test_the_kernel_writes_restrict_as_every_compiler_takes_it():
    """MSVC's C compiler knows C99's restrict as __restrict: the sources write GT_RESTRICT (common.h), never the
    keyword itself."""
    for path in sorted(CSRC.glob("*.[ch]")):
        code = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S).replace("#define GT_RESTRICT restrict", "")
        assert not re.search(r"\brestrict\b", code), f"{path.name}: write GT_RESTRICT"


def test_the_mingw_kernel_under_wine_equals_the_native_kernel_bit_for_bit(calls, replayed):
    """Every call's return value and every array it left (outputs, scratch and inputs) are byte-identical."""
    assert replayed["wine"] == replayed["native"], _first_difference(calls, replayed)
    assert {name for name, _, _ in calls} == set(entry_points())


def _first_difference(calls, replayed) -> str:
    native, wine = (decode(replayed[k], calls) for k in ("native", "wine"))
    differ = []
    for (name, params, _), (nret, narr), (wret, warr) in zip(calls, native, wine):
        if nret != wret:
            differ.append(f"{name}: the return value")
        for p, data in narr.items():
            if data != warr[p]:
                a = np.frombuffer(data, DTYPES[next(q.ctype for q in params if q.name == p)])
                b = np.frombuffer(warr[p], a.dtype)
                k = np.flatnonzero(a.view(f"u{a.itemsize}") != b.view(f"u{b.itemsize}"))
                bits = f"u{a.itemsize}"
                differ.append(f"{name} {p}: {len(k)} of {len(a)} elements differ, first at {k[0]}: native "
                              f"{a[k[0]]!r} ({a.view(bits)[k[0]]:#x}), Wine {b[k[0]]!r} ({b.view(bits)[k[0]]:#x})")
    return "the Wine run differs: " + "; ".join(differ)


def test_the_driver_gives_what_python_s_kernel_gives(calls, replayed):
    """The harness itself: the native driver's outputs are those of the kernel Python loads (gistools._kernel), so
    the calls compared are the calls the package makes."""
    from gistools import kernel

    need_kernel()
    for (name, params, args), (ret, arrays) in zip(calls, decode(replayed["native"], calls)):
        copies = {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in args.items()}
        values = [copies[p.name] for p in params]
        for k, p in enumerate(params):  # views: the address inside the copied array
            if isinstance(values[k], View):
                values[k] = copies[values[k].of].ctypes.data + values[k].offset
        got = kernel.function(name)(*values)
        returns = entry_points()[name][0]
        if returns == "void":
            assert got is None, name
        else:
            assert struct.pack("<q" if returns == "int64_t" else "<d", got) == ret, f"{name}: the return value"
        for p, data in arrays.items():
            assert copies[p].tobytes() == data, f"{name} {p}"


def test_cell_sort_is_numpys_stable_order_bit_for_bit(calls, replayed, monkeypatch):
    """gt_cell_sort is v[numpy.lexsort((v, cell))] to the bit: equal values (-0.0 and 0.0, NaNs of any bits) in
    point order, on every C library (its own merge sort, not qsort); metrics' numpy form gives the same."""
    from gistools.lidar import metrics

    monkeypatch.setattr(metrics, "_CELL_SORT", None)
    for (name, _, args), (_, arrays) in zip(calls, decode(replayed["native"], calls)):
        if name != "gt_cell_sort":
            continue
        cell, v = args["cell"], args["v"]
        want = v[np.lexsort((v, cell))].view(np.uint64)
        assert np.array_equal(np.frombuffer(arrays["out"], np.uint64), want)
        assert np.array_equal(metrics.cell_sorted(cell, v, args["ncells"])[0].view(np.uint64), want)


# Microsoft's C dialect: a real front end in MSVC compatibility mode (clang's cl driver: _MSC_VER defined, neither
# __clang__ nor __GNUC__, no __int128), against the runtime's declarations as Microsoft spells them
# (tests/windows/msvc_crt: only the functions the kernel calls). Warnings are errors, variable length arrays
# (which MSVC lacks) and GNU extensions included.
MSVC_MODE = ["--driver-mode=cl", "--target=x86_64-pc-windows-msvc", "/Zs", "/W4", "/WX", "/std:c11", "-U__clang__",
             "-U__SIZEOF_INT128__", "-D__int128=__int128_is_not_in_msvc", "-Wvla", "-Wpedantic"]


def _msvc_mode(source: Path, include: Path = ROOT / "csrc"):
    clang = shutil.which("clang")
    if clang is None:
        if os.environ.get("CI"):
            pytest.fail("CI must compile the kernel in MSVC's dialect: clang is missing (tools/run.sh test installs it)")
        pytest.skip("clang is missing here (apt-get install clang)")
    return subprocess.run([clang, *MSVC_MODE, "-imsvc", str(ROOT / "tests" / "windows" / "msvc_crt"), f"-I{include}",
                           "--", str(source)], capture_output=True, text=True, timeout=300)  # --: a path, not a /flag


@pytest.mark.parametrize("part", ["grid", "morphology", "scan", "tin"])
def test_the_kernel_compiles_in_microsofts_c_dialect(part):
    run = _msvc_mode(ROOT / "csrc" / f"{part}.c")
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.parametrize("code,error", [
    ("int f(int n) { int a[n]; a[0] = 1; return a[0]; }", "variable length array"),
    ("int g(long long a) { __int128 x = a; return (int)(x >> 1); }", "__int128_is_not_in_msvc"),
    ("int h(int a) { return ({ int b = a; b; }); }", "statement expression"),
    ("#ifndef _MSC_VER\n#error not MSVC\n#endif\n#if defined(__GNUC__) || defined(__clang__)\n#error GNU\n#endif\n"
     "int k(void) { return 0; }", None),
])
def test_the_msvc_mode_refuses_what_microsofts_compiler_refuses(tmp_path, code, error):
    """The check has teeth: what MSVC's C compiler lacks fails it, and it sees the compiler as MSVC, not as GCC."""
    source = tmp_path / "probe.c"
    source.write_text(code + "\n", encoding="utf-8")
    run = _msvc_mode(source)
    if error is None:
        assert run.returncode == 0, run.stdout + run.stderr
    else:
        assert run.returncode != 0 and error in run.stdout + run.stderr, run.stdout + run.stderr
