#!/usr/bin/env bash
# Issue 17 item 6: the side-by-side and scaling run of benches/device-scaling.sh on this machine's
# CPU devices (morphray and pygfx on lavapipe, VTK on llvmpipe), in the same form: the same
# `bench` and peer commands, the same report (python3 benches/scaling_report.py OUT), so the
# ratios can be tracked next to the H100's. A 2-core machine renders small images in minutes:
# 320x180, 20 frames, 3 first-pixel processes per cache state; volumes: the phantom at
# 128x128x96, 256x256x192 and 384x384x288 and MNI152 (lavapipe's 128 MiB storage-buffer limit
# keeps the 512^3 phantom whole on the H100 only). CPU times of software renderers: ratios, not
# GPU times.
#
#   bash benches/lavapipe-scaling.sh OUT_DIR [MNI152.nii.gz]
#
# Needs a release build and the peers as the device runs them: tools/peers/stage.sh, then a
# Python 3.12 venv with numpy and jinja2 (PYTHON=/tmp/pv312/bin/python, tools/peers/README.md).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bash benches/lavapipe-scaling.sh OUT_DIR [MNI152.nii.gz]}
mni=${2:-../shared/data/mni152_t1_2009a.nii.gz}
bin=target/release/morphray
[ -x "$bin" ] || { echo "lavapipe-scaling: build first: cargo build --release" >&2; exit 2; }
mkdir -p "$out"
V=$(mktemp -d)
for dims in 128x128x96 256x256x192 384x384x288; do
    "$bin" phantom -o "$V/phantom-$dims.nii.gz" --dims "$dims" > /dev/null
done
cp "$mni" "$V/mni152.nii.gz"
"$bin" devices | head -n 3 > "$out/device.txt"
nproc >> "$out/device.txt"
for vol in phantom-128x128x96.nii.gz phantom-256x256x192.nii.gz mni152.nii.gz phantom-384x384x288.nii.gz; do
    name=${vol//./-}
    echo "== $vol"
    "$bin" bench "$V/$vol" --frames 20 --repeat 1 --trials 3 --size 320x180 \
        --curvature on --shading on --json "$out/bench-$name.json" > "$out/bench-$name.txt" 2>&1
    grep -E '^raymarch:|total \(spawn' "$out/bench-$name.txt" | cut -c1-150
    PEERS_SKIP_PROBE=1 PEERS_SITE=${PEERS_SITE:-/tmp/site312} timeout 900 bash tools/peers/device-peers.sh \
        "$V/$vol" --size 320x180 --frames 20 --trials 3 \
        --peers vtk-composite,vtk-composite-plain,pygfx-mip --out "$out/peers-$name" \
        > "$out/peers-$name.txt" 2>&1
    tail -n 6 "$out/peers-$name.txt" | cut -c1-150
done 2>&1 | tee "$out/summary.txt"
rm -rf "$V"
