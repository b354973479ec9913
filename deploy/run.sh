#!/usr/bin/env bash
# hemm: install what is missing (Debian 12), build, and run one of
#   demo   build (release) and run the loopback demo (HEMM); `demo bimanual`,
#          `demo vps`, `demo explore3d`, `demo telemanip` run the other parts (`demo --help`)
#   test   build release + sanitizer (ASan/UBSan, clang, with libFuzzer
#          targets) configurations and run every test in both
#   bench  build release and run the benchmarks
#   build  build release only (with the benchmarks)
# Environment: HEMM_JOBS (default: nproc), HEMM_BUILD_DIR (default: build),
#   HEMM_UNITY (default: 1, unity builds; 0 builds file by file, quicker to
#   rebuild after editing one file).
set -euo pipefail

usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; }
mode="${1:-}"
case "$mode" in
  demo|test|bench|build) shift ;;&
  demo)
    case "${1:-}" in
      -h|--help)
        echo "bash deploy/run.sh demo [SECONDS]   the HEMM loopback demo (deploy/demo.sh; out/demo/)"
        echo "bash deploy/run.sh demo PART [--out DIR]   another part, a few minutes each (deploy/demo_parts.sh):"
        sed -n '2,17p' "$(dirname "$0")/demo_parts.sh" | sed 's/^#/ /'
        exit 0 ;;
      ""|bimanual|vps|explore3d|telemanip) ;;
      *) [[ "$1" =~ ^[0-9]+$ ]] || { echo "error: demo '$1': a part (bimanual, vps, explore3d, telemanip) or seconds per phase (see demo --help)" >&2; exit 2; } ;;
    esac ;;
  test|bench|build) ;;
  -h|--help) usage; exit 0 ;;
  *) usage >&2; echo "error: unknown mode '${mode}'" >&2; exit 2 ;;
esac

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
builds="${HEMM_BUILD_DIR:-$root/build}"
jobs="${HEMM_JOBS:-$(nproc)}"

