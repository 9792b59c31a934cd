#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 60), keeping each target's corpus in
# fuzz/corpus/TARGET (seeded from the project's own inputs of that format) and any crash in
# fuzz/artifacts/TARGET. Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-60}
command -v cargo-fuzz >/dev/null || { echo "cargo-fuzz is missing: cargo install cargo-fuzz" >&2; exit 1; }
seed() { # TARGET then files to copy into its corpus the first time
    local target=$1; shift
    mkdir -p "corpus/$target"
    [ -n "$(ls -A "corpus/$target")" ] && return
    for f in "$@"; do [ -f "$f" ] && cp "$f" "corpus/$target/" || true; done
}
seed compile ../stdlib_shaders/*/*.sl
seed differential ../stdlib_shaders/*/*.sl $(find ../tests/corpus -name '*.sl' | head -300)
seed rib ../examples/scenes/*.rib ../examples/office/*.rib
seed rib_render ../examples/scenes/*.rib seeds/rib_render/*.rib
seed aff $(ls ../../shared/scenes/bart/robot/aff/*.aff 2>/dev/null | head -5)
seed texture
seed grid ../examples/office/data/*.grid
seed obj
seed ply
seed gltf $(ls ../../shared/scenes/box_animated_gltf/*.gltf 2>/dev/null)
seed artifact
# Real artifacts, so that mutations start from payloads the decoder reads (the target frames each
# input again with a correct checksum).
if [ -z "$(ls -A corpus/artifact)" ]; then
    cargo run -q --release --manifest-path ../Cargo.toml --bin rtsl -- compile -o corpus/artifact \
        ../stdlib_shaders/surface/*.sl ../stdlib_shaders/light/*.sl >/dev/null 2>&1 || true
    rm -f corpus/artifact/index.json
fi
seed replica
seed protocol
seed vrml $(ls ../../shared/scenes/castle_with_trees_vrml97/*.wrl 2>/dev/null)
status=0
for target in $(cargo +nightly fuzz list); do
    echo "== $target ($seconds s)"
    if ! cargo +nightly fuzz run "$target" "corpus/$target" -- -max_total_time="$seconds" -rss_limit_mb=4096 -timeout=30 \
        2>&1 | grep -E "^(#[0-9]+ +DONE|Done|==[0-9]+== ERROR|SUMMARY)|cov:" | tail -2; then
        status=1
    fi
    [ -d "artifacts/$target" ] && [ -n "$(ls -A "artifacts/$target" 2>/dev/null)" ] && { echo "crashes in fuzz/artifacts/$target"; status=1; }
done
exit $status
