#!/usr/bin/env bash
# Transparent huge pages for the loader's large buffers (issue 17 items 1 and 4): first pixel with
# and without the MADV_HUGEPAGE advice (MORPHRAY_HUGE_PAGES=off), alternated over two rounds in
# the same call, on the 134 M-voxel phantom (.nii.gz of 1 MiB members and .nii) and the default
# phantom, plus the second file opened in a running viewer. `morphray bench --trials 5` at
# 1920x1080, step 0.5, curvature + shading; the BAR upload (the default) throughout.
# Carry the loader packages and .sv (morphray.xz and mni.nii.xz):
#   run(command="bash benches/device-hugepages.sh", carry=[".glmin", ".sv"])
set -uo pipefail
# Loader, OUT, RAW, V, M and $V/mni152.nii.gz (benches/device-common.sh).
source benches/device-common.sh
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; nproc; uname -r
  echo "THP: $(cat /sys/kernel/mm/transparent_hugepage/enabled) defrag: $(cat /sys/kernel/mm/transparent_hugepage/defrag)"; } | tee "$RAW/device.txt"
$M phantom -o "$V/p256.nii.gz" > /dev/null
cp "$V/p256.nii.gz" "$V/p256b.nii.gz"
$M phantom -o "$V/p512.nii.gz" --dims 512x512x512 > /dev/null
python3 -c 'import gzip,shutil,sys; shutil.copyfileobj(gzip.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    "$V/p512.nii.gz" "$V/p512.nii"
ttfp() { # NAME FILE [ENV...]; skipped past 480 s so the call ends inside the device's 10 minutes
    local name=$1 file=$2
    shift 2
    if [ "$SECONDS" -gt 480 ]; then echo "$name: skipped (time)"; return; fi
    env "$@" $M bench "$file" --trials 5 --frames 10 --repeat 1 --size 1920x1080 \
        --curvature on --shading on --json "$RAW/$name.json" > "$RAW/$name.txt" 2>&1
    printf '%-22s %s\n' "$name" "$(grep -E 'total \(spawn' "$RAW/$name.txt" | tr -s ' ' | cut -c1-90)"
    grep -E 'read \(|inflate \(' "$RAW/$name.txt" | tr -s ' ' | cut -c1-90
}
{
printf 'open %s\nopen %s\nopen %s\nopen %s\n' "$V/p256b.nii.gz" "$V/p256.nii.gz" "$V/p256b.nii.gz" "$V/p256.nii.gz" > "$V/open.txt"
for round in 1 2; do
    for huge in off on; do
        MORPHRAY_HUGE_PAGES=$huge timeout 120 $M view "$V/p256.nii.gz" --offscreen --size 1920x1080 \
            --curvature on --shading on --frame-budget 0 --script "$V/open.txt" > "$RAW/viewer-huge-$huge-$round.txt" 2>&1
        echo "viewer huge pages $huge: $(grep 'time to first pixel' "$RAW/viewer-huge-$huge-$round.txt" | tr '\n' ';')"
    done
done
for round in 1 2; do
    for huge in off on; do
        ttfp "p512gz-huge-$huge-$round" "$V/p512.nii.gz" MORPHRAY_HUGE_PAGES=$huge
        ttfp "p512nii-huge-$huge-$round" "$V/p512.nii" MORPHRAY_HUGE_PAGES=$huge
        ttfp "p256-huge-$huge-$round" "$V/p256.nii.gz" MORPHRAY_HUGE_PAGES=$huge
    done
done
} 2>&1 | tee "$RAW/summary.txt"
cp "$RAW/summary.txt" "$RAW/device.txt" "$OUT/"
tar czf "$OUT/raw.tgz" -C "$RAW" .