# Phase times: each phase prints its time when it ends, and the whole table is
# printed again when the script exits (also after a failure, up to that phase).
t_start=$SECONDS
phase_names=(); phase_secs=()
phase_t0=$SECONDS
phase_begin() { phase_t0=$SECONDS; }
# phase_end NAME [START]: records SECONDS - START (default: the last phase_begin).
phase_end() {
  local dt=$((SECONDS - ${2:-$phase_t0}))
  phase_names+=("$1"); phase_secs+=("$dt")
  echo "== phase: $1: ${dt} s"
}
phase_table() {
  ((${#phase_names[@]})) || return 0
  echo "== phase times (wall-clock seconds)"
  local i
  for i in "${!phase_names[@]}"; do
    printf '   %-62s %6d s\n' "${phase_names[$i]}" "${phase_secs[$i]}"
  done
  printf '   %-62s %6d s\n' "total" "$((SECONDS - t_start))"
}
# kill_tree PID: the background job PID started and everything under it.
kill_tree() {
  local child
  for child in $(pgrep -P "$1" 2>/dev/null); do kill_tree "$child"; done
  kill "$1" 2>/dev/null || true
}
on_exit() {
  local rc=$?
  # An interrupted or failed run leaves no compiler or test run behind.
  [[ -n "${asan_pid:-}" ]] && kill_tree "$asan_pid"
  [[ -n "${unit_pid:-}" ]] && kill_tree "$unit_pid"
  phase_table
  return $rc
}
trap on_exit EXIT

# ------------------------------------------------------------------ install
packages=(
  build-essential cmake ninja-build pkg-config ccache clang libclang-rt-14-dev lld
  libasio-dev libprotobuf-dev protobuf-compiler libeigen3-dev libpcl-dev libmujoco-dev
  libsodium-dev libassimp-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev
  libspdlog-dev libfcl-dev python3-matplotlib
  libzstd-dev zlib1g-dev python3-zstandard python3-protobuf dpkg-dev
  libglfw3-dev libpng-dev xvfb time
)
phase_begin
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  echo "== installing ${#missing[@]} missing Debian package(s): ${missing[*]}"
  sudo_cmd=()
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "error: need root or sudo to install packages" >&2; exit 1; }
    sudo_cmd=(sudo)
  fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -q
  "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
phase_end "install (Debian packages)"

# Every compile and link step goes through cmake/cpu_time_launcher.sh, which
# logs its CPU seconds when HEMM_CPU_LOG is set (build() sets it): each build
# ends with its CPU by target family, a figure the machine's other load
# changes less than wall time (on a loaded shared VM one compile's CPU
# seconds varied up to 4x, its wall time 13x).
cpu_launcher="$root/cmake/cpu_time_launcher.sh"
compiler_launcher="$cpu_launcher"
command -v ccache >/dev/null && compiler_launcher="$cpu_launcher;ccache"
launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER="$compiler_launcher" -DCMAKE_C_COMPILER_LAUNCHER="$compiler_launcher"
          -DCMAKE_CXX_LINKER_LAUNCHER="$cpu_launcher")
# Both builds are unity builds (up to 8 files of a target compiled as one):
# Eigen, protobuf and gtest are parsed once per batch instead of once per
# file and their templates instantiated (and, under the sanitizers,
# instrumented) once, about a quarter less compile CPU on a 2-core VM (g++:
# 436 -> 331 CPU s on a sample of six test targets).
unity=(-DCMAKE_UNITY_BUILD=ON)
if [[ "${HEMM_UNITY:-1}" == 0 ]]; then unity=(-DCMAKE_UNITY_BUILD=OFF); fi

# Warnings are errors in these builds (CI and development); a plain CMake
# build leaves HEMM_WERROR off.
# The release build keeps line tables and function names (-g1: backtraces,
# perf, gdb by line) but not full variable info, which took about a quarter of
# a typical file's compile time on a 2-core VM. It is compiled by clang, as
# the sanitizer build is: on this tree's unity files clang 14 took 36-42 %
# less CPU than g++ 12 at -O2 -g1 (hemm_vps 28.5 against 44.7 s, a test
# target's file 28.7 against 50.0 s); a plain `cmake` build uses the system's
# g++ and is checked by OrdinaryBuild.* (tests/build).
configure_release() {
  phase_begin
  CC=clang CXX=clang++ cmake -S "$root" -B "$builds/release" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHEMM_WERROR=ON \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    "${launcher[@]}" "${unity[@]}" "$@" >/dev/null
  phase_end "configure release"
}
configure_asan() {
  # Line tables are all a sanitizer report needs; full debug info only adds
  # compile and link time. The fuzz targets (coverage instrumentation on every
  # edge of the tree) are built by deploy/fuzz.sh, not here; the tests
  # labelled realtime, which only the release pass runs, are not built here.
  phase_begin
  CC=clang CXX=clang++ cmake -S "$root" -B "$builds/asan" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DHEMM_WERROR=ON -DHEMM_SANITIZE=ON -DHEMM_FUZZ=OFF -DHEMM_BENCH=OFF -DHEMM_REALTIME_TESTS=OFF "${launcher[@]}" "${unity[@]}" "$@" >/dev/null
  phase_end "configure asan"
}
# build DIR [nice]: builds DIR (at nice 19 with a second argument), logging
# each step's CPU seconds to DIR/build-cpu.log (summed by cpu_report DIR).
build() {
  local dir="$1"
  rm -f "$dir/build-cpu.log"
  if [[ -n "${2:-}" ]]; then
    HEMM_CPU_LOG="$dir/build-cpu.log" nice -n 19 cmake --build "$dir" -j "$jobs"
    return
  fi
  echo "== building $dir ($jobs jobs)"
  phase_begin
  HEMM_CPU_LOG="$dir/build-cpu.log" cmake --build "$dir" -j "$jobs"
  phase_end "build $(basename "$dir")"
  cpu_report "$dir"
}
cpu_report() { "$root/cmake/cpu_time_report.sh" "$1/build-cpu.log" | sed "s|^== build CPU|== $(basename "$1") build CPU|"; }

# Runs ctest in a build dir and appends "<passed> <failed>" to $counts.
# Tests labelled loopback or timing measure wall-clock behaviour: they run one
# at a time, after the others, so they do not compete for the 2 cores.
counts=()
ctest_pass() {
  local dir="$1"; shift
  local log; log="$(mktemp)"
  set +e
  (cd "$dir" && ctest --output-on-failure --no-tests=ignore "$@") 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  set -e
  ctest_count "$log" "$rc"
  rm -f "$log"
}
# ctest_count LOG RC: appends the counts of the ctest output in LOG (exit code RC).
ctest_count() {
  local log="$1" rc="$2"
  local line total failed
  line="$(grep -E 'tests passed, [0-9]+ tests? failed out of [0-9]+' "$log" | tail -1)"
  if [[ -z "$line" ]]; then
    # --no-tests=ignore: a label selection that matches nothing is fine.
    ((rc == 0)) && return
    echo "error: no test summary from ctest in $log" >&2
    counts+=("0 1")
    return
  fi
  failed="$(sed -E 's/.* ([0-9]+) tests? failed out of ([0-9]+).*/\1/' <<<"$line")"
  total="$(sed -E 's/.* ([0-9]+) tests? failed out of ([0-9]+).*/\2/' <<<"$line")"
  counts+=("$((total - failed)) $failed")
  if ((rc != 0 && failed == 0)); then counts+=("0 1"); fi
}

case "$mode" in
  build)
    configure_release -DHEMM_BENCH=ON
    build "$builds/release"
    ;;
  demo)
    configure_release
    build "$builds/release"
    case "${1:-}" in
      bimanual|vps|explore3d|telemanip) exec "$root/deploy/demo_parts.sh" "$1" "$builds/release" "${@:2}" ;;
    esac
    exec "$root/deploy/demo.sh" "$builds/release" "$@"
    ;;
  bench)
    configure_release -DHEMM_BENCH=ON
    build "$builds/release"
    exec "$root/deploy/bench.sh" "$builds/release" "$@"
    ;;
  test)
    # The benchmarks are not tests (they print numbers and assert nothing):
    # `run.sh bench` and `run.sh build` build them, the test mode does not.
    configure_release -DHEMM_BENCH=OFF
    configure_asan
    # The sanitizer build compiles at the lowest priority from the start:
    # beside the release build it takes only what that leaves (a target
    # waiting for its library, a lone link at the end), and beside the release
    # build's wall-clock tests, which run one at a time and mostly wait on the
    # clock (the stations at 1 kHz use about one core), it takes the other
    # core; the tests' processes (nice 0; the servo thread SCHED_FIFO when
    # permitted) preempt it. On a 2-core VM the release wall-clock pass took
    # 526 s instead of 510 s with it beside, all passing, while it did a third
    # of its work (a 791 s build alone).
    asan_log="$builds/asan-build.log"
    echo "== building $builds/asan ($jobs jobs, nice 19, beside the release build and its tests; log $asan_log)"
    t_asan=$SECONDS
    (build "$builds/asan" nice >"$asan_log" 2>&1) &
    asan_pid=$!
    build "$builds/release"
    echo "== testing $builds/release"
    phase_begin
    ctest_pass "$builds/release" -j "$jobs" -LE "loopback|timing|realtime"
    phase_end "release unit tests (parallel; asan build beside)"
    phase_begin
    ctest_pass "$builds/release" -j 1 -L "loopback|timing|realtime"
    phase_end "release wall-clock tests (one at a time; asan build beside)"
    echo "== waiting for the $builds/asan build"
    phase_begin
    if ! wait "$asan_pid"; then
      asan_pid=""
      tail -n 60 "$asan_log" >&2
      echo "error: the sanitizer build failed (log: $asan_log)" >&2
      exit 1
    fi
    asan_pid=""
    phase_end "asan build, rest after the release tests"
    phase_end "asan build, all (from the start, beside the rows above)" "$t_asan"
    cpu_report "$builds/asan"
    # Wall-clock tests run here too, their timing-only assertions skipped by
    # the tests themselves; the long end-to-end runs labelled `realtime` (a
    # robot that must arrive in time, a view beside the 1 kHz servo) run in
    # the release pass only: CI time, and most of their code paths are covered here
    # by the other loopback tests.
    # The sanitizer build's unit tests run at the lowest priority beside its
    # wall-clock tests, as its build did beside the release ones: the
    # wall-clock tests (timing assertions skipped under the sanitizers) mostly
    # wait on the clock and preempt them; the unit tests assert no timing.
    # ctest -N first: it brings every executable's test list up to date
    # (gtest discovery at test time), which the two runs would otherwise
    # both write at once.
    export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    (cd "$builds/asan" && ctest -N >/dev/null)
    unit_log="$builds/asan-unit-tests.log"
    echo "== testing $builds/asan: unit tests ($jobs jobs, nice 19; log $unit_log) beside the wall-clock tests (one at a time, without the realtime runs)"
    phase_begin
    t_unit=$SECONDS
    ( set +e
      (cd "$builds/asan" && nice -n 19 ctest --output-on-failure --no-tests=ignore -j "$jobs" \
        -LE "loopback|timing|realtime") >"$unit_log" 2>&1
      echo "$? $((SECONDS - t_unit))" >"$unit_log.rc" ) &
    unit_pid=$!
    ctest_pass "$builds/asan" -j 1 -L "loopback|timing"
    phase_end "asan wall-clock tests (one at a time; asan unit tests beside)"
    echo "== waiting for the $builds/asan unit tests"
    phase_begin
    wait "$unit_pid" || true
    unit_pid=""
    cat "$unit_log"
    read -r unit_rc unit_secs <"$unit_log.rc" || { unit_rc=1; unit_secs=0; }
    ctest_count "$unit_log" "$unit_rc"
    phase_end "asan unit tests, rest after the wall-clock tests"
    phase_names+=("asan unit tests, all (overlaps the two rows above)"); phase_secs+=("$unit_secs")
    echo "== phase: asan unit tests, all: ${unit_secs} s"
    passed=0; failed=0
    for c in "${counts[@]}"; do
      read -r p f <<<"$c"; passed=$((passed + p)); failed=$((failed + f))
    done
    echo "== release + sanitizer test runs finished in $((SECONDS - t_start)) s"
    echo "$passed passed, $failed failed"
    ((failed == 0))
    ;;
esac
