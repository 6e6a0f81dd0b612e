#!/usr/bin/env bash
# One entry point for the README's two commands, and for CI.
#   bash tools/run.sh sample   set up .venv, run the main job on sample_tiles/ into out/
#   bash tools/run.sh test     set up .venv, run the whole test suite
# Works on a fresh Debian 12 from a clean clone (installs what it needs with apt-get when run as root).
#
# The GDAL / PROJ / GEOS bound packages (rasterio, pyogrio, pyproj, shapely) are built against the
# system's libraries, not taken as binary wheels: QGIS links those system libraries, and a wheel's own
# copy of PROJ or GDAL in the same process is interposed by them (qgis_process then aborts on exit with
# "free(): invalid pointer"). One copy of each library makes the venv safe inside QGIS too.
# GISTOOLS_BINARY_WHEELS=1 skips that (faster set-up, but not for use inside QGIS).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
VENV="$ROOT/.venv"
# Debian's system Python, so that QGIS's bindings (python3-qgis) are importable in the same venv.
PY=/usr/bin/python3
[ -x "$PY" ] || PY=$(command -v python3)

need_apt=()
"$PY" -c "import venv, ensurepip" 2>/dev/null || need_apt+=(python3-venv)
WHEELS=${GISTOOLS_BINARY_WHEELS:-0}
if [ "$WHEELS" != 1 ]; then
  command -v gdal-config >/dev/null || need_apt+=(libgdal-dev)
  pkg-config --exists proj 2>/dev/null || need_apt+=(libproj-dev)
  command -v geos-config >/dev/null || need_apt+=(libgeos-dev)
  command -v proj >/dev/null || need_apt+=(proj-bin)  # lets a venv's pyproj find /usr/share/proj
  [ -f "/usr/include/python3.11/Python.h" ] || "$PY" -c "import sysconfig,os,sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()['include'],'Python.h')))" || need_apt+=(python3-dev)
  command -v g++ >/dev/null || need_apt+=(build-essential)
  command -v pkg-config >/dev/null || need_apt+=(pkg-config)
fi
if [ "${1:-}" = test ]; then
  # the QGIS plugin's tests run in a real headless QGIS (Debian's 3.22 LTR), and call its qgis_process
  QT_QPA_PLATFORM=offscreen "$PY" -c "import qgis.core" 2>/dev/null || need_apt+=(python3-qgis)
  [ -x /usr/bin/qgis_process.bin ] || need_apt+=(qgis)
  command -v chromium >/dev/null || need_apt+=(chromium)  # the web map tests render the page in headless Chromium
  command -v pdftoppm >/dev/null || need_apt+=(poppler-utils)  # the map book test renders its pages
  command -v nginx >/dev/null || [ -x /usr/sbin/nginx ] || need_apt+=(nginx-light)  # serves point clouds by range
  command -v x86_64-w64-mingw32-gcc >/dev/null || need_apt+=(gcc-mingw-w64-x86-64)  # the kernel's Windows build is checked
  # ... and run under Wine (Debian 12's wine64 package puts its loader in /usr/lib/wine, off the PATH)
  command -v wine64 >/dev/null || [ -x /usr/lib/wine/wine64 ] || need_apt+=(wine64)
  command -v clang >/dev/null || need_apt+=(clang)  # ... and compiled in MSVC's dialect (clang --driver-mode=cl)
