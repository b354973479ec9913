#!/usr/bin/env bash
# The real-time table (issue 22): runs EVERY shipped operator configuration
# (deploy/configs/operator*.pbtxt) for SECONDS each, as it ships (threaded
# SIMULATED hardware, SCHED_FIFO and mlockall where permitted), with what it
# needs: a hemm-robot for the networked ones (robot_depth.pbtxt when the
# config has a probe_3d block, else robot.pbtxt; the Omni with a scripted
# hand: --script probe-cylinder), the VPS scenes' meshes (made with
# deploy/vps/make_scenes.sh when missing). Writes a Markdown table of the
# servo loop's deadline figures per configuration (misses: a wake more than
# 0.5 ms late or a tick's work past the period; compute median / p99, period
# p99, wake p99, the worst tick and what ran in it), the SIMULATED hardware
# thread's own figures beside them, and the robot's 1 kHz control loop's;
# the timing plot of every run (deploy/plots/plot_timing.py). The condition
# (idle or beside a compile, SCHED_FIFO or not, pinned or not, the machine's
# load, date, uname) is printed at the top.
#
# Usage: deploy/rt_table.sh BUILD_DIR [--seconds N] [--beside-compile] [--compile-jobs J]
#                           [--servo-cpu C] [--only REGEX] [--out DIR] [--table FILE] [--port-base P]
#   --seconds N        per configuration (default 60)
#   --beside-compile   J loops (default: the number of CPUs) compiling a project
#                      file with its own compile command (build/compile_commands.json)
#                      at nice 0 while the runs go, for the second table
#   --servo-cpu C      pin the servo thread to CPU C (hemm-operator --servo-cpu)
#   --only REGEX       only the configs whose file name matches
#   --out DIR          the runs' files (default out/rt_table[_compile])
#   --table FILE       the Markdown table with its condition (default DIR/rt_table.md)
#   --port-base P      robot ports P, P+1 (default 47600)
set -euo pipefail

usage() { sed -n '/^# Usage:/,/^#   --port-base/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; }
build="${1:-}"
if [[ -z "$build" || "$build" == -h || "$build" == --help ]]; then usage; [[ -n "$build" ]] && exit 0 || exit 2; fi
shift
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$(cd "$build" && pwd)"
secs=60
compile=0
jobs="$(nproc)"
servo_cpu=""
only=""
out=""
table=""
base=47600
while (($#)); do
  case "$1" in
    --seconds) secs="${2:?--seconds needs a number}"; shift 2 ;;
    --beside-compile) compile=1; shift ;;
    --compile-jobs) jobs="${2:?--compile-jobs needs a number}"; shift 2 ;;
    --servo-cpu) servo_cpu="${2:?--servo-cpu needs a CPU}"; shift 2 ;;
    --only) only="${2:?--only needs a regex}"; shift 2 ;;
    --out) out="${2:?--out needs a directory}"; shift 2 ;;
    --table) table="${2:?--table needs a file}"; shift 2 ;;
    --port-base) base="${2:?--port-base needs a port}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "rt_table: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ "$secs" =~ ^[0-9]+$ ]] && ((secs >= 2)) || { echo "rt_table: --seconds '$secs': a whole number >= 2" >&2; exit 2; }
[[ "$jobs" =~ ^[0-9]+$ ]] && ((jobs >= 1)) || { echo "rt_table: --compile-jobs '$jobs': a whole number >= 1" >&2; exit 2; }
[[ "$base" =~ ^[0-9]+$ ]] && ((base >= 1024 && base <= 65000)) || { echo "rt_table: --port-base '$base': 1024..65000" >&2; exit 2; }
[[ -z "$servo_cpu" || "$servo_cpu" =~ ^[0-9]+$ ]] || { echo "rt_table: --servo-cpu '$servo_cpu': a CPU number" >&2; exit 2; }
bin="$build/bin"
for b in hemm-robot hemm-operator; do
  [[ -x "$bin/$b" ]] || { echo "rt_table: $bin/$b not found (build first: bash deploy/run.sh build)" >&2; exit 2; }
done
[[ -x /usr/bin/python3 ]] || { echo "rt_table: /usr/bin/python3 not found" >&2; exit 2; }
cfg="$root/deploy/configs"
out="${out:-$root/out/rt_table$( ((compile)) && echo _compile)}"
mkdir -p "$out"
table="${table:-$out/rt_table.md}"
mkdir -p "$(dirname "$table")"

