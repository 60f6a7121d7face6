#!/usr/bin/env bash
# Issue 33 on the lent H200, one call: the lean DVR sample (classification table, the default)
# against eq. 4's exact windows per sample (`--classification exact`) and MIP, on MNI152 at
# 1920x1080 and 500x500, shaded and unshaded; the 134 M-voxel phantom's frame; the phantom's
# cold and warm first pixel. Alternated in one process order per round, 3 rounds.
# Build here: cargo build --release; mkdir -p .gpu; cp target/release/morphray .gpu/;
#   strip .gpu/morphray; cp ../shared/data/mni152_t1_2009a.nii.gz .gpu/mni152.nii.gz
# then run(command="bash benches/device-lean.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/lean.txt"
bench() { # NAME FILE ARGS...: one line with the raymarch's frame and sample rate
    local name=$1 file=$2
    shift 2
    $M bench "$file" --frames 50 --repeat 1 --trials 0 "$@" > "$V/$name.txt" 2>&1
    echo "$name: $(grep -E '^raymarch:' "$V/$name.txt" | head -1 | cut -c1-160)" | tee -a "$OUT/lean.txt"
}
for round in 1 2 3; do
    for size in 1920x1080 500x500; do
        for cls in table exact; do
            bench "mni-$size-$cls-shaded-r$round" .gpu/mni152.nii.gz --size $size --classification $cls --shading on
            bench "mni-$size-$cls-flat-r$round" .gpu/mni152.nii.gz --size $size --classification $cls --shading off
        done
        bench "mni-$size-mip-r$round" .gpu/mni152.nii.gz --size $size --mode mip
    done
done
$M phantom --dims 512x512x512 -o "$V/big.nii.gz" > /dev/null
for round in 1 2 3; do
    for cls in table exact; do
        bench "big-1920x1080-$cls-r$round" "$V/big.nii.gz" --size 1920x1080 --classification $cls
    done
done
$M phantom -o "$V/phantom.nii.gz" > /dev/null
$M bench "$V/phantom.nii.gz" --size 1920x1080 --frames 20 --repeat 1 --trials 5 > "$V/ttfp.txt" 2>&1
grep -E 'total \(spawn|cold|warm' "$V/ttfp.txt" | head -8 | tee -a "$OUT/lean.txt"
tar -C "$V" -czf "$OUT/raw.tar.gz" --exclude '*.nii.gz' .
