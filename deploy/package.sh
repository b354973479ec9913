#!/usr/bin/env bash
# Builds the Debian package of hemm from a build tree (cpack -G DEB: the
# installed tree of docs/install.md under /usr, its Depends computed by
# dpkg-shlibdeps from the binaries' shared libraries) and shows it:
# `dpkg -I` (the control fields) and the start of `dpkg -c` (the files).
# Usage: deploy/package.sh [BUILD_DIR]   (default: build/release; run
#   `bash deploy/run.sh build` first). The .deb is left in BUILD_DIR/package/.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$(cd "${1:-$root/build/release}" 2>/dev/null && pwd)" || {
  echo "package: no build directory ${1:-$root/build/release} (bash deploy/run.sh build)" >&2; exit 2; }
[[ -f "$build/CPackConfig.cmake" ]] || { echo "package: $build is not a configured hemm build" >&2; exit 2; }
command -v dpkg-shlibdeps >/dev/null || { echo "package: needs dpkg-shlibdeps (Debian package dpkg-dev)" >&2; exit 2; }
echo "== building what is out of date in $build"
cmake --build "$build" -j "${HEMM_JOBS:-$(nproc)}" >/dev/null
out="$build/package"
rm -rf "$out"
mkdir -p "$out"
echo "== cpack -G DEB"
t0=$SECONDS
cpack --config "$build/CPackConfig.cmake" -G DEB -B "$out" >"$out/cpack.log" 2>&1 || {
  tail -n 40 "$out/cpack.log" >&2; exit 1; }
deb="$(ls "$out"/hemm_*.deb)"
echo "== $deb ($(du -h "$deb" | cut -f1), $((SECONDS - t0)) s)"
echo "== dpkg -I"
dpkg -I "$deb"
echo "== dpkg -c | head -n 40"
dpkg -c "$deb" | head -n 40 || true
