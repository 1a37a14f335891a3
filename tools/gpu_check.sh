#!/usr/bin/env bash
# One pass of the checks that need a real GPU, for a machine that has one: the GPU tests
# with the validation layer required, then the frame-time benchmark (frames back to
# back) on MODEL.hyb files, the mesh pass on a sphere, then the environment light's cost broken down by shader
# variant (FABRIC_SHADER_DIR: the hybrid programs compiled from an edited copy of
# shaders/, no rebuild). Prints everything and keeps a log in OUT_DIR.
#
#   tools/gpu_check.sh [--no-tests] [--no-variants] OUT_DIR MODEL.hyb...
#
# Build first (here or on a machine with the same system libraries):
#   cargo build --release --locked -p fabric-tools
#   cargo build --release --locked -p fabric-runtime --example bench_gpu_render
#   cargo test --release --locked -p fabric-runtime --test gpu_twins --test gpu_hybrid --test gpu_mesh --no-run
#   cargo test --release --locked -p fabric-tests --test screenshots --no-run
# BIN_DIR (default target/release) holds fabric and examples/bench_gpu_render; the test
# binaries are found under BIN_DIR/deps. runtime/GPU_MEASUREMENTS.md ("On a discrete
# GPU") and runtime/ENV_MEASUREMENTS.md ("Speed") record what such a pass measured.
set -u
cd "$(dirname "$0")/.."
tests=1
variants=1
while [ $# -gt 0 ]; do
    case "$1" in
        --no-tests) tests=0; shift ;;
        --no-variants) variants=0; shift ;;
        *) break ;;
    esac
done
if [ $# -lt 2 ]; then
    echo "usage: tools/gpu_check.sh [--no-tests] [--no-variants] OUT_DIR MODEL.hyb..." >&2
    exit 2
fi
out=$1
shift
mkdir -p "$out"
log="$out/gpu_check.log"
bin=${BIN_DIR:-target/release}
for f in "$bin/fabric" "$bin/examples/bench_gpu_render"; do
    [ -x "$f" ] || { echo "missing $f: build it first (see the top of this script)" >&2; exit 2; }
done
for m in "$@"; do
    [ -f "$m" ] || { echo "no model file $m" >&2; exit 2; }
done

say() { echo "=== $* ($(date +%T))" | tee -a "$log"; }
step() { say "$*"; "$@" 2>&1 | tee -a "$log"; echo "exit ${PIPESTATUS[0]}" | tee -a "$log"; }

say "devices"
"$bin/fabric" devices 2>&1 | tee -a "$log"

if [ $tests = 1 ]; then
    # The newest build of each test binary (cargo names them name-HASH).
    newest() { ls -t "$bin"/deps/"$1"-* 2>/dev/null | grep -v '\.d$' | head -1; }
    export FABRIC_VALIDATION=1 FABRIC_REQUIRE_VALIDATION=1
    # gpu_mesh first: it fails when FABRIC_REQUIRE_VALIDATION is set and the layer is missing.
    for t in gpu_mesh gpu_twins gpu_hybrid screenshots; do
        exe=$(newest $t)
        if [ -n "$exe" ]; then step "$exe"; else say "no test binary $t under $bin/deps: skipped"; fi
    done
    unset FABRIC_VALIDATION FABRIC_REQUIRE_VALIDATION
fi

export FABRIC_VALIDATION=0
for m in "$@"; do
    step "$bin/examples/bench_gpu_render" "$m"
done

# The mesh pass (visibility pass + compute shading since 2026-12-05; the fragment
# shader it replaced took 95 ms at 640x360 and 314 ms at 1920x1080 on an H200).
for m in "$@"; do
    for size in 640x360 1920x1080; do
        step "$bin/fabric" render "$m" --mesh sphere --size "$size" --repeat 5 --out "$out/mesh-$(basename "$m" .hyb)-$size.png"
    done
done

if [ $variants = 1 ]; then
    # Each variant: a copy of shaders/ with one edit; the same benchmark's sky section.
    dir="$out/shader-variants"
    rm -rf "$dir"
    variant() {  # name, file, sed expression
        mkdir -p "$dir/$1"
        cp -r shaders/. "$dir/$1/"
        sed -i "$3" "$dir/$1/$2"
        cmp -s "shaders/$2" "$dir/$1/$2" && { echo "variant $1: the edit of $2 matched nothing" >&2; exit 3; }
    }
    variant nodes8 common/env_shading.glsl 's/#define ENV_NODES 16u/#define ENV_NODES 8u/'
    variant lookups1 common/env_shading.glsl 's/#define ENV_LOOKUPS 4u/#define ENV_LOOKUPS 1u/'
    variant flyaway_nodes4 common/env_shading.glsl 's/#define ENV_FLYAWAY_NODES 8u/#define ENV_FLYAWAY_NODES 4u/'
    # Lower bounds: no map lookups (a constant), no SG mixtures at all.
    variant no_lookups common/env_lookup.glsl 's/^vec3 env_blurred(vec3 w, float sigma) {$/&\n    return vec3(0.5) * (1.0 + 1e-3 * (w.z + sigma));/'
    variant no_mixtures common/env_shading.glsl 's/^vec3 lobe_env(ClothLobe lobe, float eta, float a, ClothFrame f, vec3 wo, uint reading, bool volumetric, uint nodes, uint lookups) {$/&\n    return lobe.k * 1e-3;/'
    for v in nodes8 lookups1 flyaway_nodes4 no_lookups no_mixtures; do
        say "variant $v"
        for m in "$@"; do
            FABRIC_SHADER_DIR="$dir/$v" step "$bin/examples/bench_gpu_render" --env-only "$m"
        done
    done
fi
say "done: $log"
