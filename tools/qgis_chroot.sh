#!/usr/bin/env bash
# A Debian forky chroot holding today's QGIS LTR (3.44, Python 3.14), for the tests that need a newer QGIS than
# Debian 12's 3.22 (virtual point clouds, COPC layers). Needs root; about 2 minutes and 900 MB once.
#   bash tools/qgis_chroot.sh [DIR]      (default /var/tmp/gistools-qgis-forky; prints DIR when ready)
set -euo pipefail
DIR=${1:-/var/tmp/gistools-qgis-forky}
ready() { [ -x "$DIR/usr/bin/python3" ] && [ -f "$DIR/.gistools-qgis-ready" ]; }
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
rm -rf "$DIR"
mkdir -p "$DIR"
touch "$DIR/.gistools-qgis-chroot"
debootstrap --variant=minbase forky "$DIR" "$MIRROR" "$SCRIPT" >/dev/null
mount -t proc proc "$DIR/proc"
trap 'umount "$DIR/proc" 2>/dev/null || true' EXIT
chroot "$DIR" apt-get -o Acquire::Check-Valid-Until=false update -qq
chroot "$DIR" env DEBIAN_FRONTEND=noninteractive apt-get -o Acquire::Check-Valid-Until=false install -y -qq \
  --no-install-recommends python3-qgis qgis-providers >/dev/null
touch "$DIR/.gistools-qgis-ready"
echo "$DIR"
