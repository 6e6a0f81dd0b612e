#!/usr/bin/env bash
# A Debian forky chroot holding today's QGIS LTR (3.44, Python 3.14), for the tests that need a newer QGIS than
# Debian 12's 3.22 (virtual point clouds, COPC layers) and for the plugin's tests on 3.44: QGIS, qgis_process, the
# GDAL / PROJ / GEOS bound Python packages from Debian (built against the libraries QGIS links), and a venv
# /opt/gistools-venv (system site packages) with what Debian lacks (lazrs). Needs root; about 4 minutes and 1.5 GB once.
#   bash tools/qgis_chroot.sh [DIR]      (default /var/tmp/gistools-qgis-forky; prints DIR when ready)
#   bash tools/qgis_chroot.sh --bare [DIR]
#                                        (default /var/tmp/gistools-qgis-forky-bare): QGIS as a user has it from apt,
#                                        with pip and nothing for gistools (the plugin's installer's test)
set -euo pipefail
BARE=
if [ "${1:-}" = --bare ]; then BARE=1; shift; fi
DIR=${1:-/var/tmp/gistools-qgis-forky${BARE:+-bare}}
STAGE=8${BARE:+-bare}  # what a ready chroot holds (4: trimesh, for gistools:scene; 5: cffi, the kernel's binding; 6: mkdocs, the plugin's help pages; 7: mkdocstrings, their API page; 8: nginx, the service of the docs' area route); a chroot of an earlier stage is completed, not rebuilt
ready() { [ -x "$DIR/usr/bin/python3" ] && [ "$(cat "$DIR/.gistools-qgis-ready" 2>/dev/null)" = "$STAGE" ]; }
if ready; then echo "$DIR"; exit 0; fi
[ "$(id -u)" = 0 ] || { echo "qgis_chroot: needs root (debootstrap, chroot)" >&2; exit 1; }
command -v debootstrap >/dev/null || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap >/dev/null; }
# the mirror the machine's apt uses (deb822 sources, else a one-line sources.list)
MIRROR=$(awk '/^URIs:/{print $2; exit}' /etc/apt/sources.list.d/*.sources 2>/dev/null || true)
[ -n "$MIRROR" ] || MIRROR=$(awk '$1=="deb"{print $2; exit}' /etc/apt/sources.list 2>/dev/null || true)
MIRROR=${MIRROR:-http://deb.debian.org/debian}
SCRIPT=/usr/share/debootstrap/scripts/forky
[ -e "$SCRIPT" ] || SCRIPT=/usr/share/debootstrap/scripts/sid  # Debian 12's debootstrap predates forky
# only a folder this script made (its mark inside) or an empty one is (re)built: never a user's folder
if [ -e "$DIR" ] && [ -n "$(ls -A "$DIR" 2>/dev/null)" ] && [ ! -f "$DIR/.gistools-qgis-chroot" ]; then
  echo "qgis_chroot: $DIR exists and was not made by gistools; choose another folder (GISTOOLS_QGIS_CHROOT)" >&2
  exit 1
fi
mountpoint -q "$DIR/proc" 2>/dev/null && umount "$DIR/proc"
if [ ! -f "$DIR/.gistools-qgis-ready" ]; then  # no finished chroot of any stage: from scratch
  rm -rf "$DIR"
  mkdir -p "$DIR"
  touch "$DIR/.gistools-qgis-chroot"
  debootstrap --variant=minbase forky "$DIR" "$MIRROR" "$SCRIPT" >/dev/null
fi
mount -t proc proc "$DIR/proc"
trap 'umount "$DIR/proc" 2>/dev/null || true' EXIT
APT=(apt-get -o Acquire::Check-Valid-Until=false)
chroot "$DIR" "${APT[@]}" update -qq
if [ -n "$BARE" ]; then
  # QGIS from apt (its Python brings numpy, pyproj, matplotlib, GDAL's bindings) and pip: nothing else
  chroot "$DIR" env DEBIAN_FRONTEND=noninteractive "${APT[@]}" install -y -qq --no-install-recommends \
    python3-qgis qgis-providers qgis python3-pip ca-certificates >/dev/null
else
chroot "$DIR" env DEBIAN_FRONTEND=noninteractive "${APT[@]}" install -y -qq --no-install-recommends \
  python3-qgis qgis-providers qgis python3-venv python3-pip python3-setuptools python3-dev gcc \
  python3-numpy python3-cffi python3-scipy python3-rasterio python3-pyogrio python3-geopandas python3-pyproj python3-shapely \
  python3-laspy python3-matplotlib python3-click python3-tqdm python3-threadpoolctl python3-pytest proj-bin \
  nginx-light >/dev/null  # nginx: the area route of the docs reads a service on loopback
fi
# pip inside: the host's own CAs (a proxy's) added to the chroot's store, so that pip (and its truststore) trusts
# what the host trusts; else the host's whole bundle in place of the chroot's
if ls /usr/local/share/ca-certificates/*.crt >/dev/null 2>&1; then
  cp /usr/local/share/ca-certificates/*.crt "$DIR/usr/local/share/ca-certificates/"
  chroot "$DIR" update-ca-certificates >/dev/null 2>&1
else
  cp "${SSL_CERT_FILE:-/etc/ssl/certs/ca-certificates.crt}" "$DIR/etc/ssl/certs/ca-certificates.crt"
fi
if [ -z "$BARE" ]; then
[ -x "$DIR/opt/gistools-venv/bin/python" ] || chroot "$DIR" python3 -m venv --system-site-packages /opt/gistools-venv
# the host's PIP_* settings name host paths: not inside
chroot "$DIR" env -u PIP_CONSTRAINT -u PIP_FIND_LINKS PIP_CERT=/etc/ssl/certs/ca-certificates.crt \
  /opt/gistools-venv/bin/python -m pip install -q --disable-pip-version-check lazrs trimesh mkdocs mkdocs-material "mkdocstrings[python]"
fi
echo "$STAGE" > "$DIR/.gistools-qgis-ready"
echo "$DIR"
