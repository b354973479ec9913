#!/usr/bin/env bash
# Demos of hemm's other parts, each a few minutes, without a network or a
# real device (everything here is SIMULATED):
#   bimanual   the SIMULATED bimanual device (two 7-DoF arms) with its
#              `features` hand script, and its workspace (reachability) map
#   vps        the Voxmap-PointShell engine with a device in the loop: the
#              bimanual paper's peg-in-hole and assembly scenes, with rigid
#              scripted hands and with the SIMULATED bimanual device, and a
#              3-DoF tool on the SIMULATED Omni
#   explore3d  the robot's SIMULATED depth camera building a live voxmap that
#              the operator feels with the robot's probe tool (6-DoF, VPS),
#              held by a rigid scripted hand and by one arm of the SIMULATED
#              bimanual device, each compared with the scene's true geometry
#   telemanip  the SIMULATED bimanual device driving the SIMULATED two-arm
#              robot through the link (hemm-robot kind "twoarm"): the demo
#              route at 0 ms and through hemm-relay at 1000 ms round trip with
#              5 % loss, forces from the live voxmap of the robot's head camera
# Each writes into a fresh directory (default out/demo-PART-<UTC time>), with
# the plots, the live views' pictures (an Xvfb of its own without a display)
# and the logs, and lists its files at the end (also in DIR/FILES.txt).
# Usage: deploy/demo_parts.sh PART BUILD_DIR [--out DIR]
set -euo pipefail

usage() { sed -n '2,21p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
part="${1:-}"
case "$part" in
  bimanual|vps|explore3d|telemanip) ;;
  -h|--help) usage; exit 0 ;;
  *) usage >&2; echo "demo: unknown part '${part}' (bimanual, vps, explore3d or telemanip)" >&2; exit 2 ;;
esac
build="${2:?usage: deploy/demo_parts.sh PART BUILD_DIR [--out DIR]}"
shift 2
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/out/demo-$part-$(date -u +%Y%m%dT%H%M%SZ)"
while (($#)); do
  case "$1" in
    --out) out="${2:?--out needs a directory}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "demo $part: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bin="$build/bin"
cfg="$root/deploy/configs"
py=/usr/bin/python3
need=(hemm-operator)
case "$part" in
  bimanual) need+=(hemm-bimanual-workspace) ;;
  vps) need+=(hemm-vps) ;;
  explore3d) need+=(hemm-robot hemm-relay hemm-truth) ;;
  telemanip) need+=(hemm-robot hemm-relay) ;;
esac
for b in "${need[@]}"; do
  [[ -x "$bin/$b" ]] || { echo "demo $part: $bin/$b not found (build first: bash deploy/run.sh build)" >&2; exit 2; }
done
[[ -x "$py" ]] || { echo "demo $part: $py not found (apt-get install python3-matplotlib)" >&2; exit 2; }
if [[ -e "$out" && -n "$(ls -A "$out" 2>/dev/null)" ]]; then
  echo "demo $part: $out exists and is not empty; give a fresh --out DIR" >&2
  exit 2
fi
mkdir -p "$out"
out="$(cd "$out" && pwd)"

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
t0=$SECONDS
step() { echo "== [$((SECONDS - t0)) s] $*"; }
# files: "relative path<TAB>what it is", listed at the end.
files=()
note() { files+=("$1"$'\t'"$2"); }
fail() { echo "demo $part: $*" >&2; exit 1; }

# The live views: PNGs every VIEW_S seconds and one at exit.
# shellcheck source=deploy/lib/display.sh
source "$root/deploy/lib/display.sh"
have_view=0
if hemm_display "$out"; then have_view=1; else echo "demo $part: no X display and no Xvfb: no pictures of the live views"; fi
view() {  # DIR SECONDS -> the options, or nothing without a display
  ((have_view)) && printf '%s\n' --view-png "$1" --view-interval "$2"
  return 0
}
# operator NAME [hemm-operator options...]: one run without a robot into
# $out/NAME/ (servo.csv log, station.json, view/), its output in operator.txt.
operator() {
  local name="$1"; shift
  local dir="$out/$name" rc=0
  mkdir -p "$dir"
  local v; mapfile -t v < <(view "$dir/view" 1)
  "$bin/hemm-operator" "$@" --log "$dir/servo.csv" --station-json "$dir/station.json" --log-level warn "${v[@]}" \
    >"$dir/operator.txt" 2>"$dir/operator.log" || rc=$?
  ((rc == 0)) || fail "hemm-operator ($name) exited with $rc; see $dir/operator.log"
  grep -E "ticks|period|misses" "$dir/operator.txt" | head -n 3 | sed 's/^/   /' || true
  note "$name/servo.csv" "the 1 kHz servo log of the run (and servo.csv.* beside it)"
  note "$name/station.json" "the station's summary: servo timing, device, task"
  note "$name/operator.txt" "the run's summary as hemm-operator printed it at the end"
  ((have_view)) && note "$name/view/" "pictures of the live view (a PNG every second and one at exit)"
  return 0
}

