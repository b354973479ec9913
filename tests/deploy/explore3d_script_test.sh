#!/usr/bin/env bash
# deploy/explore3d.sh and deploy/explore3d_table.sh refuse bad arguments
# before running anything (exit 2, no station started, no output table), and
# explore3d.sh reads the route from the scene's header through hemm-operator
# --print-hand6-route: a scene whose route is malformed or out of reach is
# refused with the file, line and reason; a robot that cannot take its port
# stops the run before the operator starts. Nothing runs for long.
# Usage: explore3d_script_test.sh BUILD_DIR
set -euo pipefail
build="${1:?usage: explore3d_script_test.sh BUILD_DIR}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
expect2() {  # WHAT... : the command exits 2 and says WHAT (the last argument) on stderr
  local want="${@: -1}" rc=0
  "${@:1:$#-1}" >"$tmp/out" 2>"$tmp/err" || rc=$?
  ((rc == 2)) || fail "'${*:1:$#-1}' exited $rc, expected 2 ($(cat "$tmp/err"))"
  grep -qF -- "$want" "$tmp/err" || fail "'${*:1:$#-1}' did not say '$want': $(cat "$tmp/err")"
}
t="$root/deploy/explore3d_table.sh"
e="$root/deploy/explore3d.sh"
expect2 bash "$t" "$build" --scenes home,nope --out "$tmp/t1" "no scene 'nope'"
expect2 bash "$t" "$build" --operator-arg x --out "$tmp/t2" "'--operator-arg' before any --variant"
expect2 bash "$t" "$build" --variant "a|b" --out "$tmp/t3" "no '|' or '=' in a label"
expect2 bash "$t" "$build" --variant a --variant a --out "$tmp/t4" "--variant 'a' given twice"
expect2 bash "$t" "$build" --rtts 0,x --out "$tmp/t5" "round trips are whole milliseconds"
[[ ! -e "$tmp/t1/table.md" ]] || fail "a refused run wrote a table"
expect2 bash "$e" "$build" --scene nope --out "$tmp/e1" "no $root/deploy/scenes/nope.xml"
expect2 bash "$e" "$build" --robot-config "$tmp/none.pbtxt" --out "$tmp/e2" "config '$tmp/none.pbtxt' not found"
# A scene whose route has a bad key, and one whose key leaves the hand's reach.
sed 's/explore6: explore-table    13   0.85  -0.25  0.865 0.35/explore6: explore-table    13   0.85  -0.25  0.865 x/' \
  "$root/deploy/scenes/home.xml" >"$tmp/bad.xml"
cp "$root/deploy/scenes/robot.xml" "$tmp/"
expect2 bash "$e" "$build" --scene "$tmp/bad.xml" --out "$tmp/e3" "$tmp/bad.xml:30: explore6: 'x' is not a finite number"
sed 's/explore6: explore-table    13   0.85  -0.25  0.865 0.35/explore6: explore-table    13   0.85  -0.25  2.2 0.35/' \
  "$root/deploy/scenes/home.xml" >"$tmp/far.xml"
expect2 bash "$e" "$build" --scene "$tmp/far.xml" --out "$tmp/e4" "explore6 explore-table at t = 13 s: the tip (0.850 -0.250 2.200) in R is out of the device's reach"
expect2 bash "$e" "$build" --route explore-moon --out "$tmp/e5" "no route 'explore-moon'"
# --device sim-omni: the explore3 route, checked against the SIMULATED Omni's reach through probe_3d's map.
sed 's/explore3: explore-table   48.5   1.6000   2.2000  0.9200  mug-top/explore3: explore-table   48.5   1.6000   2.4000  0.9200  mug-top/' \
  "$root/deploy/scenes/home.xml" >"$tmp/far3.xml"
expect2 bash "$e" "$build" --device sim-omni --scene "$tmp/far3.xml" --out "$tmp/e7" \
  "explore3 explore-table at t = 48.5 s: the point (1.600 2.400 0.920) in W is out of the Omni's reach"
expect2 bash "$e" "$build" --device sim-omni --route explore-moon --out "$tmp/e8" "(its explore3 routes: explore-table)"
[[ ! -e "$tmp/e7/0ms" ]] || fail "a refused explore3 route started a run"
[[ ! -e "$tmp/e3/0ms" && ! -e "$tmp/e4/0ms" ]] || fail "a refused route started a run"
# A robot port another process holds: the robot does not start, and the
# operator is not left to connect to whatever listens there.
coproc HOLD { /usr/bin/python3 -c 'import socket, sys
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(1); print(s.getsockname()[1], flush=True); sys.stdin.read()'; }
read -r port <&"${HOLD[0]}"
rc=0
bash "$e" "$build" --rtts 0 --port-base "$port" --out "$tmp/e6" --no-plots >"$tmp/out" 2>"$tmp/err" || rc=$?
eval "exec ${HOLD[1]}>&-"
((rc != 0)) || fail "a run whose robot could not listen on $port went on"
grep -qF "hemm-robot did not start" "$tmp/err" || fail "no word on the robot that did not start: $(cat "$tmp/err")"
[[ ! -e "$tmp/e6/0ms/operator.txt" ]] || fail "the operator was started without its robot"
echo "explore3d scripts: refusals ok"
