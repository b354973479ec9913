#!/usr/bin/env bash
# Regenerates docs/measurements.md from runs: each section runs its producer
# (the scripts and tests that measure that part), makes its table from the
# run's own JSON/CSV/text output (deploy/report_tables.py), and states the
# command, the date, the machine (cores, CPU model, kernel) and the condition
# you give (the script cannot know whether the machine was idle).
#
# Usage: deploy/report.sh BUILD_DIR --condition TEXT [--only S1,S2,...] [--quick]
#                         [--rt-table FILE] [--out FILE] [--work DIR]
# Sections (in the document's order):
#   latency    the loopback latency suite through hemm-relay at 0-1000 ms (latency_suite_test; ~2.5 min)
#   accuracy   the local model against the scene's truth on every scene (deploy/accuracy.sh; ~12 min)
#   explore3d  the 6-DoF probe tool on the live voxmap against truth on every table scene
#              (deploy/explore3d_table.sh; ~2-2.5 min a scene and round trip, 0 and 300 ms;
#              its ports from $HEMM_EXPLORE3D_PORT_BASE, default 47300)
#   vps        the Voxmap-PointShell engine report (hemm-vps report; ~3 min)
#   vps-budget the time-critical VPS's force error against the full cycle at
#              budgets from the smallest to the full cycle, on the shipped VPS
#              configs' poses (vps_budget_bench; ~5 min), and its plot
#   bimanual   the SIMULATED bimanual device's cost per tick (bimanual_bench; ~20 s)
#   link       the link's hot paths: sealing, opening, replay window (bench_net; ~1 min)
#   rt         every shipped operator config for 60 s, its servo deadlines
#              (deploy/rt_table.sh; ~12 min), beside the machine's own floor
#              (cyclictest from rt-tests, if installed), and the histogram plot of the
#              VPS peg-in-hole with the bimanual device; or, with --rt-table
#              FILE, the table deploy/rt_table.sh wrote elsewhere, imported
#   rt-compile the same with a compile running beside (deploy/rt_table.sh
#              --beside-compile; ~12 min): figures reported, no target
# --only: these sections are run and replaced; the others are kept as they are
#   in the output file (or marked missing there). --quick: small runs of each
#   section (one scene, one round trip, a short VPS trajectory, two configs
#   for 3 s in the real-time sections), to check the
#   script, written to WORK/measurements.md unless --out is given; the latency
#   suite is left out (marked missing) in this mode. --out: default
#   docs/measurements.md. --work: where the runs' outputs are kept (default
#   out/report-<UTC time>; the evidence behind each table).
set -euo pipefail

usage() { sed -n '/^# Usage:/,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'; }
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-}"
if [[ -z "$build" || "$build" == -h || "$build" == --help ]]; then usage; [[ -n "$build" ]] && exit 0 || exit 2; fi
shift
all="latency,accuracy,explore3d,vps,vps-budget,bimanual,link,rt,rt-compile"
only="$all" condition="" quick=0 rt_table="" out="" work=""
while (($#)); do
  case "$1" in
    --condition) condition="${2:?--condition needs a text}"; shift 2 ;;
    --only) only="${2:?--only needs a list of sections}"; shift 2 ;;
    --quick) quick=1; shift ;;
    --rt-table) rt_table="${2:?--rt-table needs a file}"; shift 2 ;;
    --out) out="${2:?--out needs a file}"; shift 2 ;;
    --work) work="${2:?--work needs a directory}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "report: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
