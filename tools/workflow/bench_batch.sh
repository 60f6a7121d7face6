#!/usr/bin/env bash
# Batch throughput (issue 19 item 4): scans per second of one `morphray batch` process over N
# MNI152-sized scans (197x233x189 int16 phantoms, gzip), peaks only and with three thumbnails,
# with the per-scan time broken down (read, inflate, convert, GPU, render, encode) from the
# participant log's timings.
#
#   tools/workflow/bench_batch.sh [MORPHRAY_BINARY] [N=100] [WORKDIR=/tmp/morphray-bench-batch]
#
# The N scans are hard links of one generated file (each is still read, inflated and processed
# on its own; the file is in the page cache after the first, as a cohort on a warm disk would be).
# Device start-up is in the wall time, not in the per-scan times.
set -euo pipefail
bin="${1:-target/release/morphray}"
n="${2:-100}"
work="${3:-/tmp/morphray-bench-batch}"
rm -rf "$work"
mkdir -p "$work/bids"
"$bin" phantom --dims 197x233x189 -o "$work/scan.nii.gz" >/dev/null
for i in $(seq -w 1 "$n"); do
    mkdir -p "$work/bids/sub-$i/anat"
    ln "$work/scan.nii.gz" "$work/bids/sub-$i/anat/sub-${i}_T1w.nii.gz"
done
run() {
    local name="$1"; shift
    local out="$work/out-$name"
    local start end
    start=$(date +%s.%N)
    "$bin" batch "$work/bids" "$out" participant "$@" 2>/dev/null | tail -1
    end=$(date +%s.%N)
    python3 - "$out/logs/participant_shard-0-of-1.jsonl" "$name" "$start" "$end" <<'PY'
import json, sys, statistics
path, name, start, end = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
rows = [json.loads(l) for l in open(path)]
ok = [r["timings_ms"] for r in rows if r.get("status") == "ok"]
wall = end - start
print(f"{name}: {len(ok)} scans in {wall:.1f} s wall (device start included): "
      f"{len(ok) / wall:.2f} scans/s")
for key in ["read_ms", "inflate_ms", "convert_ms", "wait_ms", "gpu_ms", "render_ms", "encode_ms", "total_ms"]:
    values = [t.get(key, 0.0) for t in ok]
    print(f"  {key:<11} median {statistics.median(values):8.1f} ms   mean {statistics.mean(values):8.1f} ms")
PY
}
run peaks --no-thumbnails
run thumbnails