pids=()
cleanup() { for p in "${pids[@]}"; do kill -- "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

# The VPS scenes' meshes (hemm-operator builds its voxmap caches itself).
if compgen -G "$cfg/operator_vps*.pbtxt" >/dev/null && [[ ! -f "$root/out/vps/assembly-scene.stl" ]]; then
  echo "rt_table: making the VPS scenes (deploy/vps/make_scenes.sh)" >&2
  bash "$root/deploy/vps/make_scenes.sh" "$build" >"$out/make_scenes.log" 2>&1
fi

# The compile beside: a project file's own compile command, in J loops.
compile_cmd=""
if ((compile)); then
  [[ -f "$build/compile_commands.json" ]] || { echo "rt_table: no $build/compile_commands.json" >&2; exit 2; }
  compile_cmd="$(/usr/bin/python3 - "$build/compile_commands.json" "$out" <<'PY'
import json, shlex, sys
cmds = json.load(open(sys.argv[1]))
want = "operator/vps/vps_task.cpp"
for c in cmds:
    if c["file"].endswith(want):
        args = shlex.split(c["command"]) if "command" in c else c["arguments"]
        if "-o" in args:
            args[args.index("-o") + 1] = sys.argv[2] + "/compile_beside.o"
        args = [a for a in args if "ccache" not in a]  # compile for real, every time
        print("cd " + shlex.quote(c["directory"]) + " && " + " ".join(shlex.quote(a) for a in args))
        break
PY
)"
  [[ -n "$compile_cmd" ]] || { echo "rt_table: no compile command for operator/vps/vps_task.cpp" >&2; exit 2; }
  for ((j = 0; j < jobs; ++j)); do
    setsid bash -c "while :; do nice -n 0 bash -c $(printf %q "$compile_cmd") >/dev/null 2>&1; done" &
    pids+=("-$!")  # the loop's process group: the compiler with it
  done
  sleep 3
fi

condition="$( ((compile)) && echo "beside a compile ($jobs loops of g++ on operator/vps/vps_task.cpp at nice 0)" || echo "no compile started by this script")"
condition+="; load average at start $(cut -d' ' -f1 /proc/loadavg)"
{
  echo "# hemm real-time table"
  echo
  echo "- condition: $condition"
  echo "- date: $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "- machine: $(uname -srvmo); $(nproc) CPUs; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //')"
  echo "- load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "- kernel.sched_rt_runtime_us: $(cat /proc/sys/kernel/sched_rt_runtime_us 2>/dev/null || echo '?'); isolated CPUs: $(cat /sys/devices/system/cpu/isolated 2>/dev/null | sed 's/^$/none/' || echo '?')"
  echo "- servo thread: ${servo_cpu:+pinned to CPU $servo_cpu}${servo_cpu:-not pinned}; SCHED_FIFO and mlockall per run (columns FIFO, CPU)"
  echo "- $secs s per configuration; command: deploy/rt_table.sh BUILD --seconds $secs$( ((compile)) && echo " --beside-compile")${servo_cpu:+ --servo-cpu $servo_cpu}${only:+ --only '$only'}"
} >"$out/condition.md"
cat "$out/condition.md"

run_one() {  # CONFIG_FILE
  local file="$1" name dir robot_cfg="" args=()
  name="$(basename "$file" .pbtxt)"
  dir="$out/$name"
  mkdir -p "$dir"
  rm -f "$dir/station.json" "$dir/robot.json"
  # What it needs: a robot unless it runs alone (a VPS scene, the bimanual device without the 6-DoF tool).
  if grep -q '^\s*vps\s*{' "$file"; then
    robot_cfg=""
  elif grep -q 'type: *"sim-bimanual"' "$file" && ! grep -q 'tool: *"pointshell"' "$file"; then
    robot_cfg=""
  elif grep -q '^\s*probe_3d\s*{' "$file"; then
    robot_cfg="robot_depth.pbtxt"
  else
    robot_cfg="robot.pbtxt"
  fi
  if grep -q 'type: *"sim-omni"' "$file" && [[ -n "$robot_cfg" ]]; then args+=(--script probe-cylinder); fi
  [[ -n "$servo_cpu" ]] && args+=(--servo-cpu "$servo_cpu")
  echo "rt_table: $name ($secs s${robot_cfg:+, with hemm-robot $robot_cfg})" >&2
  local robot=""
  if [[ -n "$robot_cfg" ]]; then
    "$bin/hemm-robot" --config "$cfg/$robot_cfg" --session-port "$base" --stream-port $((base + 1)) \
      --duration $((secs + 15)) --log-level warn --station-json "$dir/robot.json" \
      >"$dir/robot.txt" 2>"$dir/robot.log" &
    robot=$!
    pids+=("$robot")
    sleep 1
    args+=(--session-port "$base" --stream-port $((base + 1)))
  fi
  local rc=0
  "$bin/hemm-operator" --config "$file" --duration "$secs" --log-level warn \
    --station-json "$dir/station.json" "${args[@]}" >"$dir/operator.txt" 2>"$dir/operator.log" || rc=$?
  if [[ -n "$robot" ]]; then
    kill -INT "$robot" 2>/dev/null || true
    wait "$robot" 2>/dev/null || true
  fi
  if ((rc != 0)); then
    echo "rt_table: $name: hemm-operator exited with $rc ($dir/operator.log)" >&2
    return 0
  fi
  /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/station.json" --out "$dir/timing.png" \
    --title "$name, $secs s, $condition" >/dev/null || true
}

