"""The plugin zip ``tools/build_plugin.py`` makes is one plugins.qgis.org accepts, and publishable as it stands.

The upload checks of the official repository are reimplemented here (not imported: the site is a Django project)
from QGIS-Django, https://github.com/qgis/QGIS-Django at commit f2b9bd925ed8fff0067642dd7abcbe5db4b6d685:

- qgis-app/plugins/validator.py, ``validator()``: the zip's size (PLUGIN_MAX_UPLOAD_SIZE, 25 MB), no path
  information, no .pyc, no __MACOSX / .git / __pycache__ folder, a sound zip (testzip), one top folder whose name is
  a package name (PEP 8 for a new plugin), __init__.py and metadata.txt in it, a [general] section, the required
  fields (PLUGIN_REQUIRED_METADATA), the icon, the boolean flags, qgisMinimumVersion >= 1.8, the tracker /
  repository / homepage as URLs with a scheme and a host other than the template's ``http://bugs`` ... and reachable
  (``_check_url_link``: a HEAD request; here only with GISTOOLS_CHECK_URLS=1, the tests run offline), the LICENSE
  file (mandatory since June 2024), an author without a slash;
- qgis-app/plugins/models.py: ``email`` an EmailField, ``homepage`` / ``repository`` / ``tracker`` URLFields,
  ``version`` a VersionField (digits and dots, sorted by ``vjust`` as up to four parts of up to three characters,
  32 characters at most), ``min_qg_version`` / ``max_qg_version`` QGVersionZeroForcedFields, ``name`` and
  ``author`` 256 characters at most;
- qgis-app/plugins/views.py, ``plugin_upload``: ``tracker``, ``repository`` and ``about`` must not be empty, an
  empty ``homepage`` is warned about (recommended).

Beyond the site's checks: the LICENSE is the repository's (MIT), no placeholder or empty URL in metadata.txt or in
the shipped model, supportsQt6 declared, every Help of the algorithms and of the model opens a page the zip's
documentation has, and no two modules of the plugin import each other (directly or through others, function-level
imports included).
"""

from __future__ import annotations

import ast
import configparser
import io
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

from conftest import ROOT, SAMPLE

sys.path.insert(0, str(ROOT / "tools"))
import build_plugin  # noqa: E402
import make_model  # noqa: E402

# validator.py
MAX_UPLOAD_SIZE = 25_000_000
REQUIRED = ("name", "description", "version", "qgisMinimumVersion", "author", "email", "about", "tracker",
            "repository")
BOOLEANS = ("experimental", "deprecated", "server")
FORBIDDEN_FOLDERS = ("__MACOSX", ".git", "__pycache__")
TEMPLATE_URLS = {"tracker": "http://bugs", "repository": "http://repo", "homepage": "http://homepage"}
# views.py warns without it; QGIS's plugin manager reads the rest (docs: pyqgis_developer_cookbook, metadata.txt)
RECOMMENDED = ("homepage", "tags", "icon", "category", "qgisMaximumVersion", "experimental", "deprecated")
URL_FIELDS = ("homepage", "repository", "tracker")
# hosts that stand for no site: RFC 2606 / 6761 names and this machine
PLACEHOLDER_HOST = re.compile(r"(^|\.)(example\.(org|com|net)|example|invalid|test|localhost)$|^127\.|^0\.0\.0\.0$")
URL = re.compile(r"""https?://[^\s"'<>)]+""")


# ------------------------------------------------------------------ plugins.qgis.org's upload checks, reimplemented

def _zip_problems(zf: zipfile.ZipFile, size: int) -> list[str]:
    problems = [] if size <= MAX_UPLOAD_SIZE else [f"{size} bytes, more than {MAX_UPLOAD_SIZE}"]
    for name in zf.namelist():
        if ".." in name or name.startswith("/"):
            problems.append(f"path information in {name}")
        if ".pyc" in name:
            problems.append(f".pyc file {name}")
        problems += [f"{folder} folder in {name}" for folder in FORBIDDEN_FOLDERS if folder in name.split("/")]
    bad = zf.testzip()
    if bad:
        problems.append(f"bad zip (CRC) on {bad}")
    parents = sorted({name.split("/")[0] for name in zf.namelist()})
    if len(parents) > 1:
        problems.append(f"several top folders: {parents}")
    return problems


