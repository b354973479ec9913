#!/usr/bin/env bash
# 6-DoF exploration of the remote table through the live voxmap (issue 13),
# SIMULATION ONLY truth. For each round trip it runs hemm-robot
# (robot_depth.pbtxt: home scene, the robot at W (1.5, 1.0) facing the table,
# SIMULATED mast depth camera), hemm-relay above 0 ms (half the round trip
# each way, 5 % loss each way), and hemm-operator (operator_explore3d.pbtxt:
# the robot's probe tool as a VPS pointshell on the live voxmap, held by a
# SIMULATED rigid 6-DoF scripted hand that presses and slides on the tops and
# the robot-facing sides of the block, the book and the mug); then hemm-truth
# --tool6 replays the logged hand path against a 2.5 mm voxmap of the scene's
# true geometry with the same tool, contact and coupling. Prints the force and
# torque error table and the servo's numbers, and writes the plots.
# --device sim-bimanual holds the tool with the right arm of the SIMULATED
# bimanual device instead (operator_explore3d_bimanual.pbtxt: its SIMULATED
# human follows the same script and yields to the force; the truth replays the
# hand's actual path); output under out/explore3d_bimanual, plot
# DOC/explore3d_bimanual_wrench.png.
#
# Usage: deploy/explore3d.sh BUILD_DIR [--device sim-hand6|sim-bimanual] [--rtts 0,300] [--out DIR] [--doc DIR] [--port-base P] [--views]
# (ports P, P+1 for the robot and P+100, P+101 for the relay; P default 47300;
# --views: both stations write PNGs of their live view every 2 s into
# DIR/<rtt>ms/{operator,robot}_view/, on the caller's X display.)
# Takes about 75 s per round trip. HEMM_EXPLORE3D_OPERATOR_ARGS (words) are
# passed on to hemm-operator, e.g. "--shape-completion-3d off --unknown-solid off".
set -euo pipefail

usage() {
  sed -n '/^# Usage:/s/^# //p' "${BASH_SOURCE[0]}"
  echo "Writes DIR/<rtt>ms/{servo.csv*,truth.csv,truth.json,station.json,timing.png,robot_timing.png}; DOC/explore3d_wrench.png and"
  echo "DOC/explore3d_voxmap.png (DOC default deploy/doc; sim-bimanual: DOC/explore3d_bimanual_wrench.png)."
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
while (($#)); do
  case "$1" in
    --port-base) base="${2:?--port-base needs a port}"; shift 2 ;;
    --device) device="${2:?--device needs sim-hand6 or sim-bimanual}"; shift 2 ;;
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
  *) echo "explore3d: --device '$device': sim-hand6 or sim-bimanual" >&2; exit 2 ;;
esac
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
cfg="$root/deploy/configs"
secs=60  # the explore-table script ends at 58.5 s
mkdir -p "$out" "$doc"

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

run() {  # RTT_MS
  local rtt="$1" dir="$out/${1}ms"
  mkdir -p "$dir"
  local op_view=() robot_view=()
  if ((views)); then
    op_view=(--view-png "$dir/operator_view" --view-interval 2)
    robot_view=(--view-png "$dir/robot_view" --view-interval 2)
  fi
  echo "explore3d: ${rtt} ms round trip$( ((rtt > 0)) && echo ", 5 % loss each way") ($secs s) -> $dir" >&2
  "$bin/hemm-robot" --config "$cfg/robot_depth.pbtxt" --session-port "$base" --stream-port $((base + 1)) \
    --duration $((secs + 10)) --log-level warn --station-json "$dir/robot_station.json" "${robot_view[@]}" \
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
  local rc=0
  "$bin/hemm-operator" --config "$cfg/$opcfg" --session-port "$port" --stream-port "$stream" \
    --log "$dir/servo.csv" --duration "$secs" --log-level warn --station-json "$dir/station.json" "${op_view[@]}" \
    ${HEMM_EXPLORE3D_OPERATOR_ARGS:-} \
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
  /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/station.json" --out "$dir/timing.png" \
    --title "$tag, ${rtt} ms: operator servo loop" >&2
  /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/robot_station.json" --out "$dir/robot_timing.png" \
    --title "$tag, ${rtt} ms: robot control loop" >&2
  echo "explore3d: truth replay (2.5 mm voxmap of the scene) for ${rtt} ms" >&2
  "$bin/hemm-truth" --scene "$root/deploy/scenes/home.xml" --log "$dir/servo.csv.world.csv" \
    --tool6 "$dir/servo.csv.tool6.txt" --csv "$dir/truth.csv" --json "$dir/truth.json" >"$dir/truth.txt"
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
if [[ "$device" == sim-bimanual ]]; then
  /usr/bin/python3 "$root/deploy/plots/plot_explore3d.py" --wrench "$doc/explore3d_bimanual_wrench.png" \
    --title "6-DoF probe tool on the right arm of the SIMULATED bimanual device: block, book, mug (SIMULATION)" \
    "${args[@]}"
  echo "explore3d: wrote $doc/explore3d_bimanual_wrench.png" >&2
else
  /usr/bin/python3 "$root/deploy/plots/plot_explore3d.py" --wrench "$doc/explore3d_wrench.png" \
    --voxmap "$doc/explore3d_voxmap.png" --voxcsv "$out/${first}ms/servo.csv.voxmap.csv" "${args[@]}"
  echo "explore3d: wrote $doc/explore3d_wrench.png and $doc/explore3d_voxmap.png" >&2
fi

/usr/bin/python3 - "$out" "$rtts" <<'PY'
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
    print(f"| {link} | {t['contact_ticks']} | {t['force_rms_n']:.3f} / {t['force_max_n']:.3f} | "
          f"{t['true_force_peak_n']:.2f} | {t['torque_rms_nm']:.4f} / {t['torque_max_nm']:.4f} | "
          f"{t['true_torque_peak_nm']:.3f} | {tm['period_us']['median']} / {tm['period_us']['p99']} | "
          f"{tm['misses']} / {tm['ticks']} | {tm['compute_us']['p99']} |")

# Per feature (the explore-table script's phases, tool6_explorer.cpp): force error RMS over contact ticks.
import csv, math
phases = [("block top", 6, 15), ("block front side", 16, 22.5), ("block left side", 23, 30), ("book top", 32, 40.5),
          ("book front side", 41.5, 46.5), ("mug top", 48.5, 52.5), ("mug front side", 53.5, 58.5)]
print()
print("| link | " + " | ".join(p[0] for p in phases) + " |")
print("|---|" + "--:|" * len(phases))
for r in rtts:
    rows = list(csv.DictReader(open(os.path.join(out, f"{r}ms", "truth.csv"))))
    cells = []
    for name, a, b in phases:
        e2, n, peak = 0.0, 0, 0.0
        for x in rows:
            t = int(x["tick"]) * 1e-3
            if not (a <= t < b) or (x["contacts"] == "0" and x["contacts_true"] == "0"):
                continue
            d = [float(x[k]) - float(x[k.replace("f_", "ft_")]) for k in ("f_x", "f_y", "f_z")]
            e2 += sum(v * v for v in d)
            n += 1
            peak = max(peak, math.sqrt(sum(float(x[k]) ** 2 for k in ("ft_x", "ft_y", "ft_z"))))
        cells.append(f"{math.sqrt(e2 / n):.2f} N of {peak:.1f} N ({n})" if n else "no contact")
    print(f"| {r} ms | " + " | ".join(cells) + " |")
PY