: >"$out/runs.txt"  # this invocation's configs (an --out reused keeps older folders)
for f in "$cfg"/operator*.pbtxt; do
  [[ -n "$only" && ! "$(basename "$f")" =~ $only ]] && continue
  run_one "$f"
  basename "$f" .pbtxt >>"$out/runs.txt"
done

/usr/bin/python3 - "$out" "$secs" <<'PY' >"$out/table.md"
import json, os, sys
out, secs = sys.argv[1], sys.argv[2]

def n(v):
    return float(v) if v is not None else 0.0

def timing(path, key):
    try:
        j = json.load(open(path))
    except (OSError, ValueError):
        return None
    return j.get(key)

rows = []
for name in open(os.path.join(out, "runs.txt")).read().split():
    d = os.path.join(out, name)
    t = timing(os.path.join(d, "station.json"), "timing")
    if not t:
        err = ""
        try:
            err = open(os.path.join(d, "operator.log")).read().strip().splitlines()[-1][:80]
        except (OSError, IndexError):
            pass
        rows.append(f"| {name} | run failed: {err} |" + " |" * 10)
        continue
    ticks, misses = int(n(t.get("ticks"))), int(n(t.get("misses")))
    share = 100.0 * misses / ticks if ticks else 0.0
    c, p, w = t.get("compute_us", {}), t.get("period_us", {}), t.get("wake_latency_us", {})
    worst = (t.get("worst_ticks") or [{}])[0]
    wt = f"{n(worst.get('wake_latency_us')) + n(worst.get('compute_us')):.0f} us"
    if worst.get("renderer"):
        wt += f" ({worst['renderer']}" + (f", work {int(n(worst.get('work')))}" if n(worst.get("work")) else "") + ")"
    hw = t.get("simulated_hardware")
    if isinstance(hw, dict) and hw.get("timing"):
        ht = hw["timing"]
        hticks, hmiss = int(n(ht.get("ticks"))), int(n(ht.get("misses")))
        hcell = (f"{hmiss} ({100.0 * hmiss / hticks if hticks else 0:.2f} %) / "
                 f"{n(ht['compute_us'].get('median')):.1f} / {n(ht['compute_us'].get('p99')):.1f} / "
                 f"{n(ht['period_us'].get('p99')):.0f} / {n(hw.get('sample_age_us', {}).get('p99')):.0f}")
    else:
        hcell = "none (lock-step or no simulated hardware)"
    r = timing(os.path.join(d, "robot.json"), "control_timing")
    if r:
        rticks, rmiss = int(n(r.get("ticks"))), int(n(r.get("misses")))
        rcell = (f"{rmiss} ({100.0 * rmiss / rticks if rticks else 0:.2f} %) / {n(r['compute_us'].get('median')):.1f} / "
                 f"{n(r['compute_us'].get('p99')):.1f} / {n(r['period_us'].get('p99')):.0f}")
    else:
        rcell = "-"
    fifo = ("yes" if t.get("fifo") else "no") + (" (wake latency held)" if t.get("wake_latency_held") else "")
    cpu = int(n(t.get("cpu", -1)))
    rows.append(f"| {name} | {ticks} | {misses} ({share:.3f} %) | {n(c.get('median')):.1f} | {n(c.get('p99')):.1f} | "
                f"{n(p.get('p99')):.1f} | {n(w.get('p99')):.1f} | {wt} | {fifo} / {cpu if cpu >= 0 else '-'} | "
                f"{hcell} | {rcell} |")

print(f"| config ({secs} s) | ticks | misses (%) | compute median us | compute p99 us | period p99 us | wake p99 us "
      "| worst tick (what ran) | FIFO / CPU | SIMULATED hardware: misses (%) / compute median / p99 / period p99 / "
      "sample age p99 us | robot 1 kHz control: misses (%) / compute median / p99 / period p99 us |")
print("|---|--:|--:|--:|--:|--:|--:|---|---|---|---|")
for r in rows:
    print(r)
print()
print("Targets (idle machine): misses <= 0.1 %, compute p99 <= 300 us, period p99 <= 1100 us. A miss: a wake more "
      "than 0.5 ms late or a tick's work past the next deadline. Plots: <config>/timing.png.")
PY
cat "$out/condition.md" "$out/table.md" >"$table"
echo
cat "$out/table.md"
echo
echo "rt_table: wrote $table (and each run's station.json, timing.png under $out/<config>/)" >&2
