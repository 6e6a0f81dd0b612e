"""Build the QGIS plugin zip (Plugins > Manage and Install Plugins > Install from ZIP), and optionally install it.

    python tools/build_plugin.py                       # -> dist/gistools_qgis-<version>.zip
    python tools/build_plugin.py --install PROFILE_DIR # also unpack it into a QGIS profile and enable it

PROFILE_DIR is a QGIS profile folder, e.g. ~/.local/share/QGIS/QGIS3/profiles/default. The plugin folder
is named gistools_qgis (not gistools, which would hide the gistools library on QGIS's sys.path).

The zip is what plugins.qgis.org accepts (tests/test_plugin_package.py applies its upload checks): metadata.txt
with every required and recommended field (the project's homepage, repository, tracker and email are declared
once, in qgis_plugin/metadata.txt), the LICENSE, no caches or hidden files.
"""

from __future__ import annotations

import argparse
import configparser
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "qgis_plugin"
PLUGIN = "gistools_qgis"


def version() -> str:
    """The gistools version, from gistools/_version.py (the one place it is written): the zip's metadata.txt
    carries it."""
    import re

    found = re.search(r'^__version__ = "([^"]+)"', (ROOT / "gistools" / "_version.py").read_text(), re.M)
    if not found:
        raise SystemExit("gistools/_version.py has no __version__")
    return found.group(1)


# what plugins.qgis.org requires in metadata.txt (its upload refuses a zip without one), then what it recommends and
# QGIS reads; the project's public home among them is declared once, in qgis_plugin/metadata.txt
REQUIRED = ("name", "qgisMinimumVersion", "description", "about", "version", "author", "email", "repository", "tracker")
RECOMMENDED = ("homepage", "tags", "icon", "category", "qgisMaximumVersion", "experimental", "deprecated",
               "supportsQt6")
URLS = ("homepage", "repository", "tracker")


def declared() -> dict:
    """The [general] fields of qgis_plugin/metadata.txt (the one declaration of the project's homepage, repository,
    tracker and email), checked: every required and recommended field given, each URL an http(s) address."""
    from urllib.parse import urlparse

    cfg = configparser.ConfigParser(interpolation=None)
    cfg.optionxform = str
    cfg.read(SOURCE / "metadata.txt", encoding="utf-8")
    fields = dict(cfg["general"]) if cfg.has_section("general") else {}
    lacking = [k for k in REQUIRED + RECOMMENDED if not fields.get(k, "").strip()]
    if lacking:
        raise SystemExit(f"qgis_plugin/metadata.txt lacks {', '.join(lacking)} (plugins.qgis.org needs them)")
    bad = [k for k in URLS if urlparse(fields[k]).scheme not in ("http", "https") or not urlparse(fields[k]).netloc]
    if bad:
        raise SystemExit(f"qgis_plugin/metadata.txt: {', '.join(bad)} must be http(s) addresses")
    return fields


def metadata() -> str:
    """qgis_plugin/metadata.txt with version= set to the gistools version (after :func:`declared` checked it), and
    the algorithms of the commands declared whole (gistools.parameters) named in about= beside the others."""
    declared()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from gistools.parameters import DECLARED

    more = "".join(f" {name.replace('-', '_')} ({spec['summary'].split(' (')[0].rstrip('.')});"
                   for name, spec in sorted(DECLARED.items()))
    lines = []
    for line in (SOURCE / "metadata.txt").read_text().splitlines():
        if line.startswith("version="):
            line = f"version={version()}"
        elif line.startswith("about=") and more:
            line = line.replace(" Needs the gistools Python package", f" Also{more.rstrip(';')}. Needs the gistools "
                                "Python package", 1)
        lines.append(line)
    return "\n".join(lines) + "\n"


def shipped(path: Path) -> bool:
    """Whether a file of qgis_plugin/ goes into the zip: not Python's caches, nor hidden files or folders (.git,
    .DS_Store), nor macOS's __MACOSX, which plugins.qgis.org refuses, nor a help/ folder (the built site goes
    there)."""
    parts = path.relative_to(SOURCE).parts
    return (path.is_file() and path.suffix != ".pyc" and "__pycache__" not in parts and "__MACOSX" not in parts
            and parts[0] != "help" and not any(p.startswith(".") for p in parts))


def build_site(into: Path) -> bool:
    """The documentation site (mkdocs.yml, docs/) built into ``into``, for the algorithms' Help buttons; False
    (with a note) where MkDocs is not installed (pip install mkdocs mkdocs-material)."""

    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "-q", "-f", str(ROOT / "mkdocs.yml"), "-d", str(into)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"build_plugin: the help pages are left out (mkdocs: {(proc.stderr or proc.stdout).strip()[-300:]})",
              file=sys.stderr)
        return False
    return True


