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
DOMAIN = ("grid.py", "units.py", "mesh.py", "lidar", "aquifer", "runway", "structure", "vector", "terrain")
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


def _import_graph() -> dict:
    """{module: the gistools modules it imports}, every import statement counted (those inside functions too);
    ``from pkg import name`` is an import of ``pkg.name`` where that is a module, else of ``pkg``."""
    package = ROOT / "gistools"
    modules = {}
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    compiled = {".".join(p.relative_to(ROOT).parts[:-1] + (p.name.split(".")[0],))
                for p in [*package.rglob("*.so"), *package.rglob("*.pyd")]}  # extension modules: leaves
    graph = {}
    for name, path in modules.items():
        base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                where = ".".join(base[:len(base) - node.level + 1] + [node.module or ""]).strip(".") if node.level \
                    else node.module or ""
                edges.update(f"{where}.{a.name}" if f"{where}.{a.name}" in modules.keys() | compiled else where
                             for a in node.names)
            elif isinstance(node, ast.Import):
                edges.update(a.name for a in node.names)
        graph[name] = {e for e in edges if e in modules and e != name}
    return graph


def test_the_package_has_no_import_cycle():
    """No module imports, directly or through others, a module that imports it (a package's __init__ running
    before its modules is Python's order, not an edge here)."""
    from test_plugin_package import cycles

    found = cycles(_import_graph())
    assert not found, found


def test_the_version_is_written_in_one_place():
    """gistools/_version.py holds it; pyproject.toml reads it from there (dynamic), the plugin's zip is given it by
    tools/build_plugin.py, and the source metadata.txt (QGIS loading the plugin from a checkout) agrees."""
    from gistools import __version__

    pyproject = (ROOT / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in pyproject and 'attr = "gistools._version.__version__"' in pyproject
    assert not re.search(r'^version = "', pyproject, re.M)
    metadata = (ROOT / "qgis_plugin" / "metadata.txt").read_text()
    assert f"\nversion={__version__}\n" in metadata
