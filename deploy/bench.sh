#!/usr/bin/env bash
# Runs every benchmark binary of a release build (tests/bench/*), one after
# the other, and saves their output under out/bench/.
# Usage: deploy/bench.sh BUILD_DIR [benchmark-name-filter]
set -euo pipefail
build="${1:?usage: deploy/bench.sh BUILD_DIR [filter]}"
filter="${2:-}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/out/bench"
mkdir -p "$out"
shopt -s nullglob
ran=0
for b in "$build"/bin/bench/*; do
  name="$(basename "$b")"
  [[ -n "$filter" && "$name" != *"$filter"* ]] && continue
  echo "== $name"
  "$b" 2>&1 | tee "$out/$name.txt"
  ran=$((ran + 1))
done
# The VPS speed-against-error report (1M-triangle scene, two tools, FCL side by side).
if [[ -z "$filter" || "vps-report" == *"$filter"* ]] && [[ -x "$build/bin/hemm-vps" ]]; then
  echo "== hemm-vps report"
  "$build/bin/hemm-vps" report 2>&1 | tee "$out/hemm-vps-report.txt"
  ran=$((ran + 1))
fi
echo "== $ran benchmark(s); output in $out"
