#!/usr/bin/env bash
# Streamed loading (issue 17 items 1 and 4): what the parallel read, inflation and staging copy,
# the resizable-BAR upload and the multi-member files each buy in time to first pixel, as ratios
# in the same run, on the lent GPU machine; and the second file opened in a running viewer.
# Every variant is `morphray bench --trials 5` (5 cold and 5 warm fresh processes, 1920x1080,
# step 0.5, curvature + shading) of one stripped release binary of this tree:
#   MORPHRAY_IO_THREADS=1        one thread reads, inflates and copies (the old path)
#   (unset)                      every core (at most 16)
#   MORPHRAY_UPLOAD=rebar|staged the samples through the BAR into device-local memory, or staged
# Volumes: the phantom at 512x512x512 (134 M voxels) as multi-member .nii.gz (what morphray
# writes), as a single-member .nii.gz (what gzip(1) writes) and as .nii; the default phantom
# 256x256x192; MNI152. Rounds alternate the variants so drift hits them alike.
# Carry the loader packages and .sv (morphray.xz and mni.nii.xz, both xz):
#   run(command="bash benches/device-streamed.sh", carry=[".glmin", ".sv"])
set -uo pipefail
# Loader, OUT, RAW, V, M and $V/mni152.nii.gz (benches/device-common.sh).
source benches/device-common.sh
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$RAW/device.txt"
nproc | tee -a "$RAW/device.txt"
$M phantom -o "$V/p512.nii.gz" --dims 512x512x512 > /dev/null
$M phantom -o "$V/p256.nii.gz" > /dev/null
cp "$V/p256.nii.gz" "$V/p256b.nii.gz"
python3 -c 'import gzip,shutil,sys; shutil.copyfileobj(gzip.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    "$V/p512.nii.gz" "$V/p512.nii"
gzip -6 -c "$V/p512.nii" > "$V/p512-single.nii.gz"
ls -l "$V" | tee "$RAW/volumes.txt"
$M info "$V/p512.nii.gz" | head -3 >> "$RAW/volumes.txt"
$M info "$V/p512-single.nii.gz" | head -3 >> "$RAW/volumes.txt"

ttfp() { # NAME FILE [ENV...]; skipped past 470 s so the call ends inside the device's 10 minutes
    local name=$1 file=$2
    shift 2
    if [ "$SECONDS" -gt 470 ]; then echo "$name: skipped (time)"; return; fi
    env "$@" $M bench "$file" --trials 5 --frames 10 --repeat 1 --size 1920x1080 \
        --curvature on --shading on --json "$RAW/$name.json" > "$RAW/$name.txt" 2>&1
    printf '%-28s %s | %s\n' "$name" \
        "$(grep -E 'total \(spawn' "$RAW/$name.txt" | tr -s ' ' | cut -c1-90)" \
        "$(grep -E 'load path' "$RAW/$name.txt" | tr -s ' ')"
}
{
# The second file in a running viewer: the viewer opens p256, then the script opens p256b and
# p256 again (each one's first pixel logged from the request), offscreen at 1920x1080.
printf 'open %s\nopen %s\nopen %s\n' "$V/p256b.nii.gz" "$V/p256.nii.gz" "$V/p256b.nii.gz" > "$V/open.txt"
for upload in staged rebar; do
    MORPHRAY_UPLOAD=$upload timeout 120 $M view "$V/p256.nii.gz" --offscreen --size 1920x1080 \
        --curvature on --shading on --frame-budget 0 --script "$V/open.txt" > "$RAW/viewer-$upload.txt" 2>&1
    echo "viewer ($upload): $(grep 'time to first pixel' "$RAW/viewer-$upload.txt" | tr '\n' ';')"
done
for round in 1 2; do
    ttfp "p512gz-t1-$round" "$V/p512.nii.gz" MORPHRAY_IO_THREADS=1 MORPHRAY_UPLOAD=staged
    ttfp "p512gz-staged-$round" "$V/p512.nii.gz" MORPHRAY_UPLOAD=staged
    ttfp "p512gz-rebar-$round" "$V/p512.nii.gz" MORPHRAY_UPLOAD=rebar
    ttfp "p512nii-t1-$round" "$V/p512.nii" MORPHRAY_IO_THREADS=1 MORPHRAY_UPLOAD=staged
    ttfp "p512nii-staged-$round" "$V/p512.nii" MORPHRAY_UPLOAD=staged
    ttfp "p512nii-rebar-$round" "$V/p512.nii" MORPHRAY_UPLOAD=rebar
    ttfp "p512single-staged-$round" "$V/p512-single.nii.gz" MORPHRAY_UPLOAD=staged
    ttfp "p256-t1-$round" "$V/p256.nii.gz" MORPHRAY_IO_THREADS=1 MORPHRAY_UPLOAD=staged
    ttfp "p256-staged-$round" "$V/p256.nii.gz" MORPHRAY_UPLOAD=staged
    ttfp "p256-rebar-$round" "$V/p256.nii.gz" MORPHRAY_UPLOAD=rebar
    ttfp "mni-staged-$round" "$V/mni152.nii.gz" MORPHRAY_UPLOAD=staged
    ttfp "mni-rebar-$round" "$V/mni152.nii.gz" MORPHRAY_UPLOAD=rebar
done
} 2>&1 | tee "$RAW/summary.txt"
cp "$RAW/summary.txt" "$RAW/device.txt" "$OUT/"
tar czf "$OUT/raw.tgz" -C "$RAW" .
