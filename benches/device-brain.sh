#!/usr/bin/env bash
# Issue 27 on the lent H200, one call: brain extraction's GPU time and the head's time to first
# pixel with it (cold and warm pipeline caches, 5 fresh processes each) against --brain off, on
# chris_t1 (the 0.88 mm T1 head) and T2w (the 1x1x2 mm clinical T2 whose bridge into the scalp
# the second try cuts), and the default phantom's first pixel (issue 33's target), each at
# 1920x1080, default scene (shaded), 50 orbit frames x 5.
# Build here: cargo build --release; mkdir -p .gpu; cp target/release/morphray .gpu/;
#   strip .gpu/morphray; cp ../shared/data/real/{chris_t1,T2w}.nii.gz .gpu/
# then run(command="bash benches/device-brain.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$OUT/smi.txt"
$M phantom -o "$V/phantom.nii.gz" > /dev/null
bench() { # NAME FILE ARGS...
    local name=$1 file=$2
    shift 2
    if [ "$SECONDS" -gt 480 ]; then echo "$name: skipped (time)"; return; fi
    $M bench "$file" --size 1920x1080 --frames 50 --repeat 5 --trials 5 \
        --json "$V/$name.json" "$@" > "$V/$name.txt" 2>&1
    echo "== $name"
    grep -E '^brain extraction|^raymarch:|^empty-space|total \(spawn' "$V/$name.txt" | cut -c1-150
}
bench chris .gpu/chris_t1.nii.gz
bench chris-off .gpu/chris_t1.nii.gz --brain off
bench t2w .gpu/T2w.nii.gz
bench phantom "$V/phantom.nii.gz"
for f in chris_t1 T2w; do
    $M derive ".gpu/$f.nii.gz" -o "$V/maps" --maps brain --force | grep '^brain' | tee -a "$V/derive.txt"
done
tar -C "$V" -czf "$OUT/raw.tar.gz" --exclude maps --exclude phantom.nii.gz .
