#!/usr/bin/env bash
# Issue 33 item 5 on a lent machine with two H200s (kind nvidia-h200-x2), one call: the cohort
# workflow's throughput with one shard per GPU. 96 MNI152-sized phantom scans (197x233x189
# int16, gzip; hard links of one file, as tools/workflow/bench_batch.sh makes them), each
# `morphray batch ... participant` with its three thumbnails, run three ways, each three times:
#   one    one process, all scans, GPU 0;
#   same   two shards (--shard 0/2, 1/2) at once, both on GPU 0 (what two processes alone give:
#          the host work of the other shard overlaps);
#   two    two shards at once, one per GPU (--device 0, --device 1).
# "two" against "same" is what the second GPU adds; "two" against "one" the whole gain.
# SHARDS=4 runs four shards instead of two (same: all on GPU 0; two: shards alternate GPUs).
# Build here: cargo build --release; mkdir -p .gpu; cp target/release/morphray .gpu/;
#   strip .gpu/morphray; then run(kind="nvidia-h200-x2", command="bash benches/device-two-gpus.sh",
#   carry=[".gl", ".gpu"]).
set -uo pipefail
for f in .gl/lib{vulkan1,egl1,glvnd0,opengl0,gl1,glx0,gles2}_*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
M=$PWD/.gpu/morphray
OUT=${OUT:-/tmp/morphray-out}
mkdir -p "$OUT"
W=$(mktemp -d)
nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$OUT/two-gpus.txt"
$M devices 2>&1 | tee -a "$OUT/two-gpus.txt"
n=${N:-96}
$M phantom --dims 197x233x189 -o "$W/scan.nii.gz" > /dev/null
for i in $(seq -w 1 "$n"); do
    mkdir -p "$W/bids/sub-$i/anat"
    ln "$W/scan.nii.gz" "$W/bids/sub-$i/anat/sub-${i}_T1w.nii.gz"
done
batch() { # OUTDIR ARGS...
    local out=$1
    shift
    $M batch "$W/bids" "$out" participant "$@" > "$out.log" 2>&1
}
shards=${SHARDS:-2}
timed() { # NAME RUN: prints wall seconds and scans/s
    local name=$1 run=$2 start end s
    rm -rf "$W/o-$name-$run"*
    start=$(date +%s.%N)
    case $name in
        one) batch "$W/o-one-$run" --device 0 ;;
        same) for s in $(seq 0 $((shards - 1))); do
                  batch "$W/o-same-$run-$s" --device 0 --shard "$s/$shards" &
              done; wait ;;
        two) for s in $(seq 0 $((shards - 1))); do
                 batch "$W/o-two-$run-$s" --device $((s % 2)) --shard "$s/$shards" &
             done; wait ;;
    esac
    end=$(date +%s.%N)
    local ok
    ok=$(cat "$W"/o-"$name"-"$run"*/logs/participant_shard-*.jsonl 2>/dev/null | grep -c '"status":"ok"')
    python3 -c "import sys; n,s,e=int(sys.argv[1]),float(sys.argv[2]),float(sys.argv[3]); print(f'$name ($shards shards) run $run: {n} scans ok in {e-s:.2f} s: {n/(e-s):.2f} scans/s')" \
        "$ok" "$start" "$end" | tee -a "$OUT/two-gpus.txt"
}
for run in 1 2 3; do
    for name in one same two; do timed "$name" "$run"; done
done
tail -n 3 "$W"/o-two-1-0.log >> "$OUT/two-gpus.txt"
