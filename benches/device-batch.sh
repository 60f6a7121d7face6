#!/usr/bin/env bash
# Cohort throughput on the lent GPU machine (issue 19 item 4): tools/workflow/bench_batch.sh
# (one `morphray batch` process over 100 MNI152-sized scans, peaks only, then with three
# thumbnails) three times, with the participant logs. Carry the Vulkan loader packages (.glmin,
# see device-payload.sh) and the release binary in .bb/:
#   run(command="bash benches/device-batch.sh", carry=[".glmin", ".bb"])
set -uo pipefail
for f in .glmin/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/device.txt"
.bb/morphray devices | tee -a "$OUT/device.txt"
for run in 1 2 3; do
    echo "== run $run" | tee -a "$OUT/batch.txt"
    bash tools/workflow/bench_batch.sh .bb/morphray 100 "/tmp/bb$run" 2>&1 | tee -a "$OUT/batch.txt"
    cp "/tmp/bb$run/out-peaks/logs/participant_shard-0-of-1.jsonl" "$OUT/peaks-run$run.jsonl"
    cp "/tmp/bb$run/out-thumbnails/logs/participant_shard-0-of-1.jsonl" "$OUT/thumbnails-run$run.jsonl"
done