fi
if [ ${#need_apt[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    echo "gistools setup: installing ${need_apt[*]} (apt-get)"
    apt-get update -qq  # (on its own line: set -e does not stop on the left side of &&)
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
  else
    echo "gistools setup: missing ${need_apt[*]}; run: sudo apt-get install --no-install-recommends ${need_apt[*]}" >&2
    exit 1
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "gistools setup: creating $VENV"
  "$PY" -m venv --system-site-packages "$VENV"
fi
# Debian 12's system Python beside its QGIS 3.22 needs numpy 1 and affine 2 (tools/constraints-debian12.txt says why);
# no other platform gets those pins
if grep -q '^12' /etc/debian_version 2>/dev/null && [ "$PY" = /usr/bin/python3 ]; then
  export PIP_CONSTRAINT="$ROOT/tools/constraints-debian12.txt"
fi
STAMP="$VENV/.gistools-installed"
WANT=$( (cat pyproject.toml setup.py csrc/*.h csrc/*.c csrc/*.py tools/constraints-debian12.txt; echo "wheels=$WHEELS") | sha256sum | cut -c1-16)  # a changed kernel is rebuilt
pipq() {  # pip install, quiet on success, the whole log on failure
  local log; log=$(mktemp)
  if ! "$VENV/bin/python" -m pip install -q "$@" >"$log" 2>&1; then cat "$log" >&2; rm -f "$log"; return 1; fi
  grep -v "^WARNING: Location\|^DEPRECATION: --no-binary\|^$" "$log" || true; rm -f "$log"
}
system_libs_only() {  # one GDAL / PROJ / GEOS in the process: the system's
  "$VENV/bin/python" - <<'PYEOF'
import subprocess as sp, sys
import pyogrio, pyproj, rasterio, shapely
gdal = sp.check_output(["gdal-config", "--version"], text=True).strip()
proj = sp.check_output(["pkg-config", "--modversion", "proj"], text=True).strip()
geos = sp.check_output(["geos-config", "--version"], text=True).strip()
got = (rasterio.__gdal_version__, pyogrio.__gdal_version_string__, pyproj.proj_version_str, shapely.geos_version_string)
if got != (gdal, gdal, proj, geos):
    print(f"built against GDAL/GDAL/PROJ/GEOS {got}; the system has {gdal}, {proj}, {geos}", file=sys.stderr)
    sys.exit(1)
pyproj.CRS(2882)
PYEOF
}
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
  echo "gistools setup: installing gistools and its dependencies into $VENV"
  rm -f gistools/_kernel.cpython-*.so  # an earlier in-place build (before the abi3 kernel) would be imported first
  pipq --upgrade pip
  if [ "$WHEELS" != 1 ]; then
    echo "gistools setup: building rasterio, pyogrio, pyproj, shapely against the system GDAL $(gdal-config --version), PROJ $(pkg-config --modversion proj), GEOS $(geos-config --version) (a few minutes, once)"
    # pyproj 3.7 needs PROJ >= 9.2 (Debian 12 has 9.1); 3.6 must be compiled with Cython < 3.1 (pyproj issue #1451)
    PYPROJ="pyproj>=3.5"
    pkg-config --atleast-version=9.2 proj || PYPROJ="pyproj>=3.5,<3.7"
    pipq "cython<3.1" setuptools wheel numpy
    PIP_NO_BINARY=pyproj pipq --no-cache-dir --no-build-isolation "$PYPROJ"
    export PIP_NO_BINARY=rasterio,pyogrio,shapely
  fi
  pipq -e ".[test,plot]"
  unset PIP_NO_BINARY
  "$VENV/bin/python" -c "import gistools, laspy, lazrs, rasterio, triangle, pyogrio, pyproj, shapely"
  if [ "$WHEELS" != 1 ] && ! system_libs_only; then  # a venv made before: replace its binary wheels once
    PIP_NO_BINARY=pyproj pipq --no-cache-dir --force-reinstall --no-deps --no-build-isolation "$PYPROJ"
    PIP_NO_BINARY=rasterio,pyogrio,shapely pipq --force-reinstall --no-deps rasterio pyogrio shapely
    system_libs_only || { echo "gistools setup: rasterio / pyogrio / pyproj / shapely do not use the system libraries" >&2; exit 1; }
  fi
  # Debian's python3-matplotlib (pulled in by qgis) registers mpl_toolkits from /usr/lib/python3 at start-up (its
  # nspkg.pth), which hides the venv's mpl_toolkits.mplot3d; importing it first from the venv's own .pth fixes the order.
  SITE=$("$VENV/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
  echo 'import importlib.util as u; u.find_spec("mpl_toolkits") and __import__("mpl_toolkits")' > "$SITE/00-gistools-mpl-toolkits.pth"
  echo "$WANT" > "$STAMP"
fi

# The pip route, as most users install: a venv without system packages, `pip install .` with the newest binary
# wheels of every dependency (numpy 2), then the whole suite but what needs QGIS in the process (those tests skip
# there: QGIS's bindings are Debian's), the pip-route install tests (they make such venvs themselves) and the
# QGIS 3.44 chroot's (Debian's route). GISTOOLS_ROUTE=wheels tells the documentation's test which blocks are this
# route's.
route_wheels() {
  local V="$ROOT/.venv-wheels" want
  want=$( (cat pyproject.toml setup.py csrc/*.h csrc/*.c csrc/*.py; date +%Y-%m-%d) | sha256sum | cut -c1-16)  # newest: daily
  [ -x "$V/bin/python" ] || "$PY" -m venv "$V" || return 1
  if [ "$(cat "$V/.gistools-installed" 2>/dev/null)" != "$want" ]; then
    echo "gistools setup: the pip route's venv $V (the newest binary wheels)"
    env -u PIP_CONSTRAINT -u PIP_NO_BINARY "$V/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip \
      || return 1
    env -u PIP_CONSTRAINT -u PIP_NO_BINARY "$V/bin/python" -m pip install -q --disable-pip-version-check --upgrade \
      --upgrade-strategy eager --only-binary :all: --no-binary gistools ".[test]" 2>&1 | grep -v "^WARNING: Location" \
      || true
    "$V/bin/python" -c "import gistools, numpy, matplotlib, trimesh" || return 1
    echo "$want" > "$V/.gistools-installed"
  fi
  env -u PIP_CONSTRAINT GISTOOLS_ROUTE=wheels "$V/bin/python" -m pytest -p no:cacheprovider \
    --ignore=tests/test_install.py --ignore=tests/test_qgis_today.py
}

case "${1:-}" in
  sample)
    shift
    B=sample_tiles/breaklines.gpkg
    "$VENV/bin/gistools" shrub sample_tiles --out out --roads "$B:ROADBREAKLINE" --hydro "$B:HYDROGRAPHICFEATURE" \
      --waterbodies "$B:WATERBODY" --wetlands "$B:WETLAND" --tile-index "$B:FOOTPRINT" "$@"
    echo "outputs in $ROOT/out: shrub_map.png / .pdf, shrub_classes.gpkg, rasters (dsm/ dem/ ndsm/ bands/ veg/ cover/ classes/ ...), report.json"
    ;;
  test)
    shift
    set +e
    export QT_QPA_PLATFORM=${QT_QPA_PLATFORM:-offscreen}
    started=$(date +%s)
    "$VENV/bin/python" -m pytest "$@"
    rc=$?
    echo "gistools tests, Debian route (.venv, numpy $("$VENV/bin/python" -c 'import numpy; print(numpy.__version__)')): $(( $(date +%s) - started )) s, status $rc"
    if [ $rc -eq 5 ]; then echo "no tests were collected" >&2; exit 1; fi
    wheels=0
    if [ -z "${GISTOOLS_ONE_ROUTE:-}" ] && [ $# -eq 0 ]; then  # the whole suite: every route a user takes
      started=$(date +%s)
      route_wheels
      wheels=$?
      echo "gistools tests, pip route (.venv-wheels, the newest binary wheels): $(( $(date +%s) - started )) s, status $wheels"
    fi
    set -e
    [ $rc -eq 0 ] && [ $wheels -eq 0 ]
    exit $?
    ;;
  *)
    echo "usage: bash tools/run.sh sample|test [args...]" >&2
    exit 2
    ;;
esac
