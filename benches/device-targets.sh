#!/usr/bin/env bash
# Issue 17 item 4's targets with the final tree, on the lent GPU machine, one call: `morphray
# bench` at 1920x1080, step 0.5, curvature + shading, 100 orbit frames x 3, first pixel from 5
# fresh processes per cache state, on the default phantom, MNI152 and the 134 M-voxel phantom as
# .nii.gz (1 MiB members) and .nii; the phantom in MIP too (the texel rate without the DVR
# arithmetic: what bounds the DVR's); and a running viewer opening the phantom again (second-file
# first pixel), offscreen at 1920x1080; the accuracy study's long-step settings timed at 1920x1080.
# Carry the loader packages and .sv (morphray.xz and mni.nii.xz):
#   run(command="bash benches/device-targets.sh", carry=[".glmin", ".sv"])
set -uo pipefail
# Loader, OUT, RAW, V, M and $V/mni152.nii.gz (benches/device-common.sh).
source benches/device-common.sh
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$RAW/device.txt"
$M phantom -o "$V/p256.nii.gz" > /dev/null
cp "$V/p256.nii.gz" "$V/p256b.nii.gz"
$M phantom -o "$V/p512.nii.gz" --dims 512x512x512 > /dev/null
python3 -c 'import gzip,shutil,sys; shutil.copyfileobj(gzip.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    "$V/p512.nii.gz" "$V/p512.nii"
ls -l "$V" | tee "$RAW/volumes.txt"
$M info "$V/p512.nii.gz" | head -3 >> "$RAW/volumes.txt"

bench() { # NAME FILE ARGS...; skipped past 500 s so the call ends inside the device's 10 minutes
    local name=$1 file=$2
    shift 2
    if [ "$SECONDS" -gt 500 ]; then echo "$name: skipped (time)"; return; fi
    $M bench "$file" --size 1920x1080 --json "$RAW/$name.json" "$@" > "$RAW/$name.txt" 2>&1
    echo "== $name"
    grep -E '^raymarch:|^frame overhead|texel rate|^empty-space|total \(spawn|load path' "$RAW/$name.txt" | cut -c1-160
}
{
printf 'open %s\nopen %s\nopen %s\n' "$V/p256b.nii.gz" "$V/p256.nii.gz" "$V/p256b.nii.gz" > "$V/open.txt"
timeout 120 $M view "$V/p256.nii.gz" --offscreen --size 1920x1080 --curvature on --shading on \
    --frame-budget 0 --script "$V/open.txt" > "$RAW/viewer.txt" 2>&1
echo "viewer: $(grep 'time to first pixel' "$RAW/viewer.txt" | tr '\n' ';')"
full=(--frames 100 --repeat 3 --trials 5 --curvature on --shading on)
bench phantom "$V/p256.nii.gz" "${full[@]}"
bench mni152 "$V/mni152.nii.gz" "${full[@]}"
bench phantom-mip "$V/p256.nii.gz" --frames 100 --repeat 1 --trials 0 --mode mip
bench p512-nii-gz "$V/p512.nii.gz" "${full[@]}"
bench p512-nii "$V/p512.nii" "${full[@]}"
# The long-step settings of the accuracy study (issue 17 item 2) timed at 1920x1080 on the GPU
# (errors against the f64 twin at the study's default size).
for vol in p256 mni152; do
    if [ "$SECONDS" -gt 480 ]; then echo "accuracy $vol: skipped (time)"; continue; fi
    timeout 100 $M accuracy "$V/$vol.nii.gz" --time-size 1920x1080 --frames 21 \
        --json "$RAW/accuracy-$vol.json" > "$RAW/accuracy-$vol.txt" 2>&1
    echo "== accuracy $vol (rc $?)"
    grep -iE 'long steps|^default|setting' "$RAW/accuracy-$vol.txt" | cut -c1-150
done
} 2>&1 | tee "$RAW/summary.txt"
cp "$RAW/summary.txt" "$RAW/device.txt" "$OUT/"
tar czf "$OUT/raw.tgz" -C "$RAW" .
