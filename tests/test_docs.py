"""The documentation site builds with `mkdocs build --strict`: a broken link, a missing anchor or image, or a page
left out of mkdocs.yml's nav fails."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site, built once with ``mkdocs build --strict``."""
    pytest.importorskip("mkdocs", reason="mkdocs is in the test extra: pip install -e '.[test]'")
    pytest.importorskip("material", reason="mkdocs-material is in the test extra: pip install -e '.[test]'")
    site = tmp_path_factory.mktemp("docs") / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-5000:]
    return site


def test_the_documentation_site_builds_strictly(site):
    for page in ("index.html", "quickstart.html", "commands/shrub.html", "concepts.html"):
        assert (site / page).is_file(), page
    assert (site / "webmap.png").is_file()


def _help(*words: str) -> str:
    """``gistools WORDS --help`` as printed."""
    proc = subprocess.run([sys.executable, "-m", "gistools.cli.main", *words, "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, env={**os.environ, "COLUMNS": "100"})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def _section(text: str, name: str) -> str:
    return text.split(f"\n{name}:\n", 1)[1].split("\n\n", 1)[0] if f"\n{name}:\n" in text else ""


def _table_rows(page: Path) -> list[tuple[str, str]]:
    """The (option, what) rows of the page's options table, as the reader sees them."""
    import html
    import re

    text = page.read_text()
    table = text.split('id="options"', 1)[1].split("</table>", 1)[0]
    rows = []
    for row in re.findall(r"<tr>(.*?)</tr>", table, re.S)[1:]:
        cells = [" ".join(html.unescape(re.sub(r"<[^>]+>", "", c)).split()) for c in re.findall(r"<td>(.*?)</td>", row, re.S)]
        rows.append((cells[0], cells[1]))
    return rows


def test_every_command_has_a_reference_page_whose_options_table_is_its_help(site):
    """One page per command of ``gistools --help``; its table holds every option of ``gistools COMMAND --help``, in
    order, with the same words, and nothing else."""
    import re

    commands = []
    for name in re.findall(r"^  (\S+)", _section(_help(), "Commands"), re.M):
        subcommands = re.findall(r"^  (\S+)", _section(_help(name), "Commands"), re.M)
        commands += [(f"{name}-{sub}", (name, sub)) for sub in subcommands] or [(name, (name,))]
    assert len(commands) >= 20
    pages = sorted(p.stem for p in (site / "reference").glob("*.html"))
    assert pages == sorted(page for page, _ in commands), "a reference page per command, no other"
    for page, words in commands:
        command = " ".join(words)
        printed = _section(_help(*words), "Options")
        help_text = "".join(printed.split())
        rows = _table_rows(site / "reference" / f"{page}.html")
        # the options column of --help: the lines of the section that start with an option's name
        at = 0
        for option, what in rows:
            found = help_text.find("".join(f"{option}{what}".split()), at)
            assert found >= 0, f"gistools {command}: {option!r} {what[:60]!r}... is not in --help after position {at}"
            at = found + 1
        assert at and help_text[at - 1:].startswith("".join(f"{rows[-1][0]}{rows[-1][1]}".split())) and (
            help_text.endswith("".join(f"{rows[-1][0]}{rows[-1][1]}".split()))), f"gistools {command}: rows left out"
        assert len(rows) == len(re.findall(r"^  -", printed, re.M)), f"gistools {command}: rows left out"


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


def _hrefs(html: str) -> list[str]:
    return re.findall(r'(?:href|src)="([^"]+)"', html)


def test_the_site_works_from_files_every_link_a_file_nothing_fetched(site):
    """Opened from disk (a folder, the QGIS plugin's help/): every link of every page is a file of the site (no
    folder URL a browser would list), and no page loads a script, a style or a font from the network."""
    from urllib.parse import unquote, urlparse

    pages = sorted(p for p in site.rglob("*.html") if p.name != "404.html")  # 404: a web server's, by absolute paths
    assert len(pages) > 20
    for page in pages:
        html = page.read_text(encoding="utf-8")
        for ref in _hrefs(html):
            url = urlparse(ref)
            if url.scheme or ref.startswith(("#", "//", "mailto:")):
                continue
            target = (page.parent / unquote(url.path)).resolve() if url.path else page
            assert target.is_file(), f"{page.relative_to(site)}: {ref}"
        for tag in re.findall(r"<(?:script|link)\b[^>]*>", html):
            assert "http://" not in tag and "https://" not in tag, (page, tag)


def test_the_search_works_from_files_in_a_real_browser(site, tmp_path):
    """The search of the site opened as file:// with the network blocked (Debian's chromium): a query finds the
    pages that hold it, and each result is a file of the site."""
    from urllib.parse import unquote, urlparse

    from conftest import BLOCKED, chromium, need_chromium

    need_chromium("offline documentation")
    page = (site / "commands" / "shrub.html").as_uri() + "?q=canopy"
    dom = chromium("--virtual-time-budget=8000", *BLOCKED, "--dump-dom", page, home=tmp_path).stdout
    found = re.search(r"(\d+) matching documents?", dom)
    assert found and int(found.group(1)) >= 3, dom[-2000:]
    links = re.findall(r'<a href="([^"]+)" class="md-search-result__link', dom)
    assert links, "no result links"
    for link in links:
        url = urlparse(link)
        assert url.scheme == "file" and Path(unquote(url.path)).is_file(), link

