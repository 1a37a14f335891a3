#!/usr/bin/env bash
# The model under an environment against the path tracer (runtime/ENV_MEASUREMENTS.md,
# "The model against the path tracer"): the golden models (tests/goldens/models, baked
# from `fabric gen --size 64x64x16 --seed 1`) against `fabric reference --envmap`, and
# the same views under a directional light (35°, −60°), per pixel and over 4×4 blocks.
#
#   tools/scripts/env_vs_reference.sh OUT_DIR [ENVMAP]     (ENVMAP: sky (default) or an .exr)
#   PRESETS="twill satin" SPP=64 tools/scripts/env_vs_reference.sh /tmp/env
set -euo pipefail
out=${1:?usage: env_vs_reference.sh OUT_DIR [ENVMAP]}
env=${2:-sky}
top=$(cd "$(dirname "$0")/../.." && pwd)
fabric=${FABRIC:-$top/target/release/fabric}
models=$top/tests/goldens/models
mkdir -p "$out"
name=$(basename "${env%.exr}")
metric() { "$fabric" diff "$1" "$2" --block 4 --json | python3 -c 'import json,sys; v=json.load(sys.stdin); print("%.1f%% | %.1f%% | %+.1f%%" % (100*v["relative_rmse"], 100*v["relative_rmse_blocks"], 100*v["relative_mean_difference"]))'; }
echo "| preset, view | $name: rel. RMSE | over 4×4 blocks | mean | directional: rel. RMSE | over 4×4 blocks | mean |"
echo "|---|---|---|---|---|---|---|"
for p in ${PRESETS:-twill satin silk felt}; do
  [ -d "$out/$p" ] || "$fabric" gen --preset "$p" --size 64x64x16 --seed 1 --out "$out/$p" > /dev/null
  for v in 40,30 60,200; do
    t=$out/$p-${v/,/_}
    view=(--size 64x64 --periodic --view-angles "$v")
    [ -f "$t-ref-$name.exr" ] || "$fabric" reference "$out/$p" --envmap "$env" --spp "${SPP:-256}" "${view[@]}" --out "$t-ref-$name.exr" > "$t-ref-$name.log" 2>&1
    [ -f "$t-ref-dir.exr" ] || "$fabric" reference "$out/$p" --spp "${SPP:-256}" "${view[@]}" --light-angles 35,-60 --out "$t-ref-dir.exr" > "$t-ref-dir.log" 2>&1
    "$fabric" render "$models/$p.hyb" --backend cpu --envmap "$env" "${view[@]}" --out "$t-model-$name.exr" > /dev/null
    "$fabric" render "$models/$p.hyb" --backend cpu "${view[@]}" --light-angles 35,-60 --out "$t-model-dir.exr" > /dev/null
    echo "| $p ${v/,/°, }° | $(metric "$t-model-$name.exr" "$t-ref-$name.exr") | $(metric "$t-model-dir.exr" "$t-ref-dir.exr") |"
  done
done
