#!/usr/bin/env bash
# The loopback demo: hemm-robot and hemm-operator on 127.0.0.1, first
# directly, then through hemm-relay with an impaired network (100 ms one-way
# delay, 10 ms jitter, 5 % loss), printing each station's link statistics;
# then three haptic runs with a SIMULATED PHANToM Omni and a scripted hand:
# driving at a wall in navigation mode (HEMM Fig. 8), probing the bin in
# exploration mode (Fig. 9), and a closed-loop navigation to a goal at 300 ms
# round trip; each compared with the scene's ground truth (hemm-truth) and
# plotted to PNG in out/demo/<run>/ (with the deadline histograms of the
# operator's servo loop and the robot's control loop: timing.png,
# robot_timing.png), with pictures of both stations' live views; each run's
# recording exported as MCAP (<run>/session.mcap) and listed by
# deploy/mcap_reader.py.
# Usage: deploy/demo.sh BUILD_DIR [seconds-per-phase]
set -euo pipefail
build="${1:?usage: deploy/demo.sh BUILD_DIR [seconds]}"
secs="${2:-5}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$build/bin"
out="$root/out/demo"
mkdir -p "$out"
cfg="$root/deploy/configs"
for b in hemm-robot hemm-operator hemm-relay hemm-truth; do
  [[ -x "$bin/$b" ]] || { echo "demo: $bin/$b not found (build first: bash deploy/run.sh build)" >&2; exit 2; }
done

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

phase() {
  local name="$1" op_port="$2" op_stream="$3"
  echo
  echo "== $name"
  "$bin/hemm-robot" --config "$cfg/robot.pbtxt" --session-port 47100 --stream-port 47101 \
    --duration $((secs + 3)) --stats-json "$out/$name-robot.json" --log-level warn \
    >"$out/$name-robot.txt" 2>"$out/$name-robot.log" &
  local robot=$!
  pids+=("$robot")
  sleep 0.5
  set +e
  "$bin/hemm-operator" --config "$cfg/operator.pbtxt" --session-port "$op_port" --stream-port "$op_stream" \
    --duration "$secs" --stats-json "$out/$name-operator.json" --log-level info 2>"$out/$name-operator.log"
  local rc=$?
  set -e
  kill -INT "$robot" 2>/dev/null || true
  wait "$robot" 2>/dev/null || true
  echo "-- robot station (its summary at exit):"
  cat "$out/$name-robot.txt"
  if ((rc != 0)); then
    echo "demo: hemm-operator exited with $rc; log: $out/$name-operator.log" >&2
    exit "$rc"
  fi
}

phase direct 47100 47101

"$bin/hemm-relay" --tcp-listen 127.0.0.1:47200 --tcp-forward 127.0.0.1:47100 \
  --udp-listen 127.0.0.1:47201 --udp-forward 127.0.0.1:47101 \
  --delay-ms 100 --jitter-ms 10 --jitter-dist normal --loss 0.05 --seed 7 \
  --stats-json "$out/relay.json" >"$out/relay.txt" 2>"$out/relay.log" &
relay=$!
pids+=("$relay")
for _ in $(seq 50); do grep -q "hemm-relay ready" "$out/relay.txt" 2>/dev/null && break; sleep 0.1; done
phase "relay-100ms-5pct-loss" 47200 47201
kill -INT "$relay" 2>/dev/null || true
wait "$relay" 2>/dev/null || true
echo "-- relay counters:"
grep -v "^stats " "$out/relay.txt" || true

# The live views: both stations write PNGs of their view every 2 s (and a
# last one at exit) into out/demo/<run>/{operator,robot}_view/ (an Xvfb of
# our own without a display: deploy/lib/display.sh).
op_view=() robot_view=()
if "$bin/hemm-operator" --help 2>/dev/null | grep -q -- --view-png; then
  # shellcheck source=deploy/lib/display.sh
  source "$root/deploy/lib/display.sh"
  if hemm_display "$out"; then
    op_view=(--view-png VIEW_DIR/operator_view --view-interval 2)
    robot_view=(--view-png VIEW_DIR/robot_view --view-interval 2)
  else
    echo "demo: no X display and no Xvfb: the runs leave no pictures of the live views"
  fi
fi