def _version_problems(meta: dict) -> list[str]:
    problems = []
    version = meta.get("version", "")
    # PluginVersion.clean: digits and dots; VersionField / vjust: sortable as up to 4 parts of up to 3 characters
    if not re.fullmatch(r"\d{1,3}(\.\d{1,3}){0,3}", version) or len(version) > 32:
        problems.append(f"version {version!r} is not up to four dot-separated numbers of up to three digits")
    qgis = {}
    for key in ("qgisMinimumVersion", "qgisMaximumVersion"):
        value = meta.get(key, "")
        if value and not re.fullmatch(r"\d+\.\d+(\.\d+)?", value):
            problems.append(f"{key} {value!r} is not major.minor[.patch]")
        elif value:
            qgis[key] = tuple(int(p) for p in value.split("."))
    if qgis.get("qgisMinimumVersion", (1, 8)) < (1, 8):
        problems.append("qgisMinimumVersion below 1.8 needs the metadata in __init__.py too")
    if len(qgis) == 2 and qgis["qgisMaximumVersion"] < qgis["qgisMinimumVersion"]:
        problems.append("qgisMaximumVersion below qgisMinimumVersion")
    return problems


def _field_problems(meta: dict) -> list[str]:
    problems = [f"{key} missing or empty" for key in REQUIRED if not meta.get(key, "").strip()]
    if "/" in meta.get("author", ""):
        problems.append("author holds a slash")
    problems += [f"{key} longer than 256" for key in ("name", "author") if len(meta.get(key, "")) > 256]
    # Django's EmailValidator, in short: one @, a user part, a domain with a dot, no spaces
    if not re.fullmatch(r"[^@\s]+@[A-Za-z0-9-]+(\.[A-Za-z0-9-]+)*\.[A-Za-z]{2,}", meta.get("email", "")):
        problems.append(f"email {meta.get('email')!r} is not an address")
    for key in URL_FIELDS:
        if key in meta:  # _check_url_link: a scheme and a host, not the template's; URLField: http(s) or ftp(s)
            url = urlparse(meta[key])
            if meta[key] == TEMPLATE_URLS[key] or url.scheme not in ("http", "https", "ftp", "ftps") or not url.netloc:
                problems.append(f"{key} {meta[key]!r} is not a valid URL")
    for flag in BOOLEANS:
        if flag in meta and meta[flag].strip().lower() not in ("true", "false", "1", "0"):
            problems.append(f"{flag} {meta[flag]!r} is not a boolean")
    return problems + _version_problems(meta)


def upload_problems(path: Path, is_new: bool = True) -> list[str]:
    """What plugins.qgis.org's upload (validator.py, with the model fields' and the upload view's rules) refuses in
    the plugin zip ``path``; empty when it accepts it (URL reachability aside: :func:`test_urls_answer`)."""
    with zipfile.ZipFile(path) as zf:
        problems = _zip_problems(zf, path.stat().st_size)
        names = zf.namelist()
        package = names[0].split("/")[0] if "/" in names[0] else ""
        if not package:
            return problems + ["no folder inside the zip"]
        if is_new and not re.fullmatch(r"[a-z_][a-z0-9_]*", package):
            problems.append(f"folder {package} is not a PEP 8 package name")
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9-_]+", package):
            problems.append(f"folder {package} is not a package name")
        missing = [f for f in ("__init__.py", "metadata.txt", "LICENSE") if f"{package}/{f}" not in names]
        problems += [f"no {package}/{f}" for f in missing]
        if "metadata.txt" in missing:
            return problems
        parser = configparser.ConfigParser()  # as validator.py reads it (with interpolation: a lone % fails)
        parser.optionxform = str
        try:
            parser.read_file(io.StringIO(zf.read(f"{package}/metadata.txt").decode("utf8")))
            meta = dict(parser.items("general"))
        except (configparser.Error, UnicodeDecodeError) as err:
            return problems + [f"metadata.txt: {err}"]
        if meta.get("icon") and f"{package}/{meta['icon'].removeprefix('./')}" not in names:
            problems.append(f"icon {meta['icon']} not in the zip")
    return problems + _field_problems(meta)


# ------------------------------------------------------------------ the zip

@pytest.fixture(scope="module")
def plugin_zip(tmp_path_factory) -> Path:
    return build_plugin.build(tmp_path_factory.mktemp("dist"))


@pytest.fixture(scope="module")
def unpacked(plugin_zip, tmp_path_factory) -> Path:
    where = tmp_path_factory.mktemp("unpacked")
    with zipfile.ZipFile(plugin_zip) as zf:
        zf.extractall(where)
    return where / build_plugin.PLUGIN


