"""The documentation site builds with `mkdocs build --strict`: a broken link, a missing anchor or image, or a page
left out of mkdocs.yml's nav fails."""

from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import ROOT


def test_the_documentation_site_builds_strictly(tmp_path):
    pytest.importorskip("mkdocs", reason="mkdocs is in the test extra: pip install -e '.[test]'")
    pytest.importorskip("material", reason="mkdocs-material is in the test extra: pip install -e '.[test]'")
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-5000:]
    for page in ("index.html", "quickstart/index.html", "commands/shrub/index.html", "concepts/index.html"):
        assert (site / page).is_file(), page
    assert (site / "webmap.png").is_file()


def test_the_readme_links_point_to_files_of_the_checkout():
    import re

    text = (ROOT / "README.md").read_text()
    links = [t for t in re.findall(r"\]\(([^)\s]+)\)", text) if not t.startswith(("http://", "https://", "#"))]
    assert links, "the README links into docs/"
    missing = [t for t in links if not (ROOT / t.split("#")[0]).exists()]
    assert not missing, missing


# words of a project's own history, which users' documentation has no use for (a CHANGELOG says what changed)
HISTORY = [r"\bsessions?\b", r"\bissue #?\d{1,3}\b", r"\bthis round\b", r"\bthe commit before\b", r"\.\./shared",
           r"\bprevious (code|session|version of the code)\b", r"example\.org", r"\.ci/run"]


def test_no_page_speaks_of_the_projects_own_history():
    """README, CHANGELOG and every docs page: no development history, no placeholder URL, no path a user lacks."""
    import re

    pages = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]
    found = [f"{p.relative_to(ROOT)}: {m.group(0)!r}" for p in pages for pattern in HISTORY
             for m in re.finditer(pattern, p.read_text(), re.I)]
    assert not found, found
    assert (ROOT / "README.md").stat().st_size < 10_000
