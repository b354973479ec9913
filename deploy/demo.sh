#!/usr/bin/env bash
# The loopback demo: hemm-robot and hemm-operator on 127.0.0.1, first
# directly, then through hemm-relay with an impaired network (100 ms one-way
# delay, 10 ms jitter, 5 % loss), printing each station's link statistics;
# then two haptic runs with a SIMULATED PHANToM Omni and a scripted hand
# (HEMM Figs. 8 and 9): driving at a wall in navigation mode, and probing the
# bin in exploration mode, each plotted to PNG in out/demo/<run>/.
# Usage: deploy/demo.sh BUILD_DIR [seconds-per-phase]
set -euo pipefail
build="${1:?usage: deploy/demo.sh BUILD_DIR [seconds]}"
secs="${2:-5}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$build/bin"
out="$root/out/demo"
mkdir -p "$out"
cfg="$root/deploy/configs"
for b in hemm-robot hemm-operator hemm-relay; do
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

# Haptic runs: a fresh robot for each, so it starts at the scene's start pose.
haptic_run() {
  local name="$1" secs_run="$2"
  echo
  echo "== haptic run: $name ($secs_run s, simulated Omni, scripted hand)"
  mkdir -p "$out/$name"
  "$bin/hemm-robot" --config "$cfg/robot.pbtxt" --session-port 47100 --stream-port 47101 \
    --duration $((secs_run + 4)) --log-level warn >"$out/$name/robot.txt" 2>"$out/$name/robot.log" &
  local robot=$!
  pids+=("$robot")
  sleep 1
  set +e
  "$bin/hemm-operator" --config "$cfg/operator.pbtxt" --session-port 47100 --stream-port 47101 \
    --script "$name" --log "$out/$name/servo.csv" --duration "$secs_run" --log-level warn \
    >"$out/$name/operator.txt" 2>"$out/$name/operator.log"
  local rc=$?
  set -e
  kill -INT "$robot" 2>/dev/null || true
  wait "$robot" 2>/dev/null || true
  tail -n 25 "$out/$name/operator.txt"
  if ((rc != 0)); then
    echo "demo: hemm-operator exited with $rc; log: $out/$name/operator.log" >&2
    exit "$rc"
  fi
  /usr/bin/python3 "$root/deploy/plots/plot_run.py" "$out/$name/servo.csv" --out "$out/$name" --title "$name"
}
haptic_run nav-to-wall 14
haptic_run probe-cylinder 18

echo
echo "demo: outputs in $out (PNG plots in $out/nav-to-wall and $out/probe-cylinder)"