@pytest.fixture(scope="module")
def metadata(unpacked) -> dict:
    parser = configparser.ConfigParser()
    parser.optionxform = str
    parser.read(unpacked / "metadata.txt", encoding="utf-8")
    return dict(parser.items("general"))


def test_the_checks_see_what_plugins_qgis_org_refuses(plugin_zip, tmp_path):
    """First, that they are live: a zip with a cache folder, a .pyc, no LICENSE, a CamelCase folder, and metadata
    with the template's tracker, no repository, a bad email and version is refused for each of them."""
    bad = tmp_path / "bad.zip"
    meta = ("[general]\nname=x\ndescription=d\nabout=a\nversion=1.0.0-beta\nqgisMinimumVersion=3.22\nauthor=a/b\n"
            "email=nobody\ntracker=http://bugs\nicon=icon.png\n")
    with zipfile.ZipFile(bad, "w") as zf:
        for name, text in {"Bad/__init__.py": "", "Bad/metadata.txt": meta, "Bad/__pycache__/x.cpython-311.pyc": "",
                           "Bad/__MACOSX/y": ""}.items():
            zf.writestr(name, text)
    found = "\n".join(upload_problems(bad))
    for expected in (".pyc file", "__pycache__ folder", "__MACOSX folder", "not a PEP 8 package name", "no Bad/LICENSE",
                     "repository missing", "author holds a slash", "email 'nobody'", "tracker 'http://bugs'",
                     "version '1.0.0-beta'", "icon icon.png"):
        assert expected in found, (expected, found)
    assert upload_problems(bad, is_new=False) != [] and "PEP 8" not in "".join(upload_problems(bad, is_new=False))


def test_plugins_qgis_org_accepts_the_zip(plugin_zip):
    assert upload_problems(plugin_zip) == []
    with zipfile.ZipFile(plugin_zip) as zf:  # the folder keeps its name from version to version (forms.py)
        assert {n.split("/")[0] for n in zf.namelist()} == {build_plugin.PLUGIN}


def test_the_zip_carries_the_repositorys_mit_license(unpacked):
    text = (unpacked / "LICENSE").read_text(encoding="utf-8")
    assert text == (ROOT / "LICENSE").read_text(encoding="utf-8") and text.startswith("MIT License")


def test_metadata_has_every_required_and_recommended_field_and_declares_qt6(metadata):
    lacking = [k for k in REQUIRED + RECOMMENDED + ("supportsQt6",) if not metadata.get(k, "").strip()]
    assert not lacking, lacking
    # QGIS 4 (Qt 6) loads only plugins that say so; tests/test_qgis4_ready.py runs QGIS's migration checker on them
    assert metadata["supportsQt6"] == "True"
    assert metadata["version"] == build_plugin.version() and metadata["hasProcessingProvider"] == "yes"


def _placeholder(url: str) -> bool:
    host = urlparse(url).hostname or ""
    return not host or bool(PLACEHOLDER_HOST.search(host.lower()))


def test_no_placeholder_or_empty_url_in_metadata_or_the_model(plugin_zip, metadata, unpacked):
    urls = {key: metadata.get(key, "") for key in URL_FIELDS}
    assert all(urls.values()) and not [u for u in urls.values() if _placeholder(u)], urls
    model = (unpacked / "models" / "shrub_density.model3").read_text(encoding="utf-8")
    help_url = re.search(r'<Option value="([^"]*)" name="HELP_URL"', model) or re.search(
        r'<Option name="HELP_URL" value="([^"]*)"', model)
    assert help_url and help_url.group(1), "the model has no help URL"
    assert not [u for u in URL.findall(model) if _placeholder(u)]
    with zipfile.ZipFile(plugin_zip) as zf:  # nowhere in the zip: the documentation site included
        hits = [n for n in zf.namelist() if re.search(rb"example\.(org|com|net)\b", zf.read(n))]
    assert not hits, hits


