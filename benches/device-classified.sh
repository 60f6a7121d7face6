#!/usr/bin/env bash
# Issue 33 item 1 on the lent H200, one call: what the classified volume (the lean sample,
# `--classification volume`) saves against the per-sample table (the default). `bench` (shading
# on, 30-frame orbit, raymarch GPU median) on MNI152 and the built-in phantom at 1920x1080 and
# MNI152 at 500x500, alternated in one order per round, 3 rounds; then the accuracy study on
# MNI152 (errors at 256x256 against the f64 twin, GPU times at 1920x1080), which places
# "classified volume" and "classified volume, step 1" among the other knobs.
# Build here: cargo build --release; cp target/release/morphray .gpu/; strip .gpu/morphray;
#   cp ../shared/data/mni152_t1_2009a.nii.gz .gpu/mni152.nii.gz; cp ../shared/gpu/debs/*.deb .gl/
# then run(command="bash benches/device-classified.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
LOG="$OUT/classified.txt"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$LOG"
$M phantom -o "$V/phantom.nii.gz" > /dev/null 2>&1
pairs=(".gpu/mni152.nii.gz|1920x1080" "$V/phantom.nii.gz|1920x1080" ".gpu/mni152.nii.gz|500x500")
for round in 1 2 3; do
    for pair in "${pairs[@]}"; do
        file=${pair%%|*} size=${pair#*|}
        for lookup in table volume; do
            $M bench "$file" --size "$size" --shading on --frames 30 --repeat 1 --trials 0 \
                --classification "$lookup" > "$OUT/bench-$(basename "$file" .nii.gz)-$size-$lookup-r$round.txt" 2>&1
            echo "r$round $(basename "$file") $size $lookup: $(grep '^raymarch:' "$OUT/bench-$(basename "$file" .nii.gz)-$size-$lookup-r$round.txt" | cut -c1-110)" | tee -a "$LOG"
        done
    done
done
timeout 330 $M accuracy .gpu/mni152.nii.gz --size 256x256 --time-size 1920x1080 --views 3 \
    --frames 25 --json "$OUT/accuracy-mni152.json" > "$OUT/accuracy-mni152.txt" 2>&1
echo "accuracy exit $?" | tee -a "$LOG"