case "$part" in
bimanual)
  step "bimanual: the SIMULATED device, features script (14 s): elbows, planes, midline, torque, grip, dead-man, clutch"
  operator bimanual --config "$cfg/operator_bimanual.pbtxt"
  "$py" "$root/deploy/plots/plot_bimanual.py" "$out/bimanual/servo.csv" --out "$out/bimanual" \
    || fail "plot_bimanual.py failed"
  note "bimanual/bimanual_run.png" "both hands over time: position, force/torque, handle inputs, brakes/dead-man/clutch"
  step "bimanual: reachability index of both arms on a 10 cm grid (about a minute of CPU)"
  mkdir -p "$out/workspace"
  "$bin/hemm-bimanual-workspace" -o "$out/workspace/reachability.csv" --step 0.1 >"$out/workspace/workspace.txt" 2>&1 \
    || fail "hemm-bimanual-workspace failed; see $out/workspace/workspace.txt"
  "$py" "$root/deploy/plots/plot_reachability.py" "$out/workspace/reachability.csv" --out "$out/workspace" \
    || fail "plot_reachability.py failed"
  note "workspace/reachability.csv" "reachability index per grid point and arm (frame D)"
  note "workspace/bimanual_reachability.png" "the workspace as in the bimanual paper's Fig. 2: each arm and the overlap"
  ;;
vps)
  step "vps: writing the two scenes' meshes and scripted hands (peg-in-hole; assembly, 1.07 M triangles)"
  mkdir -p "$out/vps"
  "$bin/hemm-vps" scene --name peg-in-hole --out "$out/vps" >"$out/vps/scenes.txt" 2>&1 \
    && "$bin/hemm-vps" scene --name assembly --bosses 13 --out "$out/vps" >>"$out/vps/scenes.txt" 2>&1 \
    || fail "hemm-vps scene failed; see $out/vps/scenes.txt"
  note "vps/" "the scenes' meshes (STL), scripted hands (*-hands.csv) and the voxmap/pointshell caches (*.vps)"
  # The shipped configs name the meshes under out/vps; the demo's copies
  # name this run's, so the caches are written here and nowhere else.
  mkdir -p "$out/configs"
  for c in peg assembly peg_bimanual assembly_bimanual omni; do
    sed "s#\"\\.\\./\\.\\./out/vps/#\"$out/vps/#" "$cfg/operator_vps_$c.pbtxt" >"$out/configs/operator_vps_$c.pbtxt"
    grep -q "$out/vps/" "$out/configs/operator_vps_$c.pbtxt" || fail "operator_vps_$c.pbtxt names no mesh under ../../out/vps/"
  done
  note "configs/" "the shipped VPS configs with their meshes in vps/"
  run_vps() {  # NAME CONFIG TITLE WHAT_TAKES_TIME [options]
    local name="$1" c="$2" title="$3" slow="$4"; shift 4
    step "vps: $title${slow:+ ($slow)}"
    operator "$name" --config "$out/configs/operator_vps_$c.pbtxt" "$@"
    "$py" "$root/deploy/plots/plot_vps.py" "$out/$name/servo.csv" --out "$out/$name" --title "$title" \
      || fail "plot_vps.py ($name) failed"
    note "$name/servo.csv.wrench.png" "force and torque on each hand over time"
    note "$name/servo.csv.contact.png" "penetration per pair, the passivity observer's energy, VPS time per tick"
  }
  run_vps peg peg "peg-in-hole, rigid scripted hands" "builds the scene's voxmaps first"
  run_vps peg-bimanual peg_bimanual "peg-in-hole, SIMULATED bimanual device" ""
  run_vps assembly assembly "assembly (1.07 M triangles), rigid scripted hands" "builds the scene's voxmaps first, ~30 s"
  run_vps assembly-bimanual assembly_bimanual "assembly, SIMULATED bimanual device" ""
  run_vps omni omni "8 mm ball on the SIMULATED Omni over the holes block" "" --duration 4
  ;;