def test_the_project_home_is_declared_once_and_the_build_refuses_without_it(tmp_path, monkeypatch):
    """qgis_plugin/metadata.txt holds the homepage, repository, tracker and email; build_plugin.py checks them and
    make_model.py takes the model's help from there. A declaration without them builds nothing."""
    assert build_plugin.declared()["homepage"].startswith("https://")
    source = tmp_path / "qgis_plugin"
    shutil.copytree(build_plugin.SOURCE, source, ignore=shutil.ignore_patterns("__pycache__"))
    text = (source / "metadata.txt").read_text(encoding="utf-8")
    (source / "metadata.txt").write_text(re.sub(r"(?m)^(email|tracker)=.*\n", "", text), encoding="utf-8")
    monkeypatch.setattr(build_plugin, "SOURCE", source)
    with pytest.raises(SystemExit, match="lacks email, tracker"):
        build_plugin.build(tmp_path / "dist")
    assert not list((tmp_path / "dist").glob("*.zip*"))
    (source / "metadata.txt").write_text(text.replace("tracker=https://", "tracker=ftp:/"), encoding="utf-8")
    with pytest.raises(SystemExit, match="tracker must be"):
        build_plugin.declared()


def test_the_models_help_opens_its_section_of_the_documentation(unpacked, metadata):
    """The model file holds its help URL (no path of the plugin's folder can be written in it): the model's section
    of the documentation site at the declared homepage, the same site the zip ships in help/."""
    model = (unpacked / "models" / "shrub_density.model3").read_text(encoding="utf-8")
    url = make_model.help_url()
    assert f'"{url}"' in model, "the model was not made from the declared homepage: run tools/make_model.py"
    home = metadata["homepage"].rstrip("/") + "/"
    assert url.startswith(home)
    page, _, anchor = url[len(home):].partition("#")
    html = unpacked / "help" / page
    assert html.is_file() and f'id="{anchor}"' in html.read_text(encoding="utf-8"), url


def test_every_algorithms_help_opens_a_page_of_the_zip(unpacked):
    """Each algorithm's Help (GistoolsAlgorithm.helpUrl) from the plugin as unpacked from the zip: a file of its
    help/ folder holding the algorithm's section."""
    pytest.importorskip("qgis.core")
    script = ("import json, sys\n"
              f"sys.path[:0] = [{str(unpacked.parent)!r}, {str(ROOT)!r}]\n"
              f"from {build_plugin.PLUGIN}.algorithms import ALGORITHMS\n"
              "print(json.dumps({a().name(): a().helpUrl() for a in ALGORITHMS}))\n")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert run.returncode == 0, run.stderr[-3000:]
    urls = json.loads(run.stdout.strip().splitlines()[-1])
    assert len(urls) >= 20
    for name, url in urls.items():
        parsed = urlparse(url)
        page = Path(unquote(parsed.path))
        assert parsed.scheme == "file" and page.is_relative_to(unpacked / "help") and page.is_file(), (name, url)
        assert parsed.fragment == f"qgis-{name}" and f'id="qgis-{name}"' in page.read_text(encoding="utf-8"), url


def test_urls_answer(metadata):
    """plugins.qgis.org sends a HEAD request to the tracker, repository and homepage and refuses the upload when one
    answers 400 or more (or not at all). Needs the network: GISTOOLS_CHECK_URLS=1 before an upload."""
    if os.environ.get("GISTOOLS_CHECK_URLS") != "1":
        pytest.skip("set GISTOOLS_CHECK_URLS=1 to check that the declared URLs answer (plugins.qgis.org does)")
    import urllib.request

    failing = []
    for key in URL_FIELDS:
        request = urllib.request.Request(metadata[key], method="HEAD", headers={"User-Agent": "Mozilla/5.0"})
        try:
            with urllib.request.urlopen(request, timeout=30) as answer:
                status = answer.status
        except Exception as err:  # noqa: BLE001 - any failure is the site's refusal
            status = getattr(err, "code", str(err))
        if not isinstance(status, int) or status >= 400:
            failing.append((key, metadata[key], status))
    assert not failing, failing


# ------------------------------------------------------------------ no import cycle between the plugin's modules