for s in ${only//,/ }; do
  [[ ",$all," == *",$s,"* ]] || { echo "report: --only: unknown section '$s' (sections: $all)" >&2; exit 2; }
done
if [[ -z "$condition" ]]; then
  ((quick)) && condition="a --quick check of deploy/report.sh: small runs, not a measurement" \
    || { echo "report: --condition TEXT is required (e.g. \"idle: nothing else running\")" >&2; exit 2; }
fi
[[ -z "$rt_table" || -f "$rt_table" ]] || { echo "report: --rt-table $rt_table: no such file" >&2; exit 2; }
build="$(cd "$build" 2>/dev/null && pwd)" || { echo "report: build directory not found" >&2; exit 2; }
bin="$build/bin"
py=/usr/bin/python3
[[ -x "$py" ]] || { echo "report: $py not found" >&2; exit 2; }
tables="$root/deploy/report_tables.py"
work="${work:-$root/out/report-$(date -u +%Y%m%dT%H%M%SZ)}"
mkdir -p "$work"
work="$(cd "$work" && pwd)"
if [[ -z "$out" ]]; then ((quick)) && out="$work/measurements.md" || out="$root/docs/measurements.md"; fi
# The plots go beside the document (docs/img/ for docs/measurements.md).
img="$(dirname "$out")/img"
mkdir -p "$(dirname "$out")"

machine="$(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'), Linux $(uname -r)"
declare -A titles=(
  [latency]="Latency injection: servo, forces and pose through hemm-relay at 0-1000 ms round trip"
  [accuracy]="The local model's force against the true scene, every scene"
  [explore3d]="6-DoF probe tool on the live voxmap against the true scene"
  [vps]="Voxmap-PointShell engine: cost per cycle against force error"
  [bimanual]="The SIMULATED bimanual device: cost per servo tick"
  [link]="Link: sealing and opening datagrams and frames"
  [vps-budget]="Time-critical VPS: force error against the full cycle at each budget"
  [rt]="Real-time servo: every shipped operator configuration"
  [rt-compile]="Real-time servo beside a compile"
)
order=()
for s in ${all//,/ }; do order+=(--order "$s=${titles[$s]}"); done
t0=$SECONDS
step() { echo "== [$((SECONDS - t0)) s] $*" >&2; }
sections=()

# emit NAME COMMAND TABLE_FILE [NOTE [CONDITION]]: the section file for NAME
# (CONDITION: the run's own, default --condition's).
emit() {
  local name="$1" command="$2" table="$3" note="${4:-}" cond="${5:-$condition}"
  local f="$work/section-$name.md"
  "$py" "$tables" section "$name" "${titles[$name]}" --command "$command" --date "$(date -u '+%Y-%m-%d %H:%M UTC')" \
    --machine "$machine" --condition "$cond" --table "$table" ${note:+--note "$note"} >"$f"
  sections+=("$f")
}
missing() {  # NAME REASON
  local f="$work/section-$1.md"
  "$py" "$tables" section "$1" "${titles[$1]}" --missing "$2" >"$f"
  sections+=("$f")
}
need() { local x; for x in "$@"; do [[ -x "$bin/$x" ]] || { echo "report: $bin/$x not found (build it first)" >&2; exit 2; }; done; }
rel() { echo "${1#"$root"/}"; }  # a path as the command line shows it, from the repository's root

for s in ${only//,/ }; do
  case "$s" in
  latency)
    if ((quick)); then missing latency "not run by --quick (the whole suite takes about 2.5 minutes)."; continue; fi
    need latency_suite_test hemm-robot hemm-operator hemm-relay hemm-truth
    step "latency: latency_suite_test (about 2.5 minutes)"
    cmd="$(rel "$bin")/latency_suite_test --gtest_filter=LatencySuite.NavigationToAGoal*"
    (cd "$work" && "$bin/latency_suite_test" --gtest_filter='LatencySuite.NavigationToAGoal*') >"$work/latency.txt" 2>&1 \
      || echo "report: latency_suite_test failed (its table is kept; see $work/latency.txt)" >&2
    "$py" "$tables" latency "$work/latency.txt" >"$work/latency.md"
    emit latency "$cmd" "$work/latency.md" "Columns as the suite prints them (tests/integration/latency): per50/per99 the servo period, wake99/comp99 its wake-up lateness and compute time, E_gen/E_ep energy the rendering gave the hand, goal_p/goal_t the predicted / true distance to the goal, dF/cF the force error against the true scene over all / contact ticks, pose_e the pose error."
    ;;
  accuracy)
    need hemm-robot hemm-operator hemm-relay hemm-truth
    a=()
    ((quick)) && a=(--scenes home --rtts 0 --runs probe-cylinder)
    step "accuracy: deploy/accuracy.sh ${a[*]} (about 40 s a run)"
    rc=0
    "$root/deploy/accuracy.sh" "$build" "${a[@]}" --out "$work/accuracy" >"$work/accuracy.txt" 2>"$work/accuracy.log" || rc=$?
    "$py" "$tables" markdown-rows "$work/accuracy.txt" >"$work/accuracy.md" \
      || { tail -n 20 "$work/accuracy.log" >&2; echo "report: accuracy.sh gave no table (exit $rc)" >&2; exit 1; }
    note="cF: |F_rendered - F_true| over contact ticks (RMS, max, RMS as a share of the SIMULATED Omni's 3.3 N peak); dF over all ticks."
    ((rc)) && note+=" accuracy.sh exited $rc: $(tail -n 1 "$work/accuracy.txt")."
    emit accuracy "deploy/accuracy.sh $(rel "$build") ${a[*]}" "$work/accuracy.md" "$note"
    ;;
  explore3d)
    need hemm-robot hemm-operator hemm-relay hemm-truth
    a=()
    ((quick)) && a=(--scenes home --rtts 0)
    step "explore3d: deploy/explore3d_table.sh ${a[*]} (about 2-2.5 min a scene and round trip: the route, then the truth replay)"
    # HEMM_EXPLORE3D_PORT_BASE: other ports when another run on this machine holds 47300.
    "$root/deploy/explore3d_table.sh" "$build" "${a[@]}" --port-base "${HEMM_EXPLORE3D_PORT_BASE:-47300}" --out "$work/explore3d" \
      >"$work/explore3d.txt" 2>"$work/explore3d.log" || { tail -n 20 "$work/explore3d.log" >&2; echo "report: explore3d_table.sh failed" >&2; exit 1; }
    # The per-feature table, then each run's whole-run table (force, torque, servo) as explore3d.sh printed it.
    {
      cat "$work/explore3d/table.md"
      for f in "$work"/explore3d/*/variant*.txt; do
        v="${f%.txt}"
        printf '\n%s, %s:\n\n' "$(basename "$(dirname "$f")")" "$(cat "$v/label.txt")"
        awk '/^\|/ {p = 1; print; next} p {exit}' "$f"
      done
    } >"$work/explore3d.md"
    emit explore3d "deploy/explore3d_table.sh $(rel "$build") ${a[*]}" "$work/explore3d.md" \
      "First table: per scene, the force error RMS over each feature's contact ticks (the features of the scene's route, from its header) and over the whole run, of the true force's peak there (its share); columns: round trip and variant. Then each run's whole-run force and torque errors and its servo timing."
    ;;
  vps)
    need hemm-vps
    a=()
    ((quick)) && a=(--bosses 1 --ticks 200 --repeats 1 --fcl-every 0 --paper-bosses 0)
    step "vps: hemm-vps report ${a[*]}"
    "$bin/hemm-vps" report "${a[@]}" >"$work/vps.txt" 2>&1 || { tail -n 20 "$work/vps.txt" >&2; echo "report: hemm-vps report failed" >&2; exit 1; }
    "$py" "$tables" markdown-rows "$work/vps.txt" >"$work/vps.md"
    emit vps "$(rel "$bin")/hemm-vps report ${a[*]}" "$work/vps.md" \
      "CPU µs: thread CPU time per three-pair cycle (median, p99); F/T err: RMS error against the exact references, as a share of the RMS exact force (torque over force times the tool's radius)."
    ;;
  bimanual|link)
    if [[ "$s" == bimanual ]]; then
      b=bimanual_bench
      note="Both arms' controllers (kinematics, dynamics, projector, feed-forward, collision pairs), the MuJoCo plant for one 1 ms period, and the operator station's tick with the device (read, task, write); wall-clock and CPU time per iteration."
    else
      b=bench_net
      note="Wall-clock time per operation (Google Benchmark); the datagram cases repeat 5 times. Argument: payload bytes (1156: the largest that fits a datagram)."
    fi
    need "bench/$b"
    a=()
    ((quick)) && a=(--benchmark_min_time=0.01)
    step "$s: $b ${a[*]}"
    "$bin/bench/$b" "${a[@]}" --benchmark_out="$work/$b.json" --benchmark_out_format=json \
      >"$work/$b.txt" 2>&1 || { tail -n 20 "$work/$b.txt" >&2; echo "report: $b failed" >&2; exit 1; }
    "$py" "$tables" bench "$work/$b.json" >"$work/$s.md"
    emit "$s" "$(rel "$bin")/bench/$b ${a[*]}" "$work/$s.md" "$note"
    ;;
  vps-budget)
    need bench/vps_budget_bench
    scenes=()
    # --quick: the Omni's probe only.
    ((quick)) && scenes=("$root/deploy/configs/operator_vps_omni.pbtxt")
    if [[ ! -f "$root/out/vps/assembly-scene.stl" || ! -f "$root/out/vps/peg-in-hole-probe.stl" ]]; then
      step "vps-budget: making the VPS scenes (deploy/vps/make_scenes.sh)"
      bash "$root/deploy/vps/make_scenes.sh" "$build" >"$work/make_scenes.log" 2>&1 \
        || { tail -n 20 "$work/make_scenes.log" >&2; echo "report: make_scenes.sh failed" >&2; exit 1; }
    fi
    step "vps-budget: vps_budget_bench $(((quick)) && echo "(the Omni's probe only)")"
    mkdir -p "$work/vps_budget"
    "$bin/bench/vps_budget_bench" --out "$work/vps_budget" "${scenes[@]}" >"$work/vps_budget.txt" 2>&1 \
      || { tail -n 20 "$work/vps_budget.txt" >&2; echo "report: vps_budget_bench failed" >&2; exit 1; }
    "$py" "$tables" vps-budget "$work/vps_budget/vps_budget.csv" >"$work/vps-budget.md"
    mkdir -p "$img"
    "$py" "$root/deploy/plots/plot_vps_budget.py" "$work/vps_budget/vps_budget.csv" --out "$img/vps_budget.png" >/dev/null \
      || { echo "report: plot_vps_budget.py failed" >&2; exit 1; }
    emit vps-budget "$(rel "$bin")/bench/vps_budget_bench ${scenes[*]/#"$root/"/}" "$work/vps-budget.md" \
      "Each shipped VPS config's device in lock step with the VPS task at the full cycle; then on the same poses the time-critical cycle at work budgets (units), at the task's time budgets (µs: calibrated on the model, then the measured cost per unit each tick) and the full cycle. Early: share of all ticks stopped before some pair's finest level. Error: |F - F_full| on each held object over the ticks the full cycle has a contact (RMS, max; RMS as a share of the RMS contact force). Work-budget rows are deterministic; time-budget rows and times are this machine's. Plot: ![force error and ticks stopped early against the VPS time per tick](img/vps_budget.png)"
    ;;
  rt|rt-compile)
    if [[ "$s" == rt && -n "$rt_table" ]]; then
      step "rt: importing $rt_table"
      # The file as deploy/rt_table.sh wrote it (its own command, date and
      # machine lines kept), without its headings; it must hold a table.
      "$py" "$tables" markdown-rows "$rt_table" >/dev/null
      grep -v '^#' "$rt_table" >"$work/rt.md"
      emit rt "deploy/rt_table.sh (imported by deploy/report.sh --rt-table $(rel "$(cd "$(dirname "$rt_table")" && pwd)/$(basename "$rt_table")"))" \
        "$work/rt.md" "Imported from the file the real-time script wrote: the date above is the import's; the run's own are in the text below, if it gives them."
      continue
    fi
    need hemm-robot hemm-operator
    a=()
    ((quick)) && a=(--seconds 3 --only '^operator(_vps_omni)?\.pbtxt$')
    # The machine's own floor, before hemm runs: how late it wakes a bare
    # SCHED_FIFO thread every 1 ms (cyclictest, Debian's rt-tests), if present.
    floor=""
    if [[ "$s" == rt ]] && command -v cyclictest >/dev/null; then
      step "rt: cyclictest, the machine alone ($(((quick)) && echo 3 || echo 60) s)"
      if cyclictest -m -p 80 -i 1000 -D "$(((quick)) && echo 3 || echo 60)" -q -h 5000 --histfile="$work/cyclictest.txt" \
        >"$work/cyclictest.log" 2>&1; then
        floor="$("$py" "$tables" cyclictest "$work/cyclictest.txt") "
      else
        floor="(cyclictest could not run here: $(tail -n 1 "$work/cyclictest.log")) "
      fi
    fi
    [[ "$s" == rt-compile ]] && a+=(--beside-compile)
    step "$s: deploy/rt_table.sh ${a[*]} (about 70 s a configuration)"
    "$root/deploy/rt_table.sh" "$build" "${a[@]}" --out "$work/$s" --table "$work/$s-table.md" \
      >"$work/$s.txt" 2>"$work/$s.log" || { tail -n 20 "$work/$s.log" >&2; echo "report: rt_table.sh failed" >&2; exit 1; }
    # The script's own condition lines (load, RT throttling, pinning) above its table.
    { grep '^- ' "$work/$s/condition.md" | grep -v '^- date:\|^- machine:'; echo; cat "$work/$s/table.md"; } >"$work/$s.md"
    "$py" "$tables" markdown-rows "$work/$s.md" >/dev/null
    note="${floor}Per configuration: its servo loop (misses: a wake more than 0.5 ms late or a tick's work past the next deadline; compute from the wake to the end of the tick's work), the SIMULATED hardware thread beside it, and the robot station's 1 kHz control loop for the networked ones. Each run's histograms: $(rel "$work")/$s/<config>/timing.png."
    cond="$condition"
    if [[ "$s" == rt-compile ]]; then
      cond="$condition, then a compile started beside the runs by deploy/rt_table.sh --beside-compile (figures reported, no target)"
    elif ((!quick)) && [[ -f "$work/$s/operator_vps_peg_bimanual/timing.png" ]]; then
      mkdir -p "$img"
      cp "$work/$s/operator_vps_peg_bimanual/timing.png" "$img/timing.png"
      note+=" The histograms of the VPS peg-in-hole with the SIMULATED bimanual device: ![deadline histograms](img/timing.png)"
    fi
    emit "$s" "deploy/rt_table.sh $(rel "$build") ${a[*]}" "$work/$s.md" "$note" "$cond"
    ;;
  esac
done

"$py" "$tables" merge "$out" "${sections[@]}" "${order[@]}" >"$work/measurements.new.md"
mv "$work/measurements.new.md" "$out"
step "wrote $out (sections run: $only; runs' outputs in $work)"
