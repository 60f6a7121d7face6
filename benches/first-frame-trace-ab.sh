#!/usr/bin/env bash
# Where a first frame's time goes, per build: `morphray --trace` of one `render` (fresh process,
# driver shader cache off so every run compiles), builds alternated per round; medians over
# rounds of the wall time, each pipeline kind's compile time (worker threads) and the main
# passes' GPU times (on lavapipe the first dispatch includes the driver's JIT of the variant).
# Usage: benches/first-frame-trace-ab.sh OUT_DIR ROUNDS VOLUME MORPHRAY...
# Environment: SIZE (500x500), EXTRA (more render options).
set -uo pipefail
OUT=${1:?usage: $0 OUT_DIR ROUNDS VOLUME MORPHRAY...}
ROUNDS=${2:?usage: $0 OUT_DIR ROUNDS VOLUME MORPHRAY...}
VOL=${3:?usage: $0 OUT_DIR ROUNDS VOLUME MORPHRAY...}
shift 3
SIZE=${SIZE:-500x500}
EXTRA=${EXTRA-}
mkdir -p "$OUT"
: > "$OUT/wall.txt"
for round in $(seq 1 "$ROUNDS"); do
    for bin in "$@"; do
        name=$(basename "$bin")
        start=$(date +%s%N)
        # shellcheck disable=SC2086
        MESA_SHADER_CACHE_DISABLE=true "$bin" --trace "$OUT/$name-$round.json" render "$VOL" \
            --size "$SIZE" $EXTRA -o "$OUT/$name-$round.png" > "$OUT/$name-$round.log" 2>&1 \
            || echo "$name round $round failed (see $OUT/$name-$round.log)"
        end=$(date +%s%N)
        echo "$name $round $(( (end - start) / 1000000 ))" >> "$OUT/wall.txt"
    done
done
python3 - "$OUT" "$@" <<'PY' | tee "$OUT/summary.txt"
import collections, glob, json, os, statistics, sys
out, names = sys.argv[1], [os.path.basename(b) for b in sys.argv[2:]]
walls = collections.defaultdict(list)
for line in open(f"{out}/wall.txt"):
    name, _, ms = line.split()
    walls[name].append(float(ms))
KEEP = ("prepare (upload, min/max, range, normalize, histogram)", "derived volumes",
        "brain extraction", "occupancy", "raymarch", "frame")
for name in names:
    rows = collections.defaultdict(list)
    for path in glob.glob(f"{out}/{name}-*.json"):
        trace = json.load(open(path))
        events = trace["traceEvents"] if isinstance(trace, dict) else trace
        sums = collections.defaultdict(float)
        for e in events:
            if e.get("ph") != "X":
                continue
            label = e["name"]
            if label.startswith("pipeline "):
                label = "compile " + label[len("pipeline "):].split(" (")[0]
            elif label not in KEEP:
                continue
            sums[label] += e["dur"] / 1000
        for label, ms in sums.items():
            rows[label].append(ms)
    print(f"{name}: wall {statistics.median(walls[name]):.0f} ms (median of {len(walls[name])})")
    for label in sorted(rows):
        print(f"  {label:<58} {statistics.median(rows[label]):9.1f} ms")
PY
