#!/usr/bin/env bash
# Soak test (not part of CI): both stations through hemm-relay for a long
# run with datagram loss, jitter and outages, the SIMULATED operator driving
# (nav-to-wall: navigation commands at 200 Hz, the robot held at the wall by
# the local model's force). Every 30 s it samples each process's resident
# memory and open file descriptors; the stations log their link and robot
# counters every 30 s. At the end it prints the first and last samples and
# counters side by side (out/soak/summary.txt) and fails if a process died
# or the session was not open at the end.
#
# Usage: deploy/soak.sh [--minutes M] [--build DIR] [--out DIR] [--port-base P]
#   --minutes M    run length (default 30)
#   --build DIR    build with bin/hemm-robot, hemm-operator, hemm-relay (default build/release)
#   --out DIR      logs, samples and summary (default out/soak)
#   --port-base P  robot TCP P, UDP P+1, relay TCP P+2, UDP P+3 (default: a free
#                  random base, so runs do not collide with stations already up)
set -euo pipefail

minutes=30
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$root/build/release"
out="$root/out/soak"
port=""
usage() { sed -n '2,16p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --minutes) minutes="${2:?}"; shift 2 ;;
    --build) build="${2:?}"; shift 2 ;;
    --out) out="${2:?}"; shift 2 ;;
    --port-base) port="${2:?}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "deploy/soak.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$minutes" =~ ^[0-9]+$ && "$minutes" -ge 2 ]] || { echo "deploy/soak.sh: --minutes must be an integer >= 2" >&2; exit 2; }
port_free() { ! (ss -Hltun 2>/dev/null || true) | awk '{print $5}' | grep -Eq ":($1|$(($1 + 1))|$(($1 + 2))|$(($1 + 3)))\$"; }
if [[ -z "$port" ]]; then
  for _ in $(seq 50); do
    port=$((20000 + RANDOM % 40000))
    port_free "$port" && break
  done
fi
[[ "$port" =~ ^[0-9]+$ && "$port" -ge 1024 && "$port" -le 65000 ]] || { echo "deploy/soak.sh: bad --port-base" >&2; exit 2; }
bin="$build/bin"
for b in hemm-robot hemm-operator hemm-relay; do
  [[ -x "$bin/$b" ]] || { echo "deploy/soak.sh: $bin/$b missing (build first: bash deploy/run.sh build)" >&2; exit 2; }
