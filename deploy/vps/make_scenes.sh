#!/usr/bin/env bash
# Writes the bimanual paper's two VR scenes (section 4.2) and their scripted
# hands, and builds a .vps cache (voxmap + pointshell) for every object, for
# `hemm-vps eval` (hemm-operator writes its own caches, named after mesh and
# resolution, beside the meshes on its first run).
# Usage: deploy/vps/make_scenes.sh BUILD_DIR [OUT_DIR] [BOSSES]
#   OUT_DIR defaults to out/vps; BOSSES (assembly scene) to 13 (1.07 M
#   triangles); 41 gives the paper's scale (3.36 M).
# Voxel sizes: peg-in-hole 1 mm (its clearance) with 1.5 mm pointshells, the
# table at 2 mm; assembly 3 mm for the static part, 2.5 mm for the tools (the
# engine report's choice: <= 2 % RMS force error). Distance layers: 4 (the
# couplings' maximum expected penetration needs 2; culling wants 4: docs/vps.md).
set -euo pipefail
build="${1:?usage: deploy/vps/make_scenes.sh BUILD_DIR [OUT_DIR] [BOSSES]}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
out="${2:-$root/out/vps}"
bosses="${3:-13}"
vps="$build/bin/hemm-vps"
[[ -x "$vps" ]] || { echo "no $vps: build the operator component first" >&2; exit 2; }
mkdir -p "$out"
"$vps" scene --name peg-in-hole --out "$out"
"$vps" scene --name assembly --bosses "$bosses" --out "$out"
build_cache() {  # mesh voxel shell-voxel
  "$vps" build --mesh "$out/$1.stl" --voxel "$2" --shell-voxel "$3" --layers 4 -o "$out/$1.vps"
}
build_cache peg-in-hole-scene 0.002 0.002
build_cache peg-in-hole-right 0.001 0.0015
build_cache peg-in-hole-left 0.001 0.0015
build_cache assembly-scene 0.003 0.003
build_cache assembly-right 0.0025 0.0025
build_cache assembly-left 0.0025 0.0025
echo "scenes, hands (*-hands.csv) and caches (*.vps) in $out"
