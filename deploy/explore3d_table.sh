#!/usr/bin/env bash
# The 6-DoF exploration's per-feature table over scenes, round trips and
# variants (issue 24), SIMULATION ONLY truth: runs deploy/explore3d.sh for
# each scene and variant (each run covers every round trip) and writes one
# Markdown table: per scene a row for each feature of its route (from the
# scene file's header) and one for the whole run; per round trip and variant
# a column; each cell "RMS force error N of the true peak N (its share of
# the peak)" over the feature's contact ticks (the whole run: over all of
# them).
#
# A variant is a labelled set of arguments for explore3d.sh's stations:
#   --variant LABEL  starts one (its label heads its columns, e.g. "camera
#                    fixed, completion off"); the options after it, up to the
#                    next --variant, are its own:
#   --operator-arg ARG, --robot-arg ARG   one more argument for hemm-operator /
#                    hemm-robot (repeat them: --operator-arg --shape-completion
#                    --operator-arg on)
#   --operator-config FILE, --robot-config FILE   instead of the shipped ones
# Without --variant: one variant, "main", with the shipped configs as they are.
#
# Usage: deploy/explore3d_table.sh BUILD_DIR [--scenes home,table_round,table_mixed] [--rtts 0,300] [--out DIR] [--port-base P] [--variant LABEL [--operator-arg ARG]... [--robot-arg ARG]... [--operator-config FILE] [--robot-config FILE]]...
# Writes DIR/table.md (and prints it), the runs under DIR/<scene>/<variant n>/
# (explore3d.sh's --out: route.txt, <rtt>ms/...); DIR default out/explore3d_table.
# Takes about 2-2.5 min per scene, round trip and variant (the route, then the truth replay).
set -euo pipefail

usage() { sed -n '/^# Usage:/,/^# Takes/p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
build="${1:-}"
if [[ -z "$build" || "$build" == -h || "$build" == --help ]]; then usage; [[ -n "$build" ]] && exit 0 || exit 2; fi
shift
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
scenes="home,table_round,table_mixed"
rtts="0,300"
out="$root/out/explore3d_table"
base=47300
labels=()   # one per variant
vargs=()    # per variant: its explore3d.sh arguments, one string of NUL-free words joined by \x1f
cur=-1
add() {  # append explore3d.sh arguments to the current variant
  ((cur >= 0)) || { echo "explore3d_table: '$1' before any --variant" >&2; exit 2; }
  local w
  for w in "$@"; do vargs[cur]+="$w"$'\x1f'; done
}
while (($#)); do
  case "$1" in
    --scenes) scenes="${2:?--scenes needs a list}"; shift 2 ;;
    --rtts) rtts="${2:?--rtts needs a list}"; shift 2 ;;
    --out) out="${2:?--out needs a directory}"; shift 2 ;;
    --port-base) base="${2:?--port-base needs a port}"; shift 2 ;;
    --variant)
      v="${2:?--variant needs a label}"
      [[ "$v" != *"|"* && "$v" != *"="* ]] || { echo "explore3d_table: --variant '$v': no '|' or '=' in a label" >&2; exit 2; }
      for l in "${labels[@]}"; do [[ "$l" != "$v" ]] || { echo "explore3d_table: --variant '$v' given twice" >&2; exit 2; }; done
      labels+=("$v"); cur=$((cur + 1)); vargs[cur]=""; shift 2 ;;
    --operator-arg|--robot-arg|--operator-config|--robot-config)
      (($# >= 2)) || { echo "explore3d_table: $1 needs a value" >&2; exit 2; }
      add "$1" "$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "explore3d_table: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
if ((${#labels[@]} == 0)); then labels=(main); vargs=(""); fi
for s in ${scenes//,/ }; do
  [[ "$s" =~ ^[a-z0-9_]+$ && -f "$root/deploy/scenes/$s.xml" ]] \
    || { echo "explore3d_table: --scenes: no scene '$s' (deploy/scenes/NAME.xml)" >&2; exit 2; }
done
for r in ${rtts//,/ }; do
  [[ "$r" =~ ^[0-9]+$ ]] || { echo "explore3d_table: --rtts '$rtts': round trips are whole milliseconds" >&2; exit 2; }
done
mkdir -p "$out"
out="$(cd "$out" && pwd)"

runs=()
for s in ${scenes//,/ }; do
  for i in "${!labels[@]}"; do
    dir="$out/$s/variant$i"
    mkdir -p "$out/$s"
    IFS=$'\x1f' read -r -a extra <<<"${vargs[i]}" || true
    echo "explore3d_table: scene $s, variant '${labels[i]}' -> $dir" >&2
    "$root/deploy/explore3d.sh" "$build" --scene "$s" --rtts "$rtts" --out "$dir" --doc "$dir" --port-base "$base" \
      --no-plots --label "${labels[i]}" "${extra[@]}" >"$dir.txt" 2>"$dir.log" \
      || { tail -n 20 "$dir.log" >&2; echo "explore3d_table: explore3d.sh failed for $s, '${labels[i]}' ($dir.log)" >&2; exit 1; }
    for r in ${rtts//,/ }; do runs+=(--run "$s|${labels[i]}|$r=$dir"); done
  done
done
/usr/bin/python3 "$root/deploy/report_tables.py" explore3d-table "${runs[@]}" >"$out/table.md"
cat "$out/table.md"
echo "explore3d_table: wrote $out/table.md" >&2
