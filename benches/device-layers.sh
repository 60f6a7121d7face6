#!/usr/bin/env bash
# Issue 31 item 4 on the lent H200, one call: what an intensity layer costs. MNI152 (1 mm) at
# 1920x1080, superior view, the stills' defaults, 10 turntable frames per run, alternated in
# one order per round, 3 rounds: without a layer, with the synthetic z-map of
# tools/figures/synthetic_zmap.py (2 mm grid, thresholded at 3.1 with clusters >= 20 voxels),
# and with the same layer drawing nothing (threshold above its maximum: the variant's own cost).
# Build here: cargo build --release; cp target/release/morphray .gpu/; strip .gpu/morphray;
#   cp ../shared/data/mni152_t1_2009a.nii.gz .gpu/mni152.nii.gz;
#   python tools/figures/synthetic_zmap.py .gpu/mni152.nii.gz .gpu/zmap.nii.gz
# then run(command="bash benches/device-layers.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
LOG="$OUT/layers.txt"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$LOG"
looks=(
    "plain|"
    "layer|--layer .gpu/zmap.nii.gz:red-yellow:3.1:8:cluster=20"
    "empty-layer|--layer .gpu/zmap.nii.gz:red-yellow:30:38"
)
for round in 1 2 3; do
    for look in "${looks[@]}"; do
        name=${look%%|*}
        # shellcheck disable=SC2086 # the flags are words
        $M render .gpu/mni152.nii.gz --size 1920x1080 --view superior --turntable 10 \
            -o "$V/$name-$round.png" ${look#*|} > "$V/run.txt" 2>&1
        # Frames 2..10 (the first carries the pipeline's first use).
        ms=$(grep -o 'raymarch [0-9.]* ms GPU' "$V/run.txt" | tail -n +2 | awk '{print $2}' | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
        echo "$name r$round: median raymarch ${ms} ms (frames 2-10)" | tee -a "$LOG"
    done
done
