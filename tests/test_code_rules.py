"""Rules of the code base that a test can hold: no process-wide matplotlib backend switch in library or plugin code."""

from __future__ import annotations

import re

from conftest import ROOT


def test_no_matplotlib_backend_switch_in_library_or_plugin():
    """``matplotlib.use`` would switch the backend of the whole QGIS desktop process; figures use their own canvas."""
    found = []
    for folder in ("gistools", "qgis_plugin"):
        for path in (ROOT / folder).rglob("*.py"):
            for n, line in enumerate(path.read_text().splitlines(), 1):
                if re.search(r"\bmatplotlib\.use\(|import matplotlib\.pyplot|from matplotlib import pyplot", line):
                    found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not found, found


import ast  # noqa: E402

# the domain packages: pure functions over arrays, no I/O (readers and writers live in gistools.io)
DOMAIN = ("grid.py", "units.py", "mesh.py", "lidar", "aquifer", "runway", "structure", "vector")
IO_MODULES = {"laspy", "lazrs", "pyogrio", "fiona", "csv", "pickle", "sqlite3", "shutil", "tempfile", "io", "pathlib",
              "glob", "json", "tqdm"}
IO_PARTS = {"gistools.io", "rasterio.io", "rasterio.env"}  # rasterio.features / .transform are array functions
IO_CALLS = {"open", "read_text", "write_text", "read_bytes", "write_bytes", "load", "save", "savez", "savetxt",
            "loadtxt", "fromfile", "tofile", "read_csv", "to_csv", "read_file", "to_file", "read_parquet",
            "to_parquet", "mkdir", "unlink", "rmdir", "rename", "replace_file", "read_dataframe", "write_dataframe"}


def _domain_files():
    for entry in DOMAIN:
        path = ROOT / "gistools" / entry
        yield from ([path] if path.is_file() else sorted(path.rglob("*.py")))


def test_the_domain_packages_do_no_io():
    found = []
    for path in _domain_files():
        tree = ast.parse(path.read_text())
        package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: resolve against the package
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                names = [base] + [f"{base}.{a.name}" for a in node.names]
            for name in names:
                top = name.split(".")[0]
                if top in IO_MODULES or name == "rasterio" or any(name == p or name.startswith(p + ".") for p in IO_PARTS):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: imports {name}")
            if isinstance(node, ast.Call):
                fn = node.func
                called = fn.id if isinstance(fn, ast.Name) else fn.attr if isinstance(fn, ast.Attribute) else None
                if called in IO_CALLS:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: calls {called}()")
    assert not found, "\n".join(found)


def test_no_function_is_rated_d_or_worse_by_radon():
    """Cyclomatic complexity: every function of gistools/ and qgis_plugin/ at rank C or better (radon cc -n D)."""
    from radon.complexity import cc_rank, cc_visit

    found = []
    for folder in ("gistools", "qgis_plugin"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for block in cc_visit(path.read_text()):
                if cc_rank(block.complexity) >= "D":
                    found.append(f"{path.relative_to(ROOT)}:{block.lineno} {block.name} {cc_rank(block.complexity)} "
                                 f"({block.complexity})")
    assert not found, "\n".join(found)