done
mkdir -p "$out"
rm -f "$out"/*.err "$out"/*.out "$out"/*.json "$out"/samples.csv "$out"/summary.txt

secs=$((minutes * 60))
cfg="$root/deploy/configs"
# Outages (relay clock, both directions: datagrams dropped, TCP held) spread
# over the run: 2 s, 5 s and 10 s, then 3 s near the end.
outages=(--outage "$((secs * 15 / 100)):2" --outage "$((secs * 40 / 100)):5" --outage "$((secs * 65 / 100)):10"
         --outage "$((secs * 85 / 100)):3")

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

"$bin/hemm-robot" --config "$cfg/robot.pbtxt" --listen 127.0.0.1 --session-port "$port" --stream-port "$((port + 1))" \
  --duration "$((secs + 60))" --stats-period 30 --stats-json "$out/robot.json" > "$out/robot.out" 2> "$out/robot.err" &
robot=$!
pids+=("$robot")
"$bin/hemm-relay" --tcp-listen "127.0.0.1:$((port + 2))" --tcp-forward "127.0.0.1:$port" \
  --udp-listen "127.0.0.1:$((port + 3))" --udp-forward "127.0.0.1:$((port + 1))" \
  --delay-ms 40 --jitter-ms 5 --jitter-dist normal --loss 0.02 --seed 11 "${outages[@]}" \
  --duration "$((secs + 50))" --stats-json "$out/relay.json" > "$out/relay.out" 2> "$out/relay.err" &
relay=$!
pids+=("$relay")
sleep 3
"$bin/hemm-operator" --config "$cfg/operator.pbtxt" --robot 127.0.0.1 --session-port "$((port + 2))" \
  --stream-port "$((port + 3))" --script nav-to-wall --duration "$secs" --stats-period 30 \
  --stats-json "$out/op.json" > "$out/op.out" 2> "$out/op.err" &
op=$!
pids+=("$op")

rss_kb() { awk '/^VmRSS:/ {print $2}' "/proc/$1/status" 2>/dev/null || echo -; }
fds() { ls "/proc/$1/fd" 2>/dev/null | wc -l; }
echo "t_s,robot_rss_kb,robot_fds,operator_rss_kb,operator_fds,relay_rss_kb,relay_fds" > "$out/samples.csv"
echo "soak: ports $port..$((port + 3)); $minutes min through hemm-relay (2 % loss, 40 +- 5 ms each way, outages ${outages[*]}); output in $out"
start=$(date +%s)
first_stats_robot="" first_stats_op="" first_robot_stats=""
last_stats_robot="" last_stats_op="" last_robot_stats=""
while kill -0 "$op" 2>/dev/null; do
  sleep 30
  t=$(( $(date +%s) - start ))
  kill -0 "$op" 2>/dev/null || break
  kill -0 "$robot" 2>/dev/null || { echo "deploy/soak.sh: hemm-robot died at t=${t}s" >&2; break; }
  echo "$t,$(rss_kb "$robot"),$(fds "$robot"),$(rss_kb "$op"),$(fds "$op"),$(rss_kb "$relay"),$(fds "$relay")" >> "$out/samples.csv"
  if [[ -z "$first_stats_robot" && $t -ge 60 ]]; then
    first_stats_robot="$(grep 'event=stats' "$out/robot.err" | tail -1 || true)"
    first_robot_stats="$(grep 'event=robot_stats' "$out/robot.err" | tail -1 || true)"
    first_stats_op="$(grep 'event=stats' "$out/op.err" | tail -1 || true)"
  fi
  last_stats_robot="$(grep 'event=stats' "$out/robot.err" | tail -1 || true)"
  last_robot_stats="$(grep 'event=robot_stats' "$out/robot.err" | tail -1 || true)"
  last_stats_op="$(grep 'event=stats' "$out/op.err" | tail -1 || true)"
  echo "  t=${t}s $(tail -1 "$out/samples.csv")"
done
set +e
wait "$op"
op_rc=$?
kill -TERM "$robot" "$relay" 2>/dev/null
wait "$robot"
robot_rc=$?
wait "$relay"
set -e
pids=()

field() { tr ' ' '\n' <<< "$1" | awk -F= -v k="$2" '$1 == k {print $2}'; }
{
  echo "soak: $minutes min, hemm-operator exit $op_rc, hemm-robot exit $robot_rc"
  echo "samples (first and last of $(($(wc -l < "$out/samples.csv") - 1))):"
  sed -n '1p;2p;$p' "$out/samples.csv" | awk -F, '{printf "  %-6s %14s %10s %16s %13s %13s %10s\n", $1, $2, $3, $4, $5, $6, $7}'
  echo "counters at ~60 s and at the end:"
  printf '  %-34s %16s %16s\n' counter first last
  for k in sessions_opened link_lost_events link_restored_events received delivered lost late duplicated \
           rejected_bad_tag rejected_replay path_challenges_sent paths_validated path_copies_ignored \
           handshakes_failed rtt_median_ms; do
    printf '  robot %-28s %16s %16s\n' "$k" "$(field "$first_stats_robot" "$k")" "$(field "$last_stats_robot" "$k")"
  done
  for k in sessions_opened link_lost_events link_restored_events received delivered lost sent rtt_median_ms; do
    printf '  operator %-25s %16s %16s\n' "$k" "$(field "$first_stats_op" "$k")" "$(field "$last_stats_op" "$k")"
  done
  for k in commands_received commands_applied commands_stale commands_without_control states_sent scans_sent \
           send_failures late_steps; do
    printf '  robot %-28s %16s %16s\n' "$k" "$(field "$first_robot_stats" "$k")" "$(field "$last_robot_stats" "$k")"
  done
} | tee "$out/summary.txt"
[[ $op_rc -eq 0 && $robot_rc -eq 0 ]] || { echo "deploy/soak.sh: a station failed (see $out/*.err)" >&2; exit 1; }
