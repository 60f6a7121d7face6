#!/usr/bin/env bash
# Side by side with the peers and a scaling curve (issue 17 item 5), on the lent GPU machine, one
# call. Volumes: the phantom at four sizes (128x128x96, 256x256x192 = the default, 384x384x288,
# 512x512x512 = 134 M voxels) and the MNI152 2009a T1 template; the largest also as .nii. Each:
# `morphray bench` (1920x1080, step 0.5, curvature + shading, 100 orbit frames x 3, first pixel
# from 5 fresh processes) and the peers on the same file (tools/peers: VTK 9.7.1 composite
# shaded and plain, pygfx 0.17 MIP; 100 frames, 3 fresh processes each).
# Carry the loader packages, .sv (morphray.xz: a stripped release binary, mni.nii.xz: the MNI152
# copy, both xz -9e) and the peers:
#   tools/peers/stage.sh; run(command="bash benches/device-scaling.sh", carry=[".glmin", ".sv", ".peers"])
# SIZE=500x500 renders every frame at that size instead of 1920x1080 (issue 33 item 4 asks for
# both; one call each, the two together would pass the device's 600 s a call).
# When the carry cannot hold every peer with the repository (64 MiB in all), split the run:
# PEERS=vtk-composite,vtk-composite-plain with only VTK staged in .peers, then BENCH=0
# PEERS=pygfx-mip SUFFIX=-pygfx with only the pygfx wheels; scaling_report.py merges
# peers-NAME*/ of one volume. PEERS=none runs morphray alone.
set -uo pipefail
SIZE=${SIZE:-1920x1080}
PEERS=${PEERS:-vtk-composite,vtk-composite-plain,pygfx-mip}
BENCH=${BENCH:-1}
SUFFIX=${SUFFIX:-}
for f in .glmin/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
RAW=$(mktemp -d)  # everything, handed back as one archive (the machine returns few files)
V=$(mktemp -d)
mkdir -p "$OUT"
# The binary and the MNI152 copy travel xz-compressed (the carry's 64 MiB holds the peers too).
python3 -c 'import lzma,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
    .sv/morphray.xz /tmp/morphray && chmod +x /tmp/morphray
python3 -c 'import lzma,gzip,shutil,sys; shutil.copyfileobj(lzma.open(sys.argv[1]), gzip.open(sys.argv[2], "wb", 6))' \
    .sv/mni.nii.xz /tmp/mni152.nii.gz
M=/tmp/morphray
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$RAW/device.txt"
echo "size $SIZE" | tee -a "$RAW/device.txt"
for dims in 128x128x96 256x256x192 384x384x288 512x512x512; do
    $M phantom -o "$V/phantom-$dims.nii.gz" --dims "$dims" > /dev/null
done
$M convert "$V/phantom-512x512x512.nii.gz" -o "$V/phantom-512x512x512.nii" > /dev/null 2>&1 \
    || python3 -c 'import gzip,shutil,sys; shutil.copyfileobj(gzip.open(sys.argv[1]), open(sys.argv[2], "wb"))' \
        "$V/phantom-512x512x512.nii.gz" "$V/phantom-512x512x512.nii"
cp /tmp/mni152.nii.gz "$V/mni152.nii.gz"
ls -l "$V" | tee "$RAW/volumes.txt"
for vol in phantom-128x128x96.nii.gz phantom-256x256x192.nii.gz mni152.nii.gz \
    phantom-384x384x288.nii.gz phantom-512x512x512.nii.gz phantom-512x512x512.nii; do
    name=${vol//./-}
    echo "== $vol"
    [ "$BENCH" = 1 ] && $M bench "$V/$vol" --frames 100 --repeat 3 --trials 5 --size "$SIZE" \
        --curvature on --shading on --json "$RAW/bench-$name.json" > "$RAW/bench-$name.txt" 2>&1
    [ "$BENCH" = 1 ] && grep -E '^raymarch:|^time to first pixel|^first pixel' "$RAW/bench-$name.txt" | cut -c1-150
    case $vol in *.nii) continue ;; esac  # the peers read .nii.gz like .nii: once per volume
    [ "$PEERS" = none ] && continue
    PEERS_SKIP_PROBE=1 timeout 400 bash tools/peers/device-peers.sh "$V/$vol" --size "$SIZE" \
        --frames 100 --trials 3 --peers "$PEERS" \
        --out "$RAW/peers-$name$SUFFIX" > "$RAW/peers-$name$SUFFIX.txt" 2>&1
    tail -n 6 "$RAW/peers-$name$SUFFIX.txt" | cut -c1-150
done 2>&1 | tee "$RAW/summary.txt"
cp "$RAW/summary.txt" "$RAW/device.txt" "$OUT/"
tar czf "$OUT/raw.tgz" -C "$RAW" .
