#!/usr/bin/env bash
# 6-DoF exploration of a remote table through the live voxmap (issue 13),
# SIMULATION ONLY truth. The scene (--scene: home, table_round, table_mixed
# or an MJCF file; home by default) carries its own route in its header
# comment (explore6 lines, deploy/scenes/README.md "Exploration routes"): the
# SIMULATED hand's key poses, each naming the feature it explores, the robot
# start they assume and the truth region. For each round trip it runs
# hemm-robot (robot_depth.pbtxt on that scene, started where the header says,
# SIMULATED mast depth camera), hemm-relay above 0 ms (half the round trip
# each way, 5 % loss each way), and hemm-operator (operator_explore3d.pbtxt:
# the robot's probe tool as a VPS pointshell on the live voxmap, held by a
# SIMULATED rigid 6-DoF scripted hand following the route); then hemm-truth
# --tool6 replays the logged hand path against a 2.5 mm voxmap of the
# scene's true geometry in the header's region with the same tool, contact
# and coupling. Prints the force and torque error table, the per-feature
# table (the route's features) and the servo's numbers, and writes the plots.
# --device sim-bimanual holds the tool with the right arm of the SIMULATED
# bimanual device instead (operator_explore3d_bimanual.pbtxt: its SIMULATED
# human follows the same route and yields to the force; the truth replays the
# hand's actual path); output under out/explore3d_bimanual, plot
# DOC/explore3d_bimanual_wrench.png.
# Variants (deploy/explore3d_table.sh runs them): --operator-config and
# --robot-config replace the two configs (the route, the scene and the start
# are still given on the command line), --operator-arg / --robot-arg pass one
# more argument each (repeat them), --label names the variant in the output.
# --head (issue 24): the robot's camera on its SIMULATED pan-tilt head
# (robot_depth_head.pbtxt) turned by the operator's gaze
# (operator_explore3d_gaze.pbtxt; sim-hand6 only); output under
# out/explore3d_head[_SCENE].
# --device sim-omni (issue 24 part 4): the 3-DoF point probe instead
# (operator_explore3d_omni.pbtxt: the SIMULATED Omni whose hand follows the
# scene's explore3 route, hemm-operator --hand3-route/--hand3-script), the
# truth hemm-truth --probe3 (the logged device path, the same point-probe
# contact model, against the same 2.5 mm voxmap of the scene); prints the
# force error table and the per-feature table; output under
# out/explore3d_omni[_SCENE], no wrench plot.
#
# --shape-log (issue 24): the operator writes each rebuild's accepted 3D
# primitives and their input cells to DIR/<rtt>ms/shapes/ (hemm-operator
# --shape-log); deploy/explore3d_shapes.py compares them with the scene.
#
# Usage: deploy/explore3d.sh BUILD_DIR [--shape-log] [--scene NAME|FILE] [--route NAME] [--device sim-hand6|sim-bimanual|sim-omni] [--head] [--rtts 0,300] [--out DIR] [--doc DIR] [--port-base P] [--views] [--no-plots] [--operator-config FILE] [--robot-config FILE] [--operator-arg ARG]... [--robot-arg ARG]... [--label TEXT]
# (ports P, P+1 for the robot and P+100, P+101 for the relay; P default 47300;
# --views: both stations write PNGs of their live view every 2 s into
# DIR/<rtt>ms/{operator,robot}_view/, on the caller's X display.)
# Takes about the route's length plus a minute per round trip (home: ~2.5 min).
set -euo pipefail

