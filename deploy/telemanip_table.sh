#!/usr/bin/env bash
# The telemanipulation task table (issue 25, "Must show"): the three tasks of
# the SIMULATED two-arm station driven THROUGH THE LINK by the SIMULATED
# humans' task scripts on the SIMULATED bimanual device, judged by the station
# from MuJoCo truth (SIMULATION ONLY). Per cell and seed, one at a time:
#   * a fresh hemm-robot (kind twoarm, deploy/configs/robot_twoarm.pbtxt with
#     twoarm.task set; the box in deploy/scenes/workbench_box.xml, the peg and
#     the bar in workbench.xml),
#   * above 0 ms a hemm-relay between them: rtt/2 each way, 5 % loss, the seed
#     (outage runs: a 1 s outage OUTAGE_AT s after the relay starts),
#   * hemm-operator with deploy/configs/operator_telemanip_tasks.pbtxt (both
#     configs with the path's round trip as link.rtt_ms, written into the run's folder),
#     --task TASK --task-scene SCENE [--telemanip-mode MODE]; it ends when the
#     script is done (+ its settle time) or at its duration,
# and collects both JSON reports into OUT/TASK-RTTms-MODE[-outage]-sSEED/.
# Writes OUT/table.md and OUT/table.json: per cell the success rate, the
# completion time (truth), the script's time, remote peak and RMS contact
# force per gripper, peak squeeze, with --truth-trace what each hand felt
# against the true contact force on its gripper one way delay later (RMS over
# the contact samples, deploy/telemanip_force_error.py), and the passivity
# energies (direct cells). table.json also keeps the direct mode's own
# shown-against-received wrench error (the operator's report).
#
# Usage: deploy/telemanip_table.sh BUILD_DIR [--out DIR] [--tasks box,peg,bar]
#          [--rtts 0,300,1000,3000] [--seeds N] [--seeds-3000 N] [--modes model[,direct]]
#          [--outage] [--outage-at S] [--duration S] [--port-base P] [--truth-trace]
#          [--direct-feedback spring|measured]
#   --seeds N       seeds per cell (default 3)
#   --seeds-3000 N  seeds per model-mediated cell at 3000 ms (default: --seeds)
#   --modes         model (default) and/or direct (needs hemm-operator --telemanip-mode)
#   --direct-feedback  the wrench the station's direct mode returns and its passivity
#                   observer pairs with the tracked twist: spring (default, the station's
#                   default: the impedance's spring wrench) or measured (the wrist sensor's
#                   external wrench, twoarm.direct_feedback_measured); shown in the mode column
#   --outage        also one run per task and mode at 1000 ms with a 1 s outage mid-task
#   --outage-at S   when the outage starts after the relay does (default 14 s)
#   --duration S    the operator's time limit per run (default 90 s + 30 s per second of round trip)
#   --port-base P   ports P+4k .. P+4k+3 for run k (default 47800)
#   --truth-trace   each run's SIMULATION ONLY truth every 10 ms into its folder (truth.csv,
#                   hemm-robot --truth-trace) and its hands (hands.csv, hemm-operator --hand-trace:
#                   commanded and believed G, felt force, the wrist force as believed);
#                   truth.csv: grasp sites and targets, contact force on each
#                   gripper, squeezes, object contacts, goal errors)
# The default OUT is out/telemanip-table-<UTC time>. Runs are sequential; a run
# takes about 20-60 s of wall time (more at 3000 ms).
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed -e '$d' -e 's/^# \{0,1\}//'; }
[[ "${1:-}" == "-h" || "${1:-}" == "--help" ]] && { usage; exit 0; }
build="${1:-}"
[[ -n "$build" && "$build" != -* ]] || { usage >&2; echo "telemanip_table: BUILD_DIR first" >&2; exit 2; }
shift
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/out/telemanip-table-$(date -u +%Y%m%dT%H%M%SZ)"
tasks="box,peg,bar" rtts="0,300,1000,3000" seeds=3 seeds3000="" modes="model" outage=0 outage_at=14 base=47800 limit="" trace=0 feedback=spring
while (($#)); do
  case "$1" in
    --out) out="${2:?--out needs a directory}"; shift 2 ;;
    --tasks) tasks="${2:?--tasks needs a list}"; shift 2 ;;
    --rtts) rtts="${2:?--rtts needs a list}"; shift 2 ;;
    --seeds) seeds="${2:?--seeds needs a number}"; shift 2 ;;
    --seeds-3000) seeds3000="${2:?--seeds-3000 needs a number}"; shift 2 ;;
    --modes) modes="${2:?--modes needs a list}"; shift 2 ;;
    --outage) outage=1; shift ;;
    --outage-at) outage_at="${2:?--outage-at needs seconds}"; shift 2 ;;
    --port-base) base="${2:?--port-base needs a port}"; shift 2 ;;
    --duration) limit="${2:?--duration needs seconds}"; shift 2 ;;
    --truth-trace) trace=1; shift ;;
    --direct-feedback) feedback="${2:?--direct-feedback needs spring or measured}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "telemanip_table: unknown argument '$1' (--help)" >&2; exit 2 ;;
  esac
