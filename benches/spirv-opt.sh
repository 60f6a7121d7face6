#!/usr/bin/env bash
# Issue 33 item 2: does running spirv-opt over the GLSL modules shorten the driver's pipeline
# compiles? Builds morphray twice (as is, and with MORPHRAY_SPIRV_OPT="-O", which
# tools/build/glsl.rs passes to spirv-opt), keeps both binaries, compares the size of
# raymarch.comp's module, and traces first frames of both (benches/first-frame-trace-ab.sh).
# Usage: benches/spirv-opt.sh OUT_DIR VOLUME [ROUNDS]   (needs Debian's spirv-tools)
set -euo pipefail
OUT=${1:?usage: $0 OUT_DIR VOLUME [ROUNDS]}
VOL=${2:?usage: $0 OUT_DIR VOLUME [ROUNDS]}
ROUNDS=${3:-3}
mkdir -p "$OUT"
spv_size() {
    find target/release/build -name raymarch.glslang.spv -newer "$OUT/.stamp" -printf '%s\n' | head -1
}
for flags in "" "-O"; do
    touch "$OUT/.stamp"
    sleep 1
    touch shaders/raymarch.comp
    MORPHRAY_SPIRV_OPT=$flags cargo build --release --quiet
    name=morphray-base
    [ -n "$flags" ] && name=morphray-opt
    cp target/release/morphray "$OUT/$name"
    echo "$name: raymarch.comp SPIR-V $(spv_size) bytes" | tee -a "$OUT/sizes.txt"
done
# Leave the tree's build as it was (no spirv-opt).
touch shaders/raymarch.comp
cargo build --release --quiet
bash "$(dirname "$0")/first-frame-trace-ab.sh" "$OUT/trace" "$ROUNDS" "$VOL" \
    "$OUT/morphray-base" "$OUT/morphray-opt"