usage() {
  sed -n '/^# Usage:/s/^# //p' "${BASH_SOURCE[0]}"
  echo "Writes DIR/route.txt, DIR/<rtt>ms/{servo.csv*,truth.csv,truth.json,station.json,timing.png,robot_timing.png}; DOC/explore3d_wrench.png"
  echo "and DOC/explore3d_voxmap.png (DOC default deploy/doc; another scene: DOC/explore3d_<scene>_*.png; sim-bimanual:"
  echo "DOC/explore3d_bimanual_wrench.png). DIR default out/explore3d (another scene: out/explore3d_<scene>)."
}
build="${1:-}"
if [[ -z "$build" || "$build" == -h || "$build" == --help ]]; then usage; [[ -n "$build" ]] && exit 0 || exit 2; fi
shift
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rtts="0,300"
out=""
doc="$root/deploy/doc"
device="sim-hand6"
base=47300
views=0
head=0
plots=1
shape_log=0
scene=home
route=explore-table
opcfg_arg="" robotcfg_arg="" label=""
op_extra=() robot_extra=()
while (($#)); do
  case "$1" in
    --scene) scene="${2:?--scene needs a name or an MJCF file}"; shift 2 ;;
    --route) route="${2:?--route needs a route name}"; shift 2 ;;
    --operator-config) opcfg_arg="${2:?--operator-config needs a file}"; shift 2 ;;
    --robot-config) robotcfg_arg="${2:?--robot-config needs a file}"; shift 2 ;;
    --operator-arg) op_extra+=("${2?--operator-arg needs an argument}"); shift 2 ;;
    --robot-arg) robot_extra+=("${2?--robot-arg needs an argument}"); shift 2 ;;
    --label) label="${2:?--label needs a text}"; shift 2 ;;
    --no-plots) plots=0; shift ;;
    --shape-log) shape_log=1; shift ;;
    --head) head=1; shift ;;
    --port-base) base="${2:?--port-base needs a port}"; shift 2 ;;
    --device) device="${2:?--device needs sim-hand6, sim-bimanual or sim-omni}"; shift 2 ;;
    --views) views=1; shift ;;
    --rtts) rtts="${2:?--rtts needs a list}"; shift 2 ;;
    --out) out="${2:?--out needs a directory}"; shift 2 ;;
    --doc) doc="${2:?--doc needs a directory}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "explore3d: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
case "$device" in
  sim-hand6) opcfg="operator_explore3d.pbtxt"; tag="explore3d" ;;
  sim-bimanual) opcfg="operator_explore3d_bimanual.pbtxt"; tag="explore3d_bimanual" ;;
  sim-omni) opcfg="operator_explore3d_omni.pbtxt"; tag="explore3d_omni" ;;
  *) echo "explore3d: --device '$device': sim-hand6, sim-bimanual or sim-omni" >&2; exit 2 ;;
esac
robotcfg="robot_depth.pbtxt"
if ((head)); then
  [[ "$device" == sim-hand6 ]] || { echo "explore3d: --head needs --device sim-hand6" >&2; exit 2; }
  robotcfg="robot_depth_head.pbtxt"; opcfg="operator_explore3d_gaze.pbtxt"; tag="explore3d_head"
fi
if [[ "$scene" == *.xml ]]; then scene_file="$scene"; else scene_file="$root/deploy/scenes/$scene.xml"; fi
[[ -f "$scene_file" ]] || { echo "explore3d: --scene '$scene': no $scene_file (home, table_round, table_mixed or an MJCF file)" >&2; exit 2; }
scene_file="$(cd "$(dirname "$scene_file")" && pwd)/$(basename "$scene_file")"
scene_name="$(basename "$scene_file" .xml)"
[[ "$scene_name" == home ]] || tag="${tag}_$scene_name"
opcfg_file="$root/deploy/configs/$opcfg"
robotcfg_file="$root/deploy/configs/$robotcfg"
for f in "$opcfg_arg" "$robotcfg_arg"; do
  [[ -z "$f" || -f "$f" ]] || { echo "explore3d: config '$f' not found" >&2; exit 2; }
done
[[ -n "$opcfg_arg" ]] && opcfg_file="$opcfg_arg"
[[ -n "$robotcfg_arg" ]] && robotcfg_file="$robotcfg_arg"
out="${out:-$root/out/$tag}"
bin="$build/bin"
for b in hemm-robot hemm-operator hemm-relay hemm-truth; do
  [[ -x "$bin/$b" ]] || { echo "explore3d: $bin/$b not found (build first: bash deploy/run.sh build)" >&2; exit 2; }