done
[[ -n "$seeds3000" ]] || seeds3000="$seeds"
fail_arg() { echo "telemanip_table: $*" >&2; exit 2; }
IFS=, read -r -a task_list <<<"$tasks"
IFS=, read -r -a rtt_list <<<"$rtts"
IFS=, read -r -a mode_list <<<"$modes"
for t in "${task_list[@]}"; do [[ "$t" =~ ^(box|peg|bar)$ ]] || fail_arg "--tasks: '$t' is not box, peg or bar"; done
for r in "${rtt_list[@]}"; do
  [[ "$r" =~ ^[0-9]+$ ]] && ((r <= 10000)) || fail_arg "--rtts: '$r' is not a round trip in 0..10000 ms"
done
for m in "${mode_list[@]}"; do [[ "$m" =~ ^(model|direct)$ ]] || fail_arg "--modes: '$m' is not model or direct"; done
[[ "$feedback" =~ ^(spring|measured)$ ]] || fail_arg "--direct-feedback '$feedback': spring or measured"
[[ "$seeds" =~ ^[0-9]+$ ]] && ((seeds >= 1 && seeds <= 100)) || fail_arg "--seeds '$seeds': 1..100"
[[ "$seeds3000" =~ ^[0-9]+$ ]] && ((seeds3000 >= 1 && seeds3000 <= 100)) || fail_arg "--seeds-3000 '$seeds3000': 1..100"
[[ "$outage_at" =~ ^[0-9]+(\.[0-9]+)?$ ]] || fail_arg "--outage-at '$outage_at': seconds"
[[ "$base" =~ ^[0-9]+$ ]] && ((base >= 1024 && base <= 60000)) || fail_arg "--port-base '$base': 1024..60000"
[[ -z "$limit" || ( "$limit" =~ ^[0-9]+$ && "$limit" -ge 5 && "$limit" -le 3600 ) ]] || fail_arg "--duration '$limit': 5..3600 s"
bin="$(cd "$build" 2>/dev/null && pwd)/bin" || fail_arg "BUILD_DIR '$build' not found"
for b in hemm-robot hemm-operator hemm-relay; do
  [[ -x "$bin/$b" ]] || fail_arg "$bin/$b not found (build hemm-robot hemm-operator hemm-relay)"
done
py=/usr/bin/python3
[[ -x "$py" ]] || fail_arg "$py not found"
for m in "${mode_list[@]}"; do
  if [[ "$m" == direct ]] && ! "$bin/hemm-operator" --help 2>/dev/null | grep -q -- "--telemanip-mode"; then
    fail_arg "--modes direct: this hemm-operator has no --telemanip-mode (the direct mode's operator end is not built in)"
  fi
done
if [[ -e "$out" && -n "$(ls -A "$out" 2>/dev/null)" ]]; then fail_arg "$out exists and is not empty; give a fresh --out DIR"; fi
mkdir -p "$out"
out="$(cd "$out" && pwd)"
cfg="$root/deploy/configs"
scenes="$root/deploy/scenes"

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
t0=$SECONDS

# The runs: task rtt mode seed outage(0/1).
runs=()
for m in "${mode_list[@]}"; do
  for t in "${task_list[@]}"; do
    for r in "${rtt_list[@]}"; do
      n=$seeds
      if [[ "$m" == model && "$r" == 3000 ]]; then n=$seeds3000; fi
      for ((s = 1; s <= n; s++)); do runs+=("$t $r $m $s 0"); done
    done
  done
done
if ((outage)); then
  for m in "${mode_list[@]}"; do for t in "${task_list[@]}"; do runs+=("$t 1000 $m 1 1"); done; done
fi
echo "telemanip_table: ${#runs[@]} runs into $out"

