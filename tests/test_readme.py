"""The README's Python example runs as printed, as a script, in a folder holding a copy of sample_tiles/."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

from conftest import ROOT, SAMPLE


def test_the_readme_python_example_runs_as_a_script(tmp_path):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python\n"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    shutil.copytree(SAMPLE, tmp_path / "sample_tiles")
    (tmp_path / "example.py").write_text(code)
    proc = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "{'ok': 4, 'failed': 0, 'skipped': 0}" in proc.stdout
    assert "Traceback" not in proc.stderr and "forked" not in proc.stderr  # the guard lets the workers spawn
