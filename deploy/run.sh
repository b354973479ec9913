#!/usr/bin/env bash
# hemm: install what is missing (Debian 12), build, and run one of
#   demo   build (release) and run the loopback demo
#   test   build release + sanitizer (ASan/UBSan, clang, with libFuzzer
#          targets) configurations and run every test in both
#   bench  build release and run the benchmarks
#   build  build release only
# Environment: HEMM_JOBS (default: nproc), HEMM_BUILD_DIR (default: build),
#   HEMM_UNITY (default: 1, unity builds; 0 builds file by file, quicker to
#   rebuild after editing one file).
set -euo pipefail

usage() { sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; }
mode="${1:-}"
case "$mode" in
  demo|test|bench|build) shift ;;
  -h|--help) usage; exit 0 ;;
  *) usage >&2; echo "error: unknown mode '${mode}'" >&2; exit 2 ;;
esac

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
builds="${HEMM_BUILD_DIR:-$root/build}"
jobs="${HEMM_JOBS:-$(nproc)}"

# ------------------------------------------------------------------ install
packages=(
  build-essential cmake ninja-build pkg-config ccache clang libclang-rt-14-dev lld
  libasio-dev libprotobuf-dev protobuf-compiler libeigen3-dev libpcl-dev libmujoco-dev
  libsodium-dev libassimp-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev
  libspdlog-dev libfcl-dev python3-matplotlib
  libzstd-dev zlib1g-dev python3-zstandard python3-protobuf dpkg-dev
  libglfw3-dev libpng-dev xvfb
)
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

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
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
# a typical file's compile time on a 2-core VM.
configure_release() {
  cmake -S "$root" -B "$builds/release" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHEMM_WERROR=ON \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    "${launcher[@]}" "${unity[@]}" "$@" >/dev/null
}
configure_asan() {
  # Line tables are all a sanitizer report needs; full debug info only adds
  # compile and link time. The fuzz targets (coverage instrumentation on every
  # edge of the tree) are built by deploy/fuzz.sh, not here.
  CC=clang CXX=clang++ cmake -S "$root" -B "$builds/asan" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
    -DHEMM_WERROR=ON -DHEMM_SANITIZE=ON -DHEMM_FUZZ=OFF -DHEMM_BENCH=OFF "${launcher[@]}" "${unity[@]}" "$@" >/dev/null
}
build() {
  local dir="$1"
  echo "== building $dir ($jobs jobs)"
  local t0=$SECONDS
  cmake --build "$dir" -j "$jobs"
  echo "== built $dir in $((SECONDS - t0)) s"
}

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
  local line total failed
  line="$(grep -E 'tests passed, [0-9]+ tests? failed out of [0-9]+' "$log" | tail -1)"
  rm -f "$log"
  if [[ -z "$line" ]]; then
    # --no-tests=ignore: a label selection that matches nothing is fine.
    ((rc == 0)) && return
    echo "error: no test summary from ctest in $dir" >&2
    counts+=("0 1")
    return
  fi
  failed="$(sed -E 's/.* ([0-9]+) tests? failed out of ([0-9]+).*/\1/' <<<"$line")"
  total="$(sed -E 's/.* ([0-9]+) tests? failed out of ([0-9]+).*/\2/' <<<"$line")"
  counts+=("$((total - failed)) $failed")
  if ((rc != 0 && failed == 0)); then counts+=("0 1"); fi
}
# run_tests DIR [skip-realtime]: the unit tests in parallel, then the
# wall-clock ones (labels loopback, timing, realtime) one at a time; with a
# second argument the `realtime` ones are left out.
run_tests() {
  local dir="$1" serial="loopback|timing|realtime"
  [[ -n "${2:-}" ]] && serial="loopback|timing"
  echo "== testing $dir${2:+ (without the realtime runs)}"
  ctest_pass "$dir" -j "$jobs" -LE "loopback|timing|realtime"
  ctest_pass "$dir" -j 1 -L "$serial"
}

case "$mode" in
  build)
    configure_release
    build "$builds/release"
    ;;
  demo)
    configure_release
    build "$builds/release"
    exec "$root/deploy/demo.sh" "$builds/release" "$@"
    ;;
  bench)
    configure_release -DHEMM_BENCH=ON
    build "$builds/release"
    exec "$root/deploy/bench.sh" "$builds/release" "$@"
    ;;
  test)
    t0=$SECONDS
    configure_release
    build "$builds/release"
    echo "== testing $builds/release"
    ctest_pass "$builds/release" -j "$jobs" -LE "loopback|timing|realtime"
    # The sanitizer build compiles at the lowest priority while the release
    # build's wall-clock tests run one at a time: those mostly wait on the
    # clock (the stations at 1 kHz use about one core), the compiler takes
    # what they leave, and the tests' processes (nice 0; the servo thread
    # SCHED_FIFO when permitted) preempt it. On a 2-core VM the release pass
    # took 526 s instead of 510 s, all passing, while the build did a third
    # of its work (a 791 s build alone).
    configure_asan
    asan_log="$builds/asan-build.log"
    echo "== building $builds/asan ($jobs jobs, nice 19, beside the release wall-clock tests; log $asan_log)"
    t_asan=$SECONDS
    (nice -n 19 cmake --build "$builds/asan" -j "$jobs" >"$asan_log" 2>&1) &
    asan_pid=$!
    trap 'kill "$asan_pid" 2>/dev/null || true' EXIT  # an interrupted run leaves no compiler behind
    ctest_pass "$builds/release" -j 1 -L "loopback|timing|realtime"
    echo "== waiting for the $builds/asan build"
    if ! wait "$asan_pid"; then
      tail -n 60 "$asan_log" >&2
      echo "error: the sanitizer build failed (log: $asan_log)" >&2
      exit 1
    fi
    trap - EXIT
    echo "== built $builds/asan in $((SECONDS - t_asan)) s (beside the tests)"
    # Wall-clock tests run here too, their timing-only assertions skipped by
    # the tests themselves; the long end-to-end runs labelled `realtime` (a
    # robot that must arrive in time, a view beside the 1 kHz servo) run in
    # the release pass only: CI time, and most of their code paths are covered here
    # by the other loopback tests.
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      run_tests "$builds/asan" skip-realtime
    passed=0; failed=0
    for c in "${counts[@]}"; do
      read -r p f <<<"$c"; passed=$((passed + p)); failed=$((failed + f))
    done
    echo "== release + sanitizer test runs finished in $((SECONDS - t0)) s"
    echo "$passed passed, $failed failed"
    ((failed == 0))
    ;;
esac