def import_graph(folder: Path, package: str) -> dict[str, set[str]]:
    """{module: the modules of ``package`` (the folder ``folder``) it imports}, from every import statement, those
    inside functions included; relative imports resolved; ``from . import x`` is an edge to the module x."""
    files = {p: ".".join((package, *p.relative_to(folder).with_suffix("").parts)) for p in folder.rglob("*.py")}
    files = {p: m.removesuffix(".__init__") for p, m in files.items()}
    modules = set(files.values())
    aliases = (package, "qgis_plugin", "gistools_qgis")  # the source folder's name and the installed plugin's

    def resolve(name: str) -> str:
        head, _, rest = name.partition(".")
        return package + ("." + rest if rest else "") if head in aliases else name

    graph = {}
    for path, module in files.items():
        here = module if path.name == "__init__.py" else module.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                edges.update(resolve(a.name) for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = ".".join(here.split(".")[: len(here.split(".")) - node.level + 1])
                    target = f"{base}.{node.module}" if node.module else base
                else:
                    target = resolve(node.module)
                for a in node.names:
                    edges.add(f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target)
        graph[module] = {e for e in edges if e in modules and e != module}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    state: dict = {}
    found = []

    def visit(module, path):
        state[module] = "open"
        for dep in sorted(graph[module]):
            if state.get(dep) == "open":
                found.append(path[path.index(dep):] + [dep])
            elif dep not in state:
                visit(dep, path + [dep])
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    return found


def test_the_cycle_finder_sees_function_level_and_relative_imports(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("def classFactory(iface):\n    from .plugin import P\n    return P(iface)\n")
    (pkg / "plugin.py").write_text("def start():\n    from .install import run\n    return run()\n")
    (pkg / "install.py").write_text("def run():\n    from . import plugin\n    return plugin\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "a.py").write_text("from ..install import run\nimport pkg.sub.b\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from pkg.sub import a\n")
    graph = import_graph(pkg, "pkg")
    assert graph["pkg"] == {"pkg.plugin"} and graph["pkg.sub.a"] == {"pkg.install", "pkg.sub.b"}
    assert sorted(map(tuple, cycles(graph))) == [("pkg.plugin", "pkg.install", "pkg.plugin"),
                                                ("pkg.sub.a", "pkg.sub.b", "pkg.sub.a")]


def test_no_two_modules_of_the_plugin_import_each_other(unpacked):
    graph = import_graph(unpacked, build_plugin.PLUGIN)
    plugin, install = f"{build_plugin.PLUGIN}.plugin", f"{build_plugin.PLUGIN}.install"
    assert install in graph[plugin] and plugin not in graph[install]  # the checks are install.py's, plugin.py uses them
    assert cycles(graph) == []
    source = import_graph(ROOT / "qgis_plugin", "qgis_plugin")  # the checkout's, as QGIS loads it from a link
    assert cycles(source) == [] and set(source) == {m.replace(build_plugin.PLUGIN, "qgis_plugin", 1) for m in graph}


def test_the_zip_carries_gistools_as_a_pure_wheel_that_runs_its_numpy_engine(unpacked, tmp_path):
    """The plugin's installer takes gistools from the zip (wheels/): its pure wheel (py3-none-any, no compiled file)
    installed alone runs a real command with the numpy engine, and says so; pip picks it for gistools."""
    wheels = sorted((unpacked / "wheels").glob("gistools-*.whl"))
    assert [w.name for w in wheels] == [f"gistools-{build_plugin.version()}-py3-none-any.whl"]
    with zipfile.ZipFile(wheels[0]) as z:
        names = z.namelist()
    assert "gistools/cli/main.py" in names and not [n for n in names if n.endswith((".so", ".pyd", ".dylib"))]
    site = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--disable-pip-version-check",
                          "--no-index", "--find-links", str(unpacked / "wheels"), "--target", str(site), "gistools"],
                         capture_output=True, text=True, timeout=300)
    assert pip.returncode == 0, pip.stderr[-2000:]
    assert (site / "gistools").is_dir() and not list((site / "gistools").glob("_kernel*"))
    env = {**os.environ, "PYTHONPATH": str(site)}
    # this interpreter as QGIS's would be: without the checkout's editable install (its finder maps gistools._kernel)
    alone = ("import sys; sys.path.insert(0, sys.argv[1]); "
             "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower()]; ")
    run = subprocess.run([sys.executable, "-I", "-c", alone + "from gistools.cli.main import main; sys.argv[1:] = sys.argv[2:]; main()", str(site),
                          "rasters", str(SAMPLE / "35813.laz"), "--out", str(tmp_path / "out"), "--cell-size", "6ft",
                          "-q"], capture_output=True, text=True, timeout=600, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    version = subprocess.run([sys.executable, "-I", "-c", alone + "import gistools.kernel as k, gistools; print(k.loaded(), gistools.__file__)", str(site)],
                             capture_output=True, text=True, timeout=120)
    assert version.stdout.split()[0] == "False" and version.stdout.split()[1].startswith(str(site)), version
    assert list((tmp_path / "out" / "dsm").glob("*.tif"))
