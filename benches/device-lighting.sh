#!/usr/bin/env bash
# Issue 34 on the lent H200, one call: what the lighting and depth cues cost, on MNI152 and the
# built-in phantom at 1920x1080 (DVR, shaded): headlight (the interactive default), studio,
# studio + depth cues (the stills' default), headlight + cues, and the cut-away; alternated in
# one order per round, 3 rounds (medians are taken by benches/lighting-report.py).
# Build here: cargo build --release; mkdir -p .gpu; cp target/release/morphray .gpu/;
#   strip .gpu/morphray; cp ../shared/data/mni152_t1_2009a.nii.gz .gpu/mni152.nii.gz
# then run(command="bash benches/device-lighting.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/lighting.txt"
$M phantom -o "$V/phantom.nii.gz" > /dev/null
SIZE=1920x1080 FRAMES=50 LOG="$OUT/lighting.txt" M=$M \
    bash benches/lighting-rounds.sh .gpu/mni152.nii.gz "$V/phantom.nii.gz"
