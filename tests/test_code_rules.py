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
