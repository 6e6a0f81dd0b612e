#!/usr/bin/env bash
# Fetch Leaflet's dist files from the pinned npm package into gistools/web/vendor/ (checked by its sha256).
set -euo pipefail
cd "$(dirname "$0")/.."
VERSION=1.9.4
SHA=84c65a256e50657896f54c33bd857b6849ebe94c817803be818bf32a3dde0b77
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && npm pack "leaflet@$VERSION" >/dev/null)
echo "$SHA  $tmp/leaflet-$VERSION.tgz" | sha256sum -c -
tar xzf "$tmp/leaflet-$VERSION.tgz" -C "$tmp"
cp "$tmp/package/dist/leaflet.js" "$tmp/package/dist/leaflet.css" gistools/web/vendor/
cp "$tmp/package/LICENSE" gistools/web/vendor/LICENSE-leaflet
echo "gistools/web/vendor: leaflet $VERSION"
