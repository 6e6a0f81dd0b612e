"""Build the QGIS plugin zip (Plugins > Manage and Install Plugins > Install from ZIP), and optionally install it.

    python tools/build_plugin.py                       # -> dist/gistools_qgis-<version>.zip
    python tools/build_plugin.py --install PROFILE_DIR # also unpack it into a QGIS profile and enable it

PROFILE_DIR is a QGIS profile folder, e.g. ~/.local/share/QGIS/QGIS3/profiles/default. The plugin folder
is named gistools_qgis (not gistools, which would hide the gistools library on QGIS's sys.path).
"""

from __future__ import annotations

import argparse
import configparser
import shutil
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


def metadata() -> str:
    """qgis_plugin/metadata.txt with version= set to the gistools version."""
    lines = (SOURCE / "metadata.txt").read_text().splitlines()
    return "\n".join(f"version={version()}" if line.startswith("version=") else line for line in lines) + "\n"


def build_site(into: Path) -> bool:
    """The documentation site (mkdocs.yml, docs/) built into ``into``, for the algorithms' Help buttons; False
    (with a note) where MkDocs is not installed (pip install mkdocs mkdocs-material)."""
    import subprocess

    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "-q", "-f", str(ROOT / "mkdocs.yml"), "-d", str(into)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"build_plugin: the help pages are left out (mkdocs: {(proc.stderr or proc.stdout).strip()[-300:]})",
              file=sys.stderr)
        return False
    return True


def build(dist: Path) -> Path:
    """The plugin zip: qgis_plugin/ as gistools_qgis/, its metadata given the gistools version, and the
    documentation site as gistools_qgis/help/ (each algorithm's Help opens its page there, offline)."""
    import tempfile

    dist.mkdir(parents=True, exist_ok=True)
    target = dist / f"{PLUGIN}-{version()}.zip"
    tmp = target.with_name(target.name + ".partial")
    with tempfile.TemporaryDirectory() as work, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(SOURCE.rglob("*")):
            if path.is_dir() or "__pycache__" in path.parts or path.suffix == ".pyc":
                continue
            name = f"{PLUGIN}/{path.relative_to(SOURCE).as_posix()}"
            if path == SOURCE / "metadata.txt":
                zf.writestr(name, metadata())
            else:
                zf.write(path, name)
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
    args = ap.parse_args(argv)
    zip_path = build(args.dist)
    print(zip_path)
    if args.install:
        print(install(zip_path, args.install))
    return 0


if __name__ == "__main__":
    sys.exit(main())
