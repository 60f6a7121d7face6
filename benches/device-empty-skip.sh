#!/usr/bin/env bash
# Issue 33 item 3 on the lent H200, one call: empty-space skipping by the distance map against
# the occupancy bits alone (benches/empty-skip.sh, `--empty-skip distance` vs `bricks`) at
# 1920x1080, shaded, 50 orbit frames, 3 alternated rounds, on the default phantom, MNI152, the
# 512^3 phantom (134 M voxels) and the real scans carried in .sv/real/ (never committed).
# EXTRA= runs bench's own default scene instead of the shaded one (benches/empty-skip.sh).
# Build here: cargo build --release; strip a copy; xz -9e > .sv/morphray.xz; MNI152 as
# .sv/mni.nii.xz; the real scans copied into .sv/real/;
#   run(command="bash benches/device-empty-skip.sh", carry=[".glmin", ".sv"])
set -uo pipefail
# shellcheck source=benches/device-common.sh
source benches/device-common.sh
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$RAW/device.txt"
$M phantom -o "$V/phantom-512.nii.gz" --dims 512x512x512 > /dev/null
EXTRA=${EXTRA-"--shading on"} SIZE=${SIZE:-1920x1080} FRAMES=${FRAMES:-50} ROUNDS=${ROUNDS:-3} \
    bash benches/empty-skip.sh "$M" "$RAW/empty-skip" phantom "$V/mni152.nii.gz" \
    "$V/phantom-512.nii.gz" .sv/real/*.nii.gz > /dev/null 2>&1
cp "$RAW/empty-skip/summary.txt" "$OUT/summary.txt"
tar czf "$OUT/raw.tgz" -C "$RAW" .
tail -n 16 "$OUT/summary.txt"