k=0
for run in "${runs[@]}"; do
  read -r task rtt mode seed cut <<<"$run"
  suffix=""
  if ((cut)); then suffix="-outage"; fi
  name="$task-${rtt}ms-$mode$suffix-s$seed"
  dir="$out/$name"
  mkdir -p "$dir"
  p=$((base + 4 * k))
  k=$((k + 1))
  scene="$scenes/workbench.xml"
  if [[ "$task" == box ]]; then scene="$scenes/workbench_box.xml"; fi
  # The station's config: the shipped one with absolute paths and the task judged.
  sed -e "s|key_file: \"demo.key\"|key_file: \"$cfg/demo.key\"|" -e "s|scene: \"../scenes/workbench.xml\"|scene: \"$scene\"|" \
    -e "s|^twoarm {|twoarm {\n  task: \"$task\"|" -e "s|seed: 1 |seed: $seed |" \
    -e "s|^link {|link {\n  rtt_ms: $rtt|" "$cfg/robot_twoarm.pbtxt" >"$dir/robot.pbtxt"
  if [[ "$mode" == direct && "$feedback" == measured ]]; then
    sed -i "s|^  direct_feedback_measured: false|  direct_feedback_measured: true|" "$dir/robot.pbtxt"
    grep -q "^  direct_feedback_measured: true" "$dir/robot.pbtxt" || { echo "telemanip_table: could not set direct_feedback_measured in $dir/robot.pbtxt" >&2; exit 1; }
  fi
  if [[ "$mode" == direct ]]; then echo "$feedback" >"$dir/direct_feedback"; fi
  grep -q "task: \"$task\"" "$dir/robot.pbtxt" || { echo "telemanip_table: could not set the task in $dir/robot.pbtxt" >&2; exit 1; }
  # Both ends know the path's round trip: each handshake step waits
  # handshake_timeout_ms (3 s) plus it, and at 3000 ms one step takes the
  # round trip itself (without it the first contact timed out every time).
  { echo "link { rtt_ms: $rtt }"; cat "$cfg/operator_telemanip_tasks.pbtxt"; } >"$dir/operator.pbtxt"
  op_s=$((90 + 30 * rtt / 1000))
  if [[ -n "$limit" ]]; then op_s=$limit; fi
  echo "== [$((SECONDS - t0)) s] run $k/${#runs[@]}: $name (ports $p..$((p + 3)), operator at most $op_s s)"
  trace_args=() hand_args=()
  ((trace)) && trace_args=(--truth-trace "$dir/truth.csv") hand_args=(--hand-trace "$dir/hands.csv")
  "$bin/hemm-robot" --config "$dir/robot.pbtxt" --session-port "$p" --stream-port $((p + 1)) --duration $((op_s + 30)) \
    "${trace_args[@]}" --log-level warn --stats-json "$dir/robot.json" >"$dir/robot.txt" 2>"$dir/robot.log" &
  robot=$!
  pids+=("$robot")
  port=$p stream=$((p + 1)) relay=""
  if ((rtt > 0)); then
    extra=()
    if ((cut)); then extra=(--outage "$outage_at:1"); fi
    "$bin/hemm-relay" --tcp-listen 127.0.0.1:$((p + 2)) --tcp-forward 127.0.0.1:"$p" \
      --udp-listen 127.0.0.1:$((p + 3)) --udp-forward 127.0.0.1:$((p + 1)) \
      --delay-ms $((rtt / 2)) --loss 0.05 --seed "$seed" "${extra[@]}" --stats-json "$dir/relay.json" \
      >"$dir/relay.txt" 2>"$dir/relay.log" &
    relay=$!
    pids+=("$relay")
    for _ in $(seq 50); do grep -q "hemm-relay ready" "$dir/relay.txt" 2>/dev/null && break; sleep 0.1; done
    grep -q "hemm-relay ready" "$dir/relay.txt" || { echo "telemanip_table: hemm-relay did not start ($dir/relay.log)" >&2; exit 1; }
    port=$((p + 2)) stream=$((p + 3))
  fi
  sleep 2
  kill -0 "$robot" 2>/dev/null || { echo "telemanip_table: hemm-robot did not start: $(tail -n 1 "$dir/robot.log")" >&2; exit 1; }
  modeargs=()
  if [[ "$mode" == direct ]]; then modeargs=(--telemanip-mode direct); fi
  rc=0
  "$bin/hemm-operator" --config "$dir/operator.pbtxt" --key "$cfg/demo.key" --session-port "$port" \
    --stream-port "$stream" --task "$task" --task-scene "$scene" "${modeargs[@]}" "${hand_args[@]}" --duration "$op_s" \
    --log-level warn --stats-json "$dir/operator.json" >"$dir/operator.txt" 2>"$dir/operator.log" || rc=$?
  echo "$rc" >"$dir/operator.rc"
  kill -INT "$robot" 2>/dev/null || true
  wait "$robot" 2>/dev/null || true
  if [[ -n "$relay" ]]; then kill -INT "$relay" 2>/dev/null || true; wait "$relay" 2>/dev/null || true; fi
  pids=()
  ((rc == 0)) || echo "   hemm-operator exited with $rc (see $dir/operator.log)"
  grep -E "^telemanip: task" "$dir/operator.txt" | sed 's/^/   /' || true
  grep -E "task .*SIMULATION ONLY" "$dir/robot.txt" | sed 's/^ */   robot: /' || true
