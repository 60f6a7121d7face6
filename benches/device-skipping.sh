#!/usr/bin/env bash
# Empty-space skipping on real heads and the cost of shading, on the lent GPU machine (issue 17
# item 2, issue 16 item 6). A/B of two release binaries in .sk/: `before` (adaptive windows
# whose darkest edge reached below the background: every MNI152 brick "visible") and `after`;
# each `morphray bench` at 1920x1080, step 0.5, all tissues, 100 orbit frames, alternated
# three times. Then `after` without curvature and without shading, for what shading costs.
# Carry the Vulkan loader packages and the binaries with the MNI152 copy:
#   run(command="bash benches/device-skipping.sh", carry=[".glmin", ".sk"])
set -uo pipefail
for f in .glmin/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem --format=csv,noheader | tee "$OUT/device.txt"
bench() { # NAME BINARY VOLUME ARGS...
    local name=$1 bin=$2 vol=$3
    shift 3
    ".sk/$bin" bench $vol --trials 0 --frames 100 --repeat 3 --size 1920x1080 "$@" \
        --json "$OUT/$name.json" > "/tmp/$name.txt" 2>&1
    echo "$name: $(grep -E '^raymarch:' "/tmp/$name.txt" | cut -c1-80) | $(grep -E '^empty-space' "/tmp/$name.txt" | cut -c1-70)"
}
for round in 1 2 3; do
    for vol in phantom mni; do
        input=""
        [ "$vol" = mni ] && input=.sk/mni.nii.gz
        for bin in before after; do
            bench "$vol-$bin-cs-$round" "$bin" "$input" --curvature on --shading on
        done
        bench "$vol-after-s-$round" after "$input" --shading on
        bench "$vol-after-plain-$round" after "$input"
    done
done 2>&1 | tee "$OUT/summary.txt"
