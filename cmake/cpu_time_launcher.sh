#!/usr/bin/env bash
# Compiler and linker launcher (deploy/run.sh sets it before ccache): runs the
# step and appends "<CPU seconds (user+sys)> <wall seconds> <output file>" to
# $HEMM_CPU_LOG, so the build's cost per target can be read in CPU seconds,
# which the machine's other load changes less than wall time (on a loaded
# shared VM one compile's CPU seconds varied up to 4x, its wall time 13x).
out=""; prev=""
for a in "$@"; do
  [[ "$prev" == "-o" ]] && out="$a"
  prev="$a"
done
if [[ -z "${HEMM_CPU_LOG:-}" || ! -x /usr/bin/time ]]; then exec "$@"; fi
tf="$(mktemp)"
/usr/bin/time -f "%U %S %e" -o "$tf" "$@"
rc=$?
read -r u s e <"$tf" || true
rm -f "$tf"
[[ "$u" =~ ^[0-9.]+$ && "$s" =~ ^[0-9.]+$ ]] &&
  awk -v u="$u" -v s="$s" -v e="$e" -v o="$out" 'BEGIN { printf "%.2f %s %s\n", u + s, e, o }' >>"$HEMM_CPU_LOG"
exit $rc
