#!/usr/bin/env bash
# A fuzzing campaign (not part of CI): builds every libFuzzer target of the
# project (clang, ASan + UBSan; only the fuzz_* targets and what they need)
# and runs each for a set time, keeping each target's corpus and crash
# artifacts under out/fuzz/<target>/ so that campaigns build on each other.
# Prints one line per target (executions, exec/s, corpus size, crashes) and
# the total.
#
# Usage: deploy/fuzz.sh [--seconds S] [--jobs N] [--build DIR] [--only NAME]
#   --seconds S  time per target (default 600)
#   --jobs N     targets run side by side (default 1)
#   --build DIR  build directory (default build/fuzz; configured if missing)
#   --only NAME  run only targets whose name contains NAME
# Exit status: 0 if no target crashed, 1 otherwise (the crashing inputs are
# in out/fuzz/<target>/crashes/; reproduce with build/fuzz/bin/<target> FILE).
set -euo pipefail

seconds=600
jobs=1
only=""
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$root/build/fuzz"
usage() { sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds) seconds="${2:?}"; shift 2 ;;
    --jobs) jobs="${2:?}"; shift 2 ;;
    --build) build="${2:?}"; shift 2 ;;
    --only) only="${2:?}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "deploy/fuzz.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$seconds" =~ ^[0-9]+$ && "$seconds" -gt 0 ]] || { echo "deploy/fuzz.sh: --seconds must be a positive integer" >&2; exit 2; }
[[ "$jobs" =~ ^[0-9]+$ && "$jobs" -gt 0 ]] || { echo "deploy/fuzz.sh: --jobs must be a positive integer" >&2; exit 2; }

if [[ ! -f "$build/build.ninja" ]]; then
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DHEMM_SANITIZE=ON -DHEMM_FUZZ=ON -DHEMM_BENCH=OFF
fi
mapfile -t all_targets < <(ninja -C "$build" -t targets all | awk -F: '/^fuzz_[A-Za-z0-9_]+:/ {print $1}' | sort -u)
[[ ${#all_targets[@]} -gt 0 ]] || { echo "deploy/fuzz.sh: no fuzz_* targets in $build (HEMM_FUZZ off?)" >&2; exit 1; }
cmake --build "$build" -j"$jobs" --target "${all_targets[@]}"

out="$root/out/fuzz"
mkdir -p "$out"
shopt -s nullglob
targets=()
for name in "${all_targets[@]}"; do
  [[ -n "$only" && "$name" != *"$only"* ]] && continue
  targets+=("$name")
done
[[ ${#targets[@]} -gt 0 ]] || { echo "deploy/fuzz.sh: no fuzz targets in $build/bin" >&2; exit 1; }

run_one() {
  local name="$1" dir="$out/$1"
  mkdir -p "$dir/corpus" "$dir/crashes"
  # Crashes end the run early and leave crash-*/leak-*/timeout-* files in crashes/.
  "$build/bin/$name" "$dir/corpus" -max_total_time="$seconds" -print_final_stats=1 \
    -artifact_prefix="$dir/crashes/" -rss_limit_mb=2048 -timeout=10 > "$dir/log.txt" 2>&1 || true
}

echo "fuzzing ${#targets[@]} target(s) for ${seconds} s each, $jobs at a time; output in $out"
running=0
for name in "${targets[@]}"; do
  run_one "$name" &
  running=$((running + 1))
  if [[ $running -ge $jobs ]]; then
    wait -n
    running=$((running - 1))
  fi
done
wait

total=0
crashed=0
printf '%-28s %14s %10s %8s %8s\n' target executions exec/s corpus crashes
for name in "${targets[@]}"; do
  dir="$out/$name"
  runs="$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$dir/log.txt" | grep -Eo '[0-9]+$' | tail -1 || true)"
  rate="$(grep -Eo 'stat::average_exec_per_sec: *[0-9]+' "$dir/log.txt" | grep -Eo '[0-9]+$' | tail -1 || true)"
  corpus="$(find "$dir/corpus" -type f | wc -l)"
  crashes="$(find "$dir/crashes" -type f | wc -l)"
  printf '%-28s %14s %10s %8s %8s\n' "$name" "${runs:-?}" "${rate:-?}" "$corpus" "$crashes"
  total=$((total + ${runs:-0}))
  crashed=$((crashed + crashes))
done
printf '%-28s %14s\n' total "$total"
if [[ $crashed -gt 0 ]]; then
  echo "deploy/fuzz.sh: $crashed crashing input(s); see $out/*/crashes/ and $out/*/log.txt" >&2
  exit 1
fi
