#!/usr/bin/env bash
# Sums a build's CPU log (cmake/cpu_time_launcher.sh) by target family: the
# libraries and station binaries, the tests, the benchmarks, and the ten
# costliest targets. Usage: cmake/cpu_time_report.sh LOG
set -euo pipefail
log="${1:?usage: cmake/cpu_time_report.sh LOG}"
[[ -s "$log" ]] || { echo "== build CPU: nothing compiled or linked (log $log empty)"; exit 0; }
awk '
  # Objects: <dir>/CMakeFiles/<target>.dir/...; links: <dir>/<target> or bin/<target>.
  function target(o,   m) {
    if (match(o, /CMakeFiles\/[^\/]+\.dir\//)) return substr(o, RSTART + 11, RLENGTH - 16)
    sub(/.*\//, "", o); sub(/^lib/, "", o); sub(/\.(a|so)$/, "", o); return o
  }
  function family(o, t) {
    if (o ~ /(^|\/)tests\/bench\// || o ~ /(^|\/)bin\/bench\// || t ~ /_bench$/) return "benchmarks"
    if (o ~ /(^|\/)tests\// || t ~ /^hemm_test_/) return "tests"
    return ""
  }
  { cpu[NR] = $1; out[NR] = $3; t = target($3); tgt[NR] = t; f = family($3, t)
    if (f != "" && !(t in fam)) fam[t] = f
    link[NR] = ($3 !~ /\.o$/ && $3 !~ /\.gch$/) }
  END {
    for (i = 1; i <= NR; i++) {
      t = tgt[i]; f = (t in fam) ? fam[t] : "libraries and station binaries"
      kind = link[i] ? "link" : "compile"
      by[f " " kind] += cpu[i]; fsum[f] += cpu[i]; tsum[t] += cpu[i]; total += cpu[i]
      if (link[i]) links[f]++
    }
    printf "== build CPU seconds by family (%d steps)\n", NR
    for (f in fsum) printf "   %-32s %8.0f CPU s (compile %.0f, link %.1f over %d links)\n", f, fsum[f], by[f " compile"], by[f " link"], links[f]
    printf "   %-32s %8.0f CPU s\n", "total", total
    n = 0; for (t in tsum) { name[++n] = t }
    for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (tsum[name[j]] > tsum[name[i]]) { x = name[i]; name[i] = name[j]; name[j] = x }
    printf "== the ten costliest targets\n"
    for (i = 1; i <= n && i <= 10; i++) printf "   %-40s %8.0f CPU s\n", name[i], tsum[name[i]]
  }' "$log"