explore3d)
  xo=()
  ((have_view)) && xo=(--views)
  for dev in sim-hand6 sim-bimanual; do
    mkdir -p "$out/$dev"
    step "explore3d: live voxmap and the 6-DoF probe tool, $dev, 0 ms (about 2 min: a 60 s run, then the truth replay)"
    "$root/deploy/explore3d.sh" "$build" --device "$dev" --rtts 0 --out "$out/$dev" --doc "$out/$dev" "${xo[@]}" \
      >"$out/$dev/table.md" 2>"$out/$dev/explore3d.log" || { cat "$out/$dev/explore3d.log" >&2; fail "explore3d.sh ($dev) failed"; }
    sed 's/^/   /' "$out/$dev/table.md" | head -n 3
    note "$dev/table.md" "$dev: force and torque error against the true scene, overall and per feature"
    note "$dev/0ms/" "$dev: the run's logs (servo.csv*, station.json) and the truth replay (truth.csv, truth.json)"
    ((have_view)) && note "$dev/0ms/operator_view/" "$dev: the operator station's live view (voxmap, tool, force) every 2 s"
    ((have_view)) && note "$dev/0ms/robot_view/" "$dev: the robot station's view of the SIMULATED scene every 2 s"
  done
  note "sim-hand6/explore3d_wrench.png" "|F| and |torque| against time, live voxmap and true scene (rigid hand)"
  note "sim-hand6/explore3d_voxmap.png" "the live voxmap's surface voxels with the tool tip's path"
  note "sim-bimanual/explore3d_bimanual_wrench.png" "the same wrench plot with the tool on the SIMULATED bimanual device"
  ;;
telemanip)
  # Ports P, P+1 (robot) and P+100, P+101 (relay), away from the other demos'.
  base=47650
  abin="$(cd "$bin" && pwd)"  # the stations run in the configs' folder (their relative paths)
  for rtt in 0 1000; do
    dir="$out/${rtt}ms"
    mkdir -p "$dir"
    step "telemanip: both hands drive the two-arm robot, ${rtt} ms round trip (about 25 s)"
    rv=()
    mapfile -t rv < <(view "$dir/robot_view" 5)
    (cd "$cfg" && "$abin/hemm-robot" --config robot_twoarm.pbtxt --session-port "$base" --stream-port $((base + 1)) \
      --duration 30 --log-level warn "${rv[@]}" --stats-json "$dir/robot.json" >"$dir/robot.txt" 2>"$dir/robot.log") &
    robot=$!
    pids+=("$robot")
    port=$base stream=$((base + 1))
    if ((rtt > 0)); then
      "$bin/hemm-relay" --tcp-listen 127.0.0.1:$((base + 100)) --tcp-forward 127.0.0.1:"$base" \
        --udp-listen 127.0.0.1:$((base + 101)) --udp-forward 127.0.0.1:$((base + 1)) \
        --delay-ms $((rtt / 2)) --loss 0.05 --seed 13 >"$dir/relay.txt" 2>"$dir/relay.log" &
      pids+=("$!")
      for _ in $(seq 50); do grep -q "hemm-relay ready" "$dir/relay.txt" 2>/dev/null && break; sleep 0.1; done
      grep -q "hemm-relay ready" "$dir/relay.txt" || fail "hemm-relay did not start ($dir/relay.log)"
      port=$((base + 100)) stream=$((base + 101))
    fi
    sleep 2
    kill -0 "$robot" 2>/dev/null || fail "hemm-robot did not start: $(tail -n 1 "$dir/robot.log")"
    rc=0
    (cd "$cfg" && "$abin/hemm-operator" --config operator_telemanip.pbtxt --key demo.key --session-port "$port" \
      --stream-port "$stream" --duration 20 --log-level warn --stats-json "$dir/station.json" \
      >"$dir/operator.txt" 2>"$dir/operator.log") || rc=$?
    ((rc == 0)) || fail "hemm-operator (telemanip, $rtt ms) exited with $rc; see $dir/operator.log"
    kill -INT "$robot" 2>/dev/null || true
    wait "$robot" 2>/dev/null || true
    head -n 3 "$dir/operator.txt" | sed 's/^/   /'
    grep -E "commands|applied" "$dir/robot.txt" | head -n 2 | sed 's/^/   robot: /' || true
    note "${rtt}ms/station.json" "the operator's telemanip report: commands, refusals seen, per-hand rendered force, servo timing"
    note "${rtt}ms/robot.json" "the two-arm station's report: commands applied and refused, both controllers' compute, energies"
    note "${rtt}ms/operator.txt" "the operator's summary as hemm-operator printed it"
    if ((${#rv[@]})); then
      note "${rtt}ms/robot_view/" "the two-arm station's live view every 5 s (SIMULATION ONLY truth: arms, targets, wrist wrenches, contacts)"
    fi
  done
  ;;
esac

step "demo $part done in $((SECONDS - t0)) s"
echo "demo $part: outputs in $out"
{
  for f in "${files[@]}"; do
    p="${f%%$'\t'*}"
    if [[ -e "$out/$p" ]]; then printf '  %-44s %s\n' "$p" "${f#*$'\t'}"; else printf '  %-44s MISSING: %s\n' "$p" "${f#*$'\t'}"; fi
  done
} | tee "$out/FILES.txt"
! grep -q MISSING "$out/FILES.txt"