# Haptic runs: a fresh robot for each, so it starts at the scene's start pose.
# haptic_run NAME SCRIPT SECONDS [RTT_MS]: with RTT_MS the link goes through
# hemm-relay (half the round trip each way, +-10 % jitter, 5 % loss). After
# each run hemm-truth (SIMULATION ONLY) replays the proxy path against the
# scene's exact geometry and prints the force error; the plots follow.
haptic_run() {
  local name="$1" script="$2" secs_run="$3" rtt="${4:-}"
  local dir="$out/$name"
  echo
  echo "== haptic run: $name (script $script, $secs_run s, simulated Omni, scripted hand${rtt:+, ${rtt} ms round trip through hemm-relay, 5 % loss})"
  mkdir -p "$dir"
  "$bin/hemm-robot" --config "$cfg/robot.pbtxt" --session-port 47100 --stream-port 47101 \
    --duration $((secs_run + 6)) --stats-json "$dir/robot.json" --station-json "$dir/robot_station.json" \
    --log-level warn "${robot_view[@]/VIEW_DIR/$dir}" >"$dir/robot.txt" 2>"$dir/robot.log" &
  local robot=$!
  pids+=("$robot")
  local port=47100 stream=47101 relay_pid=""
  if [[ -n "$rtt" ]]; then
    local one_way=$((rtt / 2))
    "$bin/hemm-relay" --tcp-listen 127.0.0.1:47200 --tcp-forward 127.0.0.1:47100 \
      --udp-listen 127.0.0.1:47201 --udp-forward 127.0.0.1:47101 \
      --delay-ms "$one_way" --jitter-ms $((one_way / 10 + 1)) --jitter-reorder --loss 0.05 --seed 7 \
      --stats-json "$dir/relay.json" >"$dir/relay.txt" 2>"$dir/relay.log" &
    relay_pid=$!
    pids+=("$relay_pid")
    for _ in $(seq 50); do grep -q "hemm-relay ready" "$dir/relay.txt" 2>/dev/null && break; sleep 0.1; done
    port=47200
    stream=47201
  fi
  sleep 1
  set +e
  "$bin/hemm-operator" --config "$cfg/operator.pbtxt" --session-port "$port" --stream-port "$stream" \
    --script "$script" --log "$dir/servo.csv" --duration "$secs_run" --log-level warn \
    --station-json "$dir/station.json" --record "$dir/session.rec" "${op_view[@]/VIEW_DIR/$dir}" \
    >"$dir/operator.txt" 2>"$dir/operator.log"
  local rc=$?
  set -e
  kill -INT "$robot" 2>/dev/null || true
  wait "$robot" 2>/dev/null || true
  if [[ -n "$relay_pid" ]]; then
    kill -INT "$relay_pid" 2>/dev/null || true
    wait "$relay_pid" 2>/dev/null || true
  fi
  tail -n 26 "$dir/operator.txt"
  if ((rc != 0)); then
    echo "demo: hemm-operator exited with $rc; log: $dir/operator.log" >&2
    exit "$rc"
  fi
  grep -E "steps touching|collision guard" "$dir/robot.txt" || true
  # The whole session replayed from its recording as fast as it goes: the
  # forces tick for tick against the recorded ones.
  "$bin/hemm-operator" --replay "$dir/session.rec" --replay-speed 0 --replay-json "$dir/replay.json" --log-level warn
  # The session as MCAP (Foxglove Studio or any MCAP reader opens it;
  # docs/recording.md), checked and listed by a reader written from the MCAP
  # specification, and replayed from it: the same forces.
  "$bin/hemm-operator" --export-mcap "$dir/session.rec" "$dir/session.mcap" >"$dir/mcap.txt"
  /usr/bin/python3 "$root/deploy/mcap_reader.py" "$dir/session.mcap"
  "$bin/hemm-operator" --replay "$dir/session.mcap" --replay-speed 0 --replay-json "$dir/replay-mcap.json" \
    --log-level warn
  "$bin/hemm-truth" --scene "$root/deploy/scenes/home.xml" --log "$dir/servo.csv.world.csv" \
    --csv "$dir/truth.csv" --json "$dir/truth.json"
  /usr/bin/python3 "$root/deploy/plots/plot_run.py" "$dir/servo.csv" --out "$dir" --title "$name" \
    --truth "$dir/truth.csv"
  # The deadline histograms of both 1 kHz loops (and the SIMULATED Omni's own thread).
  /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/station.json" --out "$dir/timing.png" \
    --title "$name: operator servo loop"
  /usr/bin/python3 "$root/deploy/plots/plot_timing.py" "$dir/robot_station.json" --out "$dir/robot_timing.png" \
    --title "$name: robot control loop"
}
haptic_run nav-to-wall nav-to-wall 14              # HEMM Fig. 8
haptic_run probe-cylinder probe-cylinder 19        # HEMM Fig. 9
haptic_run nav-to-goal-300ms nav-to-goal 30 300    # closed-loop navigation at 300 ms round trip

echo
echo "demo: outputs in $out (PNG plots in $out/nav-to-wall, $out/probe-cylinder, $out/nav-to-goal-300ms;"
echo "      the live views' pictures in <run>/operator_view/ and <run>/robot_view/, each session's recording"
echo "      in <run>/session.rec, as MCAP in <run>/session.mcap, its replays' results in <run>/replay.json and"
echo "      <run>/replay-mcap.json)"
