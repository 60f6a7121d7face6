#!/usr/bin/env bash
# Issue 13 item 5: the per-frame host overhead (CPU wall minus GPU time of the raymarch) before
# and after per-queue reuse, without and with readback, at 1920x1080 for the phantom
# (256x256x192, 12.6 M voxels) and for a 512x512x520 phantom (136.3 M voxels).
#
#   GL=.glmin B=.gap-before G=.gap-after bash benches/gap-run.sh       (on the lent GPU machine)
#   B=/tmp/before G=target/release bash benches/gap-run.sh [WxH] [FRAMES]   (here, lavapipe)
#
# B and G are folders holding a `morphray` release binary: B built at the commit before the reuse
# work (5c4c489, which already reports the gap), G at the reuse commit. GL (optional) is the
# folder of Vulkan loader packages that device-run.sh unpacks on the GPU machine. Runs alternate
# before/after three times, so drifting clocks or a busy host touch both alike. Each run prints
# "frame overhead (CPU wall - GPU, per frame): ..." and writes its JSON under $OUT.
set -uo pipefail
if [ -n "${GL:-}" ]; then
    for f in "$GL"/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do [ -f "$f" ] && dpkg -x "$f" /; done
    ldconfig
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
size=${1:-1920x1080}
frames=${2:-200}
OUT=${OUT:-/tmp/morphray-gap}
mkdir -p "$OUT"
W=$(mktemp -d)
"$G/morphray" phantom -o "$W/phantom.nii.gz" >/dev/null
"$G/morphray" phantom --dims 512x512x520 -o "$W/large.nii.gz" >/dev/null
common=(--size "$size" --tissues csf,gm,wm,pathology --curvature on --shading on --frames "$frames" --repeat 1 --trials 0)
for round in 1 2 3; do
    for which in before after; do
        if [ "$which" = before ]; then bin=$B/morphray; else bin=$G/morphray; fi
        for input in phantom large; do
            echo "== $which $input round $round" | tee -a "$OUT/gap-log.txt"
            "$bin" bench "$W/$input.nii.gz" "${common[@]}" --json "$OUT/gap-$which-$input-$round.json" 2>&1 |
                grep -E "^morphray: |raymarch:|frame overhead" | tee -a "$OUT/gap-log.txt"
        done
    done
done
rm -rf "$W"
