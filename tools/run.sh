#!/usr/bin/env bash
# One entry point for the README's two commands, and for CI.
#   bash tools/run.sh sample   set up .venv, run the main job on sample_tiles/ into out/
#   bash tools/run.sh test     set up .venv, run the whole test suite
# Works on a fresh Debian 12 from a clean clone (installs python3-venv when it is missing).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
VENV="$ROOT/.venv"
# Debian's system Python, so that QGIS's bindings (python3-qgis) are importable in the same venv.
PY=/usr/bin/python3
[ -x "$PY" ] || PY=$(command -v python3)

need_apt=()
"$PY" -c "import venv, ensurepip" 2>/dev/null || need_apt+=(python3-venv)
if [ ${#need_apt[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    echo "gistools setup: installing ${need_apt[*]} (apt-get)"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
  else
    echo "gistools setup: missing ${need_apt[*]}; run: sudo apt-get install ${need_apt[*]}" >&2
    exit 1
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "gistools setup: creating $VENV"
  "$PY" -m venv --system-site-packages "$VENV"
fi
STAMP="$VENV/.gistools-installed"
WANT=$(cat pyproject.toml | sha256sum | cut -c1-16)
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
  echo "gistools setup: installing gistools and its dependencies into $VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/python" -m pip install -q -e ".[test,plot]" 2>&1 | grep -v "^WARNING: Location" || true
  "$VENV/bin/python" -c "import gistools, laspy, lazrs, rasterio, triangle"
  # Debian's python3-matplotlib (pulled in by qgis) registers mpl_toolkits from /usr/lib/python3 at start-up (its
  # nspkg.pth), which hides the venv's mpl_toolkits.mplot3d; importing it first from the venv's own .pth fixes the order.
  SITE=$("$VENV/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
  echo 'import importlib.util as u; u.find_spec("mpl_toolkits") and __import__("mpl_toolkits")' > "$SITE/00-gistools-mpl-toolkits.pth"
  echo "$WANT" > "$STAMP"
fi

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
    "$VENV/bin/python" -m pytest "$@"
    rc=$?
    set -e
    if [ $rc -eq 5 ]; then echo "no tests were collected" >&2; exit 1; fi
    exit $rc
    ;;
  *)
    echo "usage: bash tools/run.sh sample|test [args...]" >&2
    exit 2
    ;;
esac