def pure_wheel(into: Path) -> Path | None:
    """gistools as a pure-Python wheel (``py3-none-any``, the numpy engine) built from a copy of the sources (no
    compiled file of the checkout's build/ can slip in); None (with a note) where pip cannot build it. The plugin's
    installer takes it where no wheel of the platform is there (gistools_qgis/wheels/)."""
    import tempfile

    into.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        src = Path(work) / "src"
        for name in ("pyproject.toml", "setup.py", "README.md", "LICENSE"):
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, src / name)
        shutil.copytree(ROOT / "gistools", src / "gistools", ignore=shutil.ignore_patterns(
            "__pycache__", "*.so", "*.pyd", "*.dylib", "*.c", "*.o"))
        try:
            proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                                   "--disable-pip-version-check", "-w", str(into), str(src)], capture_output=True,
                                  text=True, timeout=900, env={**os.environ, "GISTOOLS_PURE": "1"})
        except subprocess.TimeoutExpired:
            proc = subprocess.CompletedProcess([], 1, "", "pip wheel took more than 15 minutes")
    found = sorted(into.glob(f"gistools-{version()}-py3-none-any.whl"))
    if proc.returncode != 0 or not found:
        print(f"build_plugin: the gistools wheel is left out (pip: {(proc.stderr or proc.stdout).strip()[-300:]})",
              file=sys.stderr)
        return None
    return found[0]


def build(dist: Path, wheels: Path | None = None) -> Path:
    """The plugin zip: qgis_plugin/ as gistools_qgis/, its metadata given the gistools version, the project's
    LICENSE, and the documentation site as gistools_qgis/help/ (each algorithm's Help opens its page there,
    offline)."""
    import tempfile

    dist.mkdir(parents=True, exist_ok=True)
    target = dist / f"{PLUGIN}-{version()}.zip"
    tmp = target.with_name(target.name + ".partial")
    meta = metadata()  # refused (SystemExit) before anything is written when the declaration is incomplete
    with tempfile.TemporaryDirectory() as work, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(f"{PLUGIN}/metadata.txt", meta)
        for path in sorted(p for p in SOURCE.rglob("*") if shipped(p) and p != SOURCE / "metadata.txt"):
            zf.write(path, f"{PLUGIN}/{path.relative_to(SOURCE).as_posix()}")
        zf.write(ROOT / "LICENSE", f"{PLUGIN}/LICENSE")  # plugins.qgis.org requires it in the plugin's folder
        # gistools itself for the installer: the pure wheel, and the platform wheels of a release (``wheels``)
        made = pure_wheel(Path(work) / "wheels")
        ship = {path.name: path for path in ([made] if made else [])}
        ship.update({path.name: path for path in (sorted(Path(wheels).glob("gistools-*.whl")) if wheels else [])})
        for name, path in sorted(ship.items()):
            zf.write(path, f"{PLUGIN}/wheels/{name}")
        site = Path(work) / "help"
        if build_site(site):
            for path in sorted(p for p in site.rglob("*") if p.is_file()):
                zf.write(path, f"{PLUGIN}/help/{path.relative_to(site).as_posix()}")
    tmp.replace(target)
    return target


def install(zip_path: Path, profile: Path) -> Path:
    """Unpack into PROFILE/python/plugins and enable it in PROFILE/QGIS/QGIS3.ini (what Install from ZIP does)."""
    plugins = profile / "python" / "plugins"
    plugins.mkdir(parents=True, exist_ok=True)
    if (plugins / PLUGIN).exists():
        shutil.rmtree(plugins / PLUGIN)
    with zipfile.ZipFile(zip_path) as zf:
        zf.extractall(plugins)
    ini = profile / "QGIS" / "QGIS3.ini"
    ini.parent.mkdir(parents=True, exist_ok=True)
    cfg = configparser.RawConfigParser()
    cfg.optionxform = str
    if ini.exists():
        cfg.read(ini)
    if not cfg.has_section("PythonPlugins"):
        cfg.add_section("PythonPlugins")
    cfg.set("PythonPlugins", PLUGIN, "true")
    with ini.open("w") as f:
        cfg.write(f, space_around_delimiters=False)
    return plugins / PLUGIN


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dist", type=Path, default=ROOT / "dist", help="where the zip goes (default dist/)")
    ap.add_argument("--install", type=Path, metavar="PROFILE_DIR", help="also install into this QGIS profile folder")
    ap.add_argument("--wheels", type=Path, metavar="DIR",
                    help="also ship the gistools wheels of this folder (a release's per-platform wheels)")
    args = ap.parse_args(argv)
    zip_path = build(args.dist, args.wheels)
    print(zip_path)
    if args.install:
        print(install(zip_path, args.install))
    return 0


if __name__ == "__main__":
    sys.exit(main())
