"""The plugin is ready for QGIS 4 (Qt 6, PyQt6): QGIS's own migration checker finds nothing to change, and the rules
it enforces hold, checked here independently against the running QGIS's classes.

The checker is QGIS's scripts/pyqt5_to_pyqt6 (by Julien Cabieces), as its authors publish it on PyPI
(``qgis-pyqt5to6``, command ``pyqt5to6``): it reads Qt 6's enums from PyQt6 and rewrites every Qt 5 form it finds
(``PyQt5`` imports, unscoped enums, ``exec_``) in place, exiting 1 when it changed a file. It is installed with PyQt6
into a virtual environment of its own (PyQt6 must not meet QGIS's PyQt5 in one process), cached between runs.
"""

from __future__ import annotations

import ast
import importlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

PLUGIN = ROOT / "qgis_plugin"
CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "gistools-tests" / "pyqt5to6"
CHECKER = ("qgis-pyqt5to6==0.0.0.dev0", "PyQt6>=6.5", "PyQt6-QScintilla>=2.14", "tokenize-rt", "astpretty")


def _need(what: str, reason: str):
    if os.environ.get("CI") and os.environ.get("GISTOOLS_ROUTE") != "wheels":  # the pip route has no QGIS bindings
        pytest.fail(f"CI must run the QGIS 4 readiness check: {reason}")
    pytest.skip(f"{what}: {reason}")


@pytest.fixture(scope="module")
def pyqt5to6() -> Path:
    """The ``pyqt5to6`` command in its own environment (made once, from PyPI)."""
    exe = CACHE / "bin" / "pyqt5to6"
    if exe.exists():
        return exe
    shutil.rmtree(CACHE, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "venv", str(CACHE)], check=True, capture_output=True, timeout=300)
    # the package says Python >= 3.12 but runs on 3.11 (no newer syntax): --ignore-requires-python
    run = subprocess.run([str(CACHE / "bin" / "python"), "-m", "pip", "install", "-q", "--ignore-requires-python",
                          *CHECKER], capture_output=True, text=True, timeout=1200)
    if run.returncode != 0:
        shutil.rmtree(CACHE, ignore_errors=True)
        _need("pyqt5to6", f"pip could not install it ({run.stderr.strip().splitlines()[-1:]})")
    return exe


def _check(exe: Path, folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(exe), str(folder)], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})


def test_qgis_migration_checker_changes_nothing_in_the_plugin(pyqt5to6, tmp_path):
    live = tmp_path / "qt5_code"  # first, that it is live: Qt 5 forms are rewritten and the exit status says so
    live.mkdir()
    (live / "old.py").write_text("from PyQt5.QtCore import Qt\nfrom qgis.PyQt.QtWidgets import QMessageBox\n"
                                 "a = Qt.AlignLeft\nb = QMessageBox.Ok\n\n\ndef run(d):\n    return d.exec_()\n")
    run = _check(pyqt5to6, live)
    assert run.returncode == 1, run.stdout + run.stderr
    assert (live / "old.py").read_text() == ("from qgis.PyQt.QtCore import Qt\nfrom qgis.PyQt.QtWidgets import QMessageBox\n"
                                            "a = Qt.AlignmentFlag.AlignLeft\nb = QMessageBox.StandardButton.Ok\n\n\n"
                                            "def run(d):\n    return d.exec()\n")
    copy = tmp_path / "qgis_plugin"
    shutil.copytree(PLUGIN, copy, ignore=shutil.ignore_patterns("__pycache__", "help"))
    run = _check(pyqt5to6, copy)
    changed = [p.name for p in copy.rglob("*.py") if p.read_text() != (PLUGIN / p.relative_to(copy)).read_text()]
    assert run.returncode == 0 and not changed, (changed, run.stdout, run.stderr)
    assert "WARNING" not in run.stderr and "ERROR" not in run.stderr, run.stderr


# ------------------------------------------------------------------ the same rules, checked independently

ENUM_METATYPES = {"enumtype", "EnumType", "EnumMeta"}  # sip's (PyQt5) and Python's enum classes


def qt6_problems(folder: Path) -> list[str]:
    """Where the code under ``folder`` would fail on Qt 6 / QGIS 4: Qt imported other than through qgis.PyQt,
    an enum member reached without its enum's name (``Qt.AlignLeft``, ``QgsProcessing.TypeVectorPoint``), or
    ``exec_``. Enums are recognised by asking the running QGIS's classes."""
    problems = []
    for path in sorted(folder.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        names = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                if node.module.split(".")[0] in ("PyQt5", "PyQt6", "sip"):
                    problems.append(f"{path.name}:{node.lineno}: import from {node.module} (use qgis.PyQt)")
                if node.module.startswith("qgis"):
                    names.update({a.asname or a.name: (node.module, a.name) for a in node.names})
            elif isinstance(node, ast.Import):
                problems += [f"{path.name}:{node.lineno}: import {a.name} (use qgis.PyQt)" for a in node.names
                             if a.name.split(".")[0] in ("PyQt5", "PyQt6", "sip")]
        for node in ast.walk(tree):
            if not isinstance(node, ast.Attribute):
                continue
            if node.attr == "exec_":
                problems.append(f"{path.name}:{node.lineno}: exec_ (use exec)")
            if isinstance(node.value, ast.Name) and node.value.id in names:
                module, name = names[node.value.id]
                try:
                    owner = getattr(importlib.import_module(module), name)
                except (ImportError, AttributeError):
                    continue
                value = getattr(owner, node.attr, None)
                if value is not None and not isinstance(value, type) and type(type(value)).__name__ in ENUM_METATYPES:
                    problems.append(f"{path.name}:{node.lineno}: {node.value.id}.{node.attr} is not scoped "
                                    f"(write {type(value).__qualname__}.{node.attr}, or take it from compat.py)")
    return problems


def _qgis():
    try:
        import qgis.core  # noqa: F401
    except ImportError as err:
        _need("QGIS", f"qgis does not import ({err})")


def test_the_rules_checker_sees_each_kind_of_problem(tmp_path):
    _qgis()
    (tmp_path / "bad.py").write_text(
        "import sip\nfrom PyQt5.QtCore import QUrl\nfrom qgis.core import Qgis, QgsProcessing\n"
        "from qgis.PyQt.QtCore import Qt\n"
        "a = QgsProcessing.TypeVectorPoint\nb = Qt.AlignLeft\nc = Qgis.Critical\nd = Qt.AlignmentFlag.AlignLeft\n"
        "e = Qgis.MessageLevel.Critical\nf = QgsProcessing.TEMPORARY_OUTPUT\n\n\ndef run(d):\n    return d.exec_()\n")
    found = qt6_problems(tmp_path)
    assert sorted(int(p.split(":")[1]) for p in found) == [1, 2, 5, 6, 7, 14], found


def test_every_qt_import_goes_through_qgis_pyqt_and_every_enum_is_scoped():
    _qgis()
    assert qt6_problems(PLUGIN) == []
