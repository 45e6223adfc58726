#!/usr/bin/env bash
# Fetches the C library of the gsd package, which writes HOOMD-blue's GSD trajectories
# (`[output] format = "gsd"`; gsd/gsd.c, gsd/gsd.h and its LICENSE, BSD-2-Clause), from its pinned
# source distribution on PyPI, checks the SHA-256, and unpacks those three files outside the
# repository, where cmake/RpyfmmGsd.cmake finds them:
#   $RPYFMM_GSD_SOURCE_DIR if set, else /usr/local/src/gsd-<version> as root,
#   else ${XDG_CACHE_HOME:-$HOME/.cache}/rpyfmm/gsd-<version>.
# RPYFMM_GSD_TARBALL=<path> uses a local copy of the sdist instead of downloading (offline).
# Called by scripts/install-deps.sh. Idempotent (nothing is fetched when the files are there) and
# never fatal: offline, or on a checksum mismatch, it says so and the build goes on without GSD.
set -uo pipefail
version=5.0.1
sha256=c072d1ee934864d618039f3e7448bc79f31fe1a0f1fabfdb9cd4143a7ab2376b
url=https://files.pythonhosted.org/packages/22/16/b5298275654ab1da04e6283e6274fa9751ea0d5be36933c4e37502fda4a4/gsd-$version.tar.gz

if [ -n "${RPYFMM_GSD_SOURCE_DIR:-}" ]; then
  places=("$RPYFMM_GSD_SOURCE_DIR")
elif [ "$(id -u)" -eq 0 ]; then
  places=("/usr/local/src/gsd-$version")
else
  places=("${XDG_CACHE_HOME:-$HOME/.cache}/rpyfmm/gsd-$version" "/usr/local/src/gsd-$version")
fi
for place in "${places[@]}"; do  # already there (a root install serves every user)
  if [ -f "$place/gsd/gsd.c" ] && [ -f "$place/gsd/gsd.h" ]; then exit 0; fi
done
dest=${places[0]}

skip() {
  echo "fetch-gsd: $1; building without GSD trajectories (set RPYFMM_GSD_TARBALL to a copy of" \
       "gsd-$version.tar.gz, or RPYFMM_GSD_SOURCE_DIR, and run this script again)" >&2
  exit 0
}

if [ -e "$dest" ] && [ -n "$(ls -A "$dest" 2>/dev/null)" ]; then skip "$dest exists without gsd/gsd.c"; fi
mkdir -p "$(dirname "$dest")" || skip "cannot create $(dirname "$dest")"
work=$(mktemp -d "$(dirname "$dest")/.gsd-$version.XXXXXX") || skip "cannot write to $(dirname "$dest")"
trap 'rm -rf "$work"' EXIT
tarball=$work/gsd-$version.tar.gz
if [ -n "${RPYFMM_GSD_TARBALL:-}" ]; then
  cp "$RPYFMM_GSD_TARBALL" "$tarball" || skip "cannot read $RPYFMM_GSD_TARBALL"
elif command -v curl >/dev/null; then
  curl -fsSL --retry 2 --connect-timeout 20 --max-time 300 -o "$tarball" "$url" || skip "cannot download $url"
elif command -v python3 >/dev/null; then
  python3 -c 'import sys, urllib.request; urllib.request.urlretrieve(sys.argv[1], sys.argv[2])' "$url" "$tarball" \
    2>/dev/null || skip "cannot download $url"
else
  skip "neither curl nor python3 is there to download $url"
fi
echo "$sha256  $tarball" | sha256sum --check --status || skip "gsd-$version.tar.gz does not have the expected SHA-256"
tar --no-same-owner -xzf "$tarball" -C "$work" "gsd-$version/gsd/gsd.c" "gsd-$version/gsd/gsd.h" "gsd-$version/LICENSE" ||
  skip "cannot unpack gsd-$version.tar.gz"
echo "$sha256" > "$work/gsd-$version/.sha256"  # which sdist the files came from
chmod -R a+rX "$work/gsd-$version"
rmdir "$dest" 2>/dev/null
mv -T "$work/gsd-$version" "$dest" || skip "cannot move the sources to $dest"
echo "fetch-gsd: gsd $version C library sources in $dest"
