#!/usr/bin/env bash
# Runs on the lent GPU machine (see device-payload.sh): unpacks the Vulkan loader and validation
# layers (../shared/GPU.md), then runs every test binary with validation, `peaks`, 1920x1080
# benchmarks of the phantom (all tissues visible, step 0.5 voxel): the full plan (curvature and
# shading), DVR without curvature, MIP, the full plan bricked, the full plan under the gen12
# profile; the plans of those scenes; a render under a 16 MiB budget (bricking); and the accuracy
# study (errors at 256x256, times at 1920x1080; the phantom, and MNI152 when .data/ carries it).
# The device returns at most 8 files: run-log.txt and tests.txt beside
# results.tgz, which holds every JSON, SVG and PNG.
# Stages: `bash benches/device-run.sh [tests] [bench] [sweep] [accuracy]` (default: tests, bench,
# accuracy); `sweep` times the raymarch, derivative and normalize passes over workgroup shapes.
set -uo pipefail
stages=" ${*:-tests bench accuracy} "
want() { [[ "$stages" == *" $1 "* ]]; }
# GL: the folder of Debian packages (.gl; a bench/peers call may carry a smaller one without the
# validation layers and spirv-tools). G: the binaries (.gpu, or just the release binary).
GL=${GL:-.gl}
G=${G:-.gpu}
for f in "$GL"/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
mkdir -p /opt/vk
for f in "$GL"/vulkan-tools*.deb "$GL"/vulkan-validationlayers*.deb "$GL"/libx*.deb "$GL"/libwayland*.deb "$GL"/spirv-tools*.deb; do
    [ -f "$f" ] && dpkg -x "$f" /opt/vk
done
export PATH=/opt/vk/usr/bin:$PATH
export LD_LIBRARY_PATH=/opt/vk/usr/lib/x86_64-linux-gnu
export VK_LAYER_PATH=/opt/vk/usr/share/vulkan/explicit_layer.d
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem,clocks.max.sm,temperature.gpu,power.draw --format=csv | tee "$OUT/nvidia-smi.txt"
$G/morphray devices
# The cli tests start the binary at the path cargo compiled into them.
cli_binary=$(grep -a -o '/[[:alnum:]_./-]*/target/release/morphray' $G/cli | head -n 1 || true)
if [ -n "$cli_binary" ]; then mkdir -p "$(dirname "$cli_binary")" && cp $G/morphray "$cli_binary"; fi
W=/tmp/morphray-work
rm -rf "$W" && mkdir -p "$W"
# CPU-only test binaries (loader, phantom, reference twins, fuzz seeds) ran on the CI machine;
# the viewer's needs a display server (Xvfb), which the GPU machine does not have.
want tests && for t in $(ls $G | grep -v -E '^(morphray|fuzz_regressions|nifti_properties|nifti_loader|phantom|reference|reference_raymarch|peaks|viewer)$'); do
    echo "== $t"
    $G/$t --test-threads=4 --nocapture 2>&1 | grep -v -E "^ +[0-9]+: |^ +at /rustc|^stack backtrace|^note: Some details"
done 2>&1 | tee "$OUT/tests.txt" | grep -E "==|test result|FAILED|panicked"
$G/morphray peaks --json > "$W/peaks.json"
run() { echo "== morphray $*" | tee -a "$OUT/run-log.txt"; $G/morphray "$@" 2>&1 | tee -a "$OUT/run-log.txt"; }
# Time to first pixel is measured once, in the peers stage (--trials 5 of the side-by-side bench).
common="--tissues csf,gm,wm,pathology --frames 100 --repeat 10 --trials 0"
if want bench; then
# Issue 7: time and memory of the full plan, DVR without curvature, MIP; bricking at the same image.
run bench $common --curvature on --shading on --json "$W/bench-full.json"
run bench $common --curvature off --json "$W/bench-dvr-no-curvature.json"
run bench $common --mode mip --json "$W/bench-mip.json"
run --bricked bench $common --curvature on --shading on --json "$W/bench-full-bricked.json"
run --profile gen12 bench $common --curvature on --shading on --json "$W/bench-full-gen12.json"
for scene in "full:--curvature on --shading on" "dvr-no-curvature:--curvature off" "mip:--mode mip"; do
    $G/morphray plan --size 1920x1080 --tissues csf,gm,wm,pathology ${scene#*:} --json > "$W/plan-${scene%%:*}.json"
done
$G/morphray --bricked plan --size 1920x1080 --tissues csf,gm,wm,pathology --curvature on --shading on --json > "$W/plan-full-bricked.json"
# The phantom (24 MiB as R16) under a 16 MiB budget: bricking.
run --memory-budget 16M plan --size 512x512 --curvature on
run --memory-budget 16M render --size 512x512 --curvature on -o "$W/budget-16M.png"
run render --size 512x512 --curvature on -o "$W/whole.png"
fi
if want sweep; then
# Issue 5: workgroup shapes as measured choices (full plan; the analysis passes run once each).
for wg in 8x8 16x8 16x16 8x4 32x4 4x4; do
    run --wg raymarch=$wg bench $common --curvature on --shading on --json "$W/sweep-raymarch-$wg.json"
done
for wg in 8x8x4 4x4x4 16x4x4 8x8x8 32x4x2 8x8x1; do
    run --wg derivatives=$wg --wg normalize=$wg bench $common --curvature on --shading on --json "$W/sweep-volume-$wg.json"
done
fi
if want peers; then
# Issue 5: the peers on the same volume file, image size and sampling distance
# (tools/peers/README.md), beside morphray's bench of the same file and scenes.
$G/morphray phantom -o /tmp/phantom.nii.gz
run bench /tmp/phantom.nii.gz --tissues csf,gm,wm,pathology --frames 200 --trials 5 --curvature on --shading on --json "$W/side-full.json"
run bench /tmp/phantom.nii.gz --tissues csf,gm,wm,pathology --frames 200 --trials 5 --shading on --json "$W/side-dvr-shaded.json"
run bench /tmp/phantom.nii.gz --tissues csf,gm,wm,pathology --frames 200 --trials 5 --mode mip --json "$W/side-mip.json"
bash tools/peers/device-peers.sh /tmp/phantom.nii.gz --size 1920x1080 --frames 200 --trials 5 --png --out "$W/peers" 2>&1 | tee -a "$OUT/run-log.txt"
fi
if want accuracy; then
# Issue 6: errors at 256x256 against the f64 pipeline, times at 1920x1080.
run accuracy --size 256x256 --time-size 1920x1080 --views 3 --frames 25 --json "$W/accuracy.json" --plot "$W/accuracy.svg"
if [ -f .data/mni152.nii.gz ]; then
    run accuracy .data/mni152.nii.gz --size 256x256 --time-size 1920x1080 --views 3 --frames 25 \
        --json "$W/accuracy-mni152.json" --plot "$W/accuracy-mni152.svg"
fi
fi
nvidia-smi --query-gpu=clocks.sm,clocks.mem --format=csv | tee -a "$OUT/nvidia-smi.txt"
tar czf "$OUT/results.tgz" -C "$W" .
