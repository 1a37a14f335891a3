#!/usr/bin/env bash
# Makes the small baked models of the hybrid screenshot goldens (tests/tests/screenshots.rs):
# each preset generated at 64x64x16 with seed 1 and baked with the default settings (no
# held-out views), about four minutes each on 2 cores (K = 128 clusters at 64²). The model
# does not depend on the held-out views (twill at 1.14: the same bytes with and without
# them). Rerun after a change to the generator or the baker that should change the
# goldens, then refresh the goldens deliberately:
#   bash tests/goldens/make_models.sh && UPDATE_GOLDENS=1 cargo test -p fabric-tests --test screenshots
# The committed models were remade at format 1.15 (2026-12-07) with the debug-profile
# binary (opt-level 2), 221-261 s each: the surface fit's mask of that day and the
# visibility curvature on every level. screenshots.rs checks that level 0 carries the
# curvature, so a model left behind by a format change is caught.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin fabric
F=target/release/fabric
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for preset in plain twill satin silk felt; do
    "$F" gen --preset "$preset" --size 64x64x16 --seed 1 --out "$tmp/$preset" > /dev/null
    "$F" bake "$tmp/$preset" --out "$tmp/$preset.hyb" --held-out 0 > "$tmp/$preset.log"
    cp "$tmp/$preset.hyb" "tests/goldens/models/$preset.hyb"
    grep "^wrote .*\.hyb" "$tmp/$preset.log" | sed "s|^|$preset: |"
done