done

"$py" - "$out" "$root/deploy" <<'EOF'
import json, os, sys, statistics
out = sys.argv[1]
sys.path.insert(0, sys.argv[2])
from telemanip_force_error import force_error  # deploy/telemanip_force_error.py

def load(p):
    try:
        with open(p) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

def find_key(d, word):
    """The first numeric value under a key containing `word` (the operator's wrench error, when reported)."""
    if isinstance(d, dict):
        for k, v in d.items():
            if word in k and isinstance(v, (int, float)):
                return v
        for v in d.values():
            r = find_key(v, word)
            if r is not None:
                return r
    elif isinstance(d, list):
        for v in d:
            r = find_key(v, word)
            if r is not None:
                return r
    return None

rows = []
for name in sorted(os.listdir(out)):
    d = os.path.join(out, name)
    if not os.path.isdir(d):
        continue
    parts = name.split('-')
    task, rtt, mode = parts[0], int(parts[1][:-2]), parts[2]
    cut = 'outage' in parts
    fb = os.path.join(d, 'direct_feedback')
    if mode == 'direct' and os.path.exists(fb):
        mode = 'direct (%s wrench)' % open(fb).read().strip()
    seed = int(parts[-1][1:])
    robot = load(os.path.join(d, 'robot.json')) or {}
    op = load(os.path.join(d, 'operator.json')) or {}
    v = (robot.get('twoarm') or {}).get('task') or {}
    tp = op.get('task') or {}
    ports = (robot.get('twoarm') or {}).get('passivity') or []
    felt_err = None
    if os.path.exists(os.path.join(d, 'hands.csv')) and os.path.exists(os.path.join(d, 'truth.csv')):
        try:
            fe = force_error(d)
            felt_err = [fe[a]['rms_error_n'] for a in ('right', 'left')]
        except (OSError, ValueError, KeyError) as e:
            print('telemanip_table: %s: no force error (%s)' % (name, e), file=sys.stderr)
    rows.append(dict(
        task=task, rtt_ms=rtt, mode=mode, outage=cut, seed=seed,
        judged=bool(v), success=bool(v.get('success')), why=v.get('why', 'no verdict (robot report missing)'),
        completion_s=v.get('completion_s', -1.0), script_done=bool(tp.get('done')), script_s=tp.get('done_s', -1.0),
        last_step=tp.get('last_step', '?'), searches=tp.get('searches', 0),
        wrist_peak_n=v.get('wrist_peak_n', [0, 0]), wrist_rms_n=v.get('wrist_rms_n', [0, 0]),
        squeeze_peak_n=v.get('squeeze_peak_n', 0.0), hand_squeeze_peak_n=v.get('hand_squeeze_peak_n', [0, 0]),
        object_env_peak_n=v.get('object_env_peak_n', 0.0),
        wrench_error=find_key(op, 'wrench_err'), felt_error_n=felt_err,
        energy_in_j=[p.get('energy_in_j', 0.0) for p in ports], energy_out_j=[p.get('energy_out_j', 0.0) for p in ports],
        dissipated_j=[p.get('dissipated_j', 0.0) for p in ports],
        refusals=(robot.get('twoarm') or {}).get('commands_refused', 0),
        step_done_s=tp.get('step_done_s', []),
        servo_compute_p99_us=((op.get('timing') or {}).get('compute_us') or {}).get('p99'),
        servo_ticks=int((op.get('timing') or {}).get('ticks', 0)), servo_misses=int((op.get('timing') or {}).get('misses', 0)),
        control_compute_us=[((robot.get('twoarm') or {}).get('control_compute') or {}).get(q) for q in ('median', 'p99')],
        operator_rc=open(os.path.join(d, 'operator.rc')).read().strip() if os.path.exists(os.path.join(d, 'operator.rc')) else '?'))

