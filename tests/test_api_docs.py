"""Every function exported by ``gistools`` has a numpydoc docstring that documents its signature, read by griffe
from the imported function (as mkdocstrings renders docs/api.md), and the built site has its entry on the Python API page."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

import gistools
from conftest import ROOT

griffe = pytest.importorskip("griffe", reason="griffe comes with mkdocstrings[python], in the test extra")

FUNCTIONS = sorted(name for name in gistools.__all__ if inspect.isfunction(getattr(gistools, name)))


def _sections(name: str, caplog) -> dict:
    """{section kind: section} of the function's docstring as griffe parses it (numpy style), the docstring of the
    imported function as mkdocstrings renders it (with the shared sections of gistools/docstrings.py); griffe's
    warnings (a documented parameter not in the signature, one without a type, a malformed section) fail."""
    import logging

    function = getattr(gistools, name)
    assert function.__doc__, f"{name}: no docstring"
    defined = inspect.unwrap(function)  # gistools exports it checked (gistools.arguments); it is defined there
    docstring = griffe.Docstring(inspect.getdoc(function), parent=griffe.inspect(defined.__module__)[defined.__name__])
    with caplog.at_level(logging.WARNING):
        parsed = griffe.parse_numpy(docstring, warn_unknown_params=True, warn_missing_types=True)
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert not warnings, f"{name}: griffe warns: {warnings}"
    return {section.kind.value: section for section in parsed}


def test_the_exported_functions_are_the_ones_listed():
    """``gistools.__all__``'s functions are exactly the functions of the Python API page (docs/api.md), each
    rendered from the module that defines it."""
    import re

    page = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    listed = re.findall(r"^::: (gistools\.[\w.]+)$", page, re.M)
    functions = [name for name in listed if inspect.isfunction(getattr(gistools, name.rsplit(".", 1)[1], None))]
    assert sorted(name.rsplit(".", 1)[1] for name in functions) == FUNCTIONS
    for name in functions:
        assert inspect.unwrap(getattr(gistools, name.rsplit(".", 1)[1])).__module__ == name.rsplit(".", 1)[0], name


@pytest.mark.parametrize("name", FUNCTIONS)
def test_docstring_documents_the_signature(name, caplog):
    function = getattr(gistools, name)
    sections = _sections(name, caplog)
    import re

    assert not re.search(r"^\s*\{\w+\}\s*$", function.__doc__, re.M), f"{name}: a shared section not filled in"
    missing = {"parameters", "returns", "examples"} - set(sections)
    assert not missing, f"{name}: no {', '.join(sorted(missing))} section"
    text = sections["text"].value if "text" in sections else ""
    assert text.strip(), f"{name}: no summary"
    documented = [p.name for p in sections["parameters"].value]
    signature = [p for p in inspect.signature(function).parameters]
    assert documented == signature, f"{name}: documents {documented}, its signature has {signature}"
    for p in sections["parameters"].value:
        assert p.annotation and p.description.strip(), f"{name}: parameter {p.name} without a type or description"
    assert all(r.description.strip() for r in sections["returns"].value), f"{name}: Returns without a description"
    examples = sections["examples"].value
    assert any(kind.value == "examples" for kind, _ in examples), f"{name}: Examples without >>> lines"


@pytest.fixture(scope="module")
def api_page(tmp_path_factory):
    pytest.importorskip("mkdocstrings", reason="mkdocstrings[python] is in the test extra")
    site = tmp_path_factory.mktemp("api") / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-5000:]
    return (site / "api.html").read_text()


def test_the_api_page_speaks_to_users(api_page):
    """The docstrings reach the site: the page holds no development history (tests/test_docs.py's words) and no
    doctest flag."""
    import html
    import re

    from test_docs import HISTORY

    text = html.unescape(re.sub(r"<[^>]+>", " ", api_page))
    found = [m.group(0) for pattern in HISTORY for m in re.finditer(pattern, text, re.I)]
    assert not found, found
    assert "doctest:" not in text


@pytest.mark.parametrize("name", FUNCTIONS)
def test_the_api_page_has_each_function(api_page, name):
    function = inspect.unwrap(getattr(gistools, name))
    assert f'id="{function.__module__}.{function.__name__}"' in api_page, name


@pytest.fixture(scope="module")
def example_folder(tmp_path_factory):
    """A folder as ``gistools.write_examples`` makes it (with the checkout's sample_tiles/), made once."""
    folder = tmp_path_factory.mktemp("examples") / "made"
    gistools.write_examples(folder, sample_tiles=ROOT / "sample_tiles")
    return folder


@pytest.mark.parametrize("name", FUNCTIONS)
def test_the_examples_run_as_printed(name, example_folder, tmp_path, monkeypatch):
    """Each function's Examples, run in a fresh copy of the examples folder, print what the docstring shows. Those
    that write files carry ``doctest: +SKIP`` (pytest's --doctest-modules runs in the checkout); here the flag is
    lifted."""
    import doctest
    import importlib
    import shutil

    function = getattr(gistools, name)
    text = inspect.getdoc(function).replace("# doctest: +SKIP", "")
    module = importlib.import_module(inspect.unwrap(function).__module__)
    test = doctest.DocTestParser().get_doctest(text, dict(vars(module)), name, module.__file__, 0)
    assert test.examples, name
    shutil.copytree(example_folder, tmp_path / "run")
    monkeypatch.chdir(tmp_path / "run")
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    out = []
    result = runner.run(test, out=out.append)
    assert result.failed == 0, "".join(out) + _failed_tiles(tmp_path / "run")


def _failed_tiles(folder) -> str:
    """What the reports under ``folder`` say of their failed tiles (a failed example's count says only how many)."""
    import json

    lines = []
    for report in sorted(folder.rglob("report.json")):
        try:
            tiles = json.loads(report.read_text(encoding="utf-8")).get("tiles", {})
        except (OSError, ValueError):
            continue
        items = tiles.values() if isinstance(tiles, dict) else tiles
        lines += [f"{report}: {t.get('name')}: {t.get('error')}" for t in items
                  if isinstance(t, dict) and t.get("status") == "failed"]
    return "\n".join(["", *lines]) if lines else ""
