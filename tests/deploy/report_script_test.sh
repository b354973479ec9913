#!/usr/bin/env bash
# deploy/report.sh end to end without running anything long: an imported
# real-time table (--rt-table) with the other sections marked missing, a
# second run that replaces only that section, and refusals of bad arguments
# that leave the document as it was. Usage: report_script_test.sh BUILD_DIR
set -euo pipefail
build="${1:?usage: report_script_test.sh BUILD_DIR}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
printf '# Real-time\n\ncommand: rt_table.sh\n\n| case | p99 us |\n|---|--:|\n| servo | 42 |\n' >"$tmp/rt1.md"
doc="$tmp/measurements.md"
bash "$root/deploy/report.sh" "$build" --only rt --rt-table "$tmp/rt1.md" --condition "test" --out "$doc" \
  --work "$tmp/w1" 2>/dev/null
grep -q '^| servo | 42 |$' "$doc" || fail "the imported table is not in the document"
grep -q '^command: rt_table.sh$' "$doc" || fail "the imported file's own text is not kept"
grep -q '^- condition: test$' "$doc" || fail "no condition line"
grep -q '^- machine: [0-9]* cores, .*, Linux ' "$doc" || fail "no machine line"
for s in latency accuracy explore3d vps vps-budget bimanual link rt-compile; do
  awk "/report.sh section: $s -->/,/report.sh end: $s -->/" "$doc" | grep -q '^\*Missing:\*' || fail "section $s not marked missing"
done
printf '| case | p99 us |\n|---|--:|\n| servo | 43 |\n' >"$tmp/rt2.md"
bash "$root/deploy/report.sh" "$build" --only rt --rt-table "$tmp/rt2.md" --condition "test" --out "$doc" \
  --work "$tmp/w2" 2>/dev/null
grep -q '^| servo | 43 |$' "$doc" && ! grep -q '^| servo | 42 |$' "$doc" || fail "the section was not replaced"
[[ "$(grep -c 'report.sh section:' "$doc")" == 9 ]] || fail "sections duplicated or lost"
cp "$doc" "$tmp/before.md"
for bad in "--only nope --condition x" "--only rt --condition x --rt-table $tmp/none.md" "--only rt" \
           "--only rt --condition x --rt-table $tmp/w1/section-rt.md.none"; do
  rc=0
  # shellcheck disable=SC2086
  bash "$root/deploy/report.sh" "$build" $bad --out "$doc" --work "$tmp/w3" >/dev/null 2>&1 || rc=$?
  ((rc == 2)) || fail "'$bad' exited $rc, expected 2"
done
printf 'no table here\n' >"$tmp/rt3.md"
rc=0
bash "$root/deploy/report.sh" "$build" --only rt --rt-table "$tmp/rt3.md" --condition x --out "$doc" --work "$tmp/w4" \
  >/dev/null 2>&1 || rc=$?
((rc != 0)) || fail "an rt file without a table was accepted"
cmp -s "$doc" "$tmp/before.md" || fail "a refused run changed the document"
echo "report.sh: import, replace and refusals ok"
