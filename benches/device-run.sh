#!/usr/bin/env bash
# Runs on the lent GPU machine (see device-payload.sh): unpacks the Vulkan loader and validation
# layers (../shared/GPU.md), then runs the GPU tests with validation, `peaks`, two 1920x1080
# benchmarks of the phantom (all tissues visible, step 0.5 voxel, curvature on and off) and the
# accuracy study (256x256, 3 views), writing at most 8 files under $OUT.
set -uo pipefail
for f in .gl/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
mkdir -p /opt/vk
for f in .gl/vulkan-tools*.deb .gl/vulkan-validationlayers*.deb .gl/libx*.deb .gl/libwayland*.deb .gl/spirv-tools*.deb; do dpkg -x "$f" /opt/vk; done
export PATH=/opt/vk/usr/bin:$PATH
export LD_LIBRARY_PATH=/opt/vk/usr/lib/x86_64-linux-gnu
export VK_LAYER_PATH=/opt/vk/usr/share/vulkan/explicit_layer.d
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem,clocks.max.sm,temperature.gpu,power.draw --format=csv | tee "$OUT/nvidia-smi.txt"
G=.gpu
$G/morphray devices
# The cli tests start the binary at the path cargo compiled into them.
cli_binary=$(grep -a -o '/[[:alnum:]_./-]*/target/release/morphray' $G/cli | head -n 1 || true)
if [ -n "$cli_binary" ]; then mkdir -p "$(dirname "$cli_binary")" && cp $G/morphray "$cli_binary"; fi
for t in lib_tests shaders gpu_kernels gpu_raymarch cli; do
    echo "== $t"
    [ -x "$G/$t" ] && $G/$t --test-threads=4 --nocapture 2>&1 | grep -E "PSNR|^test |test result|panicked|error"
done 2>&1 | tee "$OUT/tests.txt" | grep -E "==|test result|FAILED|panicked"
$G/morphray peaks --json > "$OUT/peaks.json"
# Text reports go to one log (the device returns at most 8 files); JSON beside it.
for curvature in on off; do
    $G/morphray bench --tissues csf,gm,wm,pathology --frames 200 --repeat 20 --curvature $curvature \
        --json "$OUT/bench-curv-$curvature.json" 2>&1 | tee -a "$OUT/run-log.txt"
done
$G/morphray accuracy --size 256x256 --views 3 --frames 9 --json "$OUT/accuracy.json" \
    --plot "$OUT/accuracy.svg" 2>/dev/null | tee -a "$OUT/run-log.txt"
nvidia-smi --query-gpu=clocks.sm,clocks.mem --format=csv | tee -a "$OUT/nvidia-smi.txt"