cells = {}
for r in rows:
    cells.setdefault((r['task'], r['rtt_ms'], r['mode'], r['outage']), []).append(r)

def mean(xs):
    return statistics.fmean(xs) if xs else float('nan')

def fmt(x, f='%.1f'):
    return 'n/a' if x is None or x != x else f % x

order = {'box': 0, 'peg': 1, 'bar': 2}
table = []
lines = ['| task | rtt [ms] | mode | runs | success | completion [s] (truth) | script [s] | right wrist peak / RMS [N] | '
         'left wrist peak / RMS [N] | peak squeeze [N] | object contact peak [N] | felt vs true force RMS right / left [N] | energy in / out [J] | '
         'servo compute p99 [us] / misses [%] | robot controllers p99 [us] | failures |',
         '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |']
for key in sorted(cells, key=lambda k: (order.get(k[0], 9), k[2], k[3], k[1])):
    rs = cells[key]
    ok = [r for r in rs if r['success']]
    c = dict(task=key[0], rtt_ms=key[1], mode=key[2], outage=key[3], runs=len(rs), successes=len(ok),
             completion_s=mean([r['completion_s'] for r in ok]), script_s=mean([r['script_s'] for r in rs if r['script_done']]),
             wrist_peak_n=[max(r['wrist_peak_n'][a] for r in rs) for a in range(2)],
             wrist_rms_n=[mean([r['wrist_rms_n'][a] for r in rs]) for a in range(2)],
             squeeze_peak_n=max(r['squeeze_peak_n'] for r in rs), object_env_peak_n=max(r['object_env_peak_n'] for r in rs),
             wrench_error=mean([r['wrench_error'] for r in rs if r['wrench_error'] is not None]) if any(r['wrench_error'] is not None for r in rs) else None,
             felt_error_n=[mean([r['felt_error_n'][a] for r in rs if r['felt_error_n'] is not None and r['felt_error_n'][a] == r['felt_error_n'][a]]) for a in range(2)],
             energy_in_j=sum(sum(r['energy_in_j']) for r in rs) / len(rs), energy_out_j=sum(sum(r['energy_out_j']) for r in rs) / len(rs),
             servo_compute_p99_us=max((r['servo_compute_p99_us'] for r in rs if r['servo_compute_p99_us'] is not None), default=None),
             servo_miss_pct=100.0 * sum(r['servo_misses'] for r in rs) / max(1, sum(r['servo_ticks'] for r in rs)),
             control_compute_p99_us=max((r['control_compute_us'][1] for r in rs if r['control_compute_us'][1] is not None), default=None),
             failures=sorted({'s%d: %s (last step: %s%s)' % (r['seed'], r['why'].strip('; '), r['last_step'],
                                                             ', steps ended at %s s' % ' '.join('%.0f' % x for x in r['step_done_s']) if r['step_done_s'] else '')
                              for r in rs if not r['success']}))
    table.append(c)
    energy = '%.2f / %.2f' % (c['energy_in_j'], c['energy_out_j']) if key[2].startswith('direct') else '-'
    lines.append('| %s | %d%s | %s | %d | %d/%d | %s | %s | %s / %s | %s / %s | %s | %s | %s | %s | %s / %s | %s | %s |' % (
        key[0], key[1], ' (1 s outage)' if key[3] else '', key[2], len(rs), len(ok), len(rs), fmt(c['completion_s']),
        fmt(c['script_s']), fmt(c['wrist_peak_n'][0]), fmt(c['wrist_rms_n'][0]), fmt(c['wrist_peak_n'][1]),
        fmt(c['wrist_rms_n'][1]), fmt(c['squeeze_peak_n']) if key[0] == 'box' else '-', fmt(c['object_env_peak_n']),
        '%s / %s' % (fmt(c['felt_error_n'][0]), fmt(c['felt_error_n'][1])), energy, fmt(c['servo_compute_p99_us'], '%.0f'), fmt(c['servo_miss_pct'], '%.2f'),
        fmt(c['control_compute_p99_us'], '%.0f'), '; '.join(c['failures']) or '-'))
with open(os.path.join(out, 'table.md'), 'w') as f:
    f.write('\n'.join(lines) + '\n')
with open(os.path.join(out, 'table.json'), 'w') as f:
    json.dump({'cells': table, 'runs': rows}, f, indent=1)
print('\n'.join(lines))
EOF
echo "telemanip_table: done in $((SECONDS - t0)) s: $out/table.md, $out/table.json"