done
[[ "$base" =~ ^[0-9]+$ ]] && ((base >= 1024 && base <= 65000)) || { echo "explore3d: --port-base '$base': 1024..65000" >&2; exit 2; }
for r in ${rtts//,/ }; do
  [[ "$r" =~ ^[0-9]+$ ]] || { echo "explore3d: --rtts '$rtts': round trips are whole milliseconds" >&2; exit 2; }
done
[[ -x /usr/bin/python3 ]] || { echo "explore3d: /usr/bin/python3 not found (apt-get install python3-matplotlib)" >&2; exit 2; }
mkdir -p "$out" "$doc"
# The route as the operator reads it (checked against the SIMULATED hand's
# reach): the robot's start, the truth region, its end, its features.
hand6=(--hand6-route "$scene_file" --hand6-script "$route")
print_route=--print-hand6-route
truth_tool=(--tool6)  # + the run's tool file (run below)
# ---- --device sim-omni (issue 24 part 4): the 3-DoF route and its truth.
if [[ "$device" == sim-omni ]]; then
  hand6=(--hand3-route "$scene_file" --hand3-script "$route")
  print_route=--print-hand3-route
  truth_tool=(--probe3 "$opcfg_file")
  plots_wrench=0
fi
# ---- end sim-omni
"$bin/hemm-operator" --config "$opcfg_file" "${hand6[@]}" "${op_extra[@]}" "$print_route" >"$out/route.txt" \
  || { echo "explore3d: the route '$route' of $scene_file does not load (above)" >&2; exit 2; }
read -r _ sx sy st < <(grep '^start ' "$out/route.txt")
read -r _ r0 r1 r2 r3 r4 r5 < <(grep '^region ' "$out/route.txt")
read -r _ end_s < <(grep '^end ' "$out/route.txt")
secs=$(( ${end_s%.*} + 2 ))  # past the route's last key (home's explore-table: 58.5 s -> 60 s)
printf '%s\n' "${label:-main}" >"$out/label.txt"
echo "explore3d: scene $scene_name, route $route (${end_s} s), robot at W ($sx, $sy, $st)${label:+, variant: $label}" >&2

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

run() {  # RTT_MS
  local rtt="$1" dir="$out/${1}ms"
  mkdir -p "$dir"
  local op_view=() robot_view=() op_log=()
  if ((shape_log)); then
    mkdir -p "$dir/shapes"
    rm -f "$dir/shapes/"cells_*.f32
    op_log=(--shape-log "$dir/shapes")
  fi
  if ((views)); then
    op_view=(--view-png "$dir/operator_view" --view-interval 2)
    robot_view=(--view-png "$dir/robot_view" --view-interval 2)
  fi
  echo "explore3d: ${rtt} ms round trip$( ((rtt > 0)) && echo ", 5 % loss each way") ($secs s) -> $dir" >&2
  "$bin/hemm-robot" --config "$robotcfg_file" --scene "$scene_file" --start "$sx,$sy,$st" \
    --session-port "$base" --stream-port $((base + 1)) \
    --duration $((secs + 10)) --log-level warn --station-json "$dir/robot_station.json" "${robot_view[@]}" \
    "${robot_extra[@]}" \
    >"$dir/robot.txt" 2>"$dir/robot.log" &
  local robot=$! relay="" port="$base" stream=$((base + 1))
  pids+=("$robot")
  if ((rtt > 0)); then
    local one_way=$((rtt / 2))
    "$bin/hemm-relay" --tcp-listen 127.0.0.1:$((base + 100)) --tcp-forward 127.0.0.1:"$base" \
      --udp-listen 127.0.0.1:$((base + 101)) --udp-forward 127.0.0.1:$((base + 1)) \
      --delay-ms "$one_way" --loss 0.05 --seed 13 >"$dir/relay.txt" 2>"$dir/relay.log" &
    relay=$!
    pids+=("$relay")
    for _ in $(seq 50); do grep -q "hemm-relay ready" "$dir/relay.txt" 2>/dev/null && break; sleep 0.1; done
    grep -q "hemm-relay ready" "$dir/relay.txt" || { echo "explore3d: hemm-relay did not start ($dir/relay.log)" >&2; return 1; }
    port=$((base + 100))
    stream=$((base + 101))
  fi
  sleep 1
  # A robot that did not start (its port taken by another run on this machine)
  # must not leave the operator to connect to whatever listens there.
  kill -0 "$robot" 2>/dev/null || { echo "explore3d: hemm-robot did not start: $(tail -n 1 "$dir/robot.log")" >&2; return 1; }
  local rc=0
  "$bin/hemm-operator" --config "$opcfg_file" "${hand6[@]}" --session-port "$port" --stream-port "$stream" \
    --log "$dir/servo.csv" --duration "$secs" --log-level warn --station-json "$dir/station.json" "${op_view[@]}" \
    "${op_log[@]}" "${op_extra[@]}" \
    >"$dir/operator.txt" 2>"$dir/operator.log" || rc=$?
  kill -INT "$robot" 2>/dev/null || true
  wait "$robot" 2>/dev/null || true
  if [[ -n "$relay" ]]; then
    kill -INT "$relay" 2>/dev/null || true
    wait "$relay" 2>/dev/null || true
  fi
  if ((rc != 0)); then
    echo "explore3d: hemm-operator exited with $rc ($dir/operator.log)" >&2
    return "$rc"
  fi
  # The deadline histograms of the servo loop (and the SIMULATED device's own thread) and the robot's control loop.
  ((plots)) && /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/station.json" --out "$dir/timing.png" \
    --title "$tag, ${rtt} ms: operator servo loop" >&2
  ((plots)) && /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/robot_station.json" --out "$dir/robot_timing.png" \
    --title "$tag, ${rtt} ms: robot control loop" >&2
  echo "explore3d: truth replay (2.5 mm voxmap of the scene) for ${rtt} ms" >&2
  local tt=("${truth_tool[@]}")
  [[ "${tt[0]}" == --tool6 ]] && tt+=("$dir/servo.csv.tool6.txt")
  "$bin/hemm-truth" --scene "$scene_file" --region "$r0" "$r1" "$r2" "$r3" "$r4" "$r5" --log "$dir/servo.csv.world.csv" \
    "${tt[@]}" --csv "$dir/truth.csv" --json "$dir/truth.json" >"$dir/truth.txt"
  cat "$dir/truth.txt" >&2
}

for r in ${rtts//,/ }; do run "$r"; done

first="${rtts%%,*}"
args=()
for r in ${rtts//,/ }; do
  label="${r} ms"
  ((r > 0)) && label="$r ms round trip, 5 % loss each way" || label="0 ms (direct)"
  args+=(--run "$label=$out/${r}ms/truth.csv")
done
png="$tag"
# home keeps its image (the table top); another scene: its truth region, seen from behind the robot.
plot_view=()
[[ "$scene_name" == home ]] || plot_view=(--region "$r0" "$r1" 0.70 "$r3" "$r4" 0.95 --heading "$(awk -v t="$st" 'BEGIN {printf "%.1f", t * 180 / 3.141592653589793}')")
if ((!plots)) || ((!${plots_wrench:-1})); then
  :
elif [[ "$device" == sim-bimanual ]]; then
  /usr/bin/python3 "$root/deploy/plots/plot_explore3d.py" --wrench "$doc/${png}_wrench.png" \
    --title "6-DoF tool on the SIMULATED bimanual device's right arm: $scene_name (SIMULATION)" \
    "${args[@]}"
  echo "explore3d: wrote $doc/${png}_wrench.png" >&2
else
  /usr/bin/python3 "$root/deploy/plots/plot_explore3d.py" --wrench "$doc/${png}_wrench.png" \
    --title "6-DoF probe tool on the live voxmap: $scene_name table (SIMULATION)" \
    --voxmap "$doc/${png}_voxmap.png" --voxcsv "$out/${first}ms/servo.csv.voxmap.csv" "${args[@]}" \
    "${plot_view[@]}"
  echo "explore3d: wrote $doc/${png}_wrench.png and $doc/${png}_voxmap.png" >&2
fi

/usr/bin/python3 - "$out" "$rtts" "$device" <<'PY'
import json, os, sys
out, rtts = sys.argv[1], sys.argv[2].split(",")
print("| link | contact ticks | force error RMS / max N | true force peak N | torque error RMS / max N m | "
      "true torque peak N m | servo period median / p99 us | misses / ticks | compute p99 us |")
print("|---|--:|--:|--:|--:|--:|--:|--:|--:|")
for r in rtts:
    t = json.load(open(os.path.join(out, f"{r}ms", "truth.json")))
    s = json.load(open(os.path.join(out, f"{r}ms", "station.json")))
    tm = s.get("timing", {})
    link = "direct, 0 ms" if r == "0" else f"hemm-relay, {r} ms RTT, 5 % loss each way"
    if sys.argv[3] == "sim-omni":  # the point probe renders no torque
        t["torque_rms_nm"] = t["torque_max_nm"] = t["true_torque_peak_nm"] = float("nan")
    print(f"| {link} | {t['contact_ticks']} | {t['force_rms_n']:.3f} / {t['force_max_n']:.3f} | "
          f"{t['true_force_peak_n']:.2f} | {t['torque_rms_nm']:.4f} / {t['torque_max_nm']:.4f} | "
          f"{t['true_torque_peak_nm']:.3f} | {tm['period_us']['median']} / {tm['period_us']['p99']} | "
          f"{tm['misses']} / {tm['ticks']} | {tm['compute_us']['p99']} |")

PY

# Per feature (the route's features, from its header): force error RMS over each one's contact ticks.
echo
feat=()
for r in ${rtts//,/ }; do feat+=(--run "$r ms=$out/${r}ms"); done
/usr/bin/python3 "$root/deploy/report_tables.py" explore3d-features "$out/route.txt" "${feat[@]}"
