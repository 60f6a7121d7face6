#!/usr/bin/env bash
# A/B of the preparation passes (`morphray bench`'s pass table) between two builds on one device,
# rounds alternated so that drift of a noisy machine falls on both. For each pass: the median over
# rounds of each build's per-run median, and B / A.
# Usage: benches/passes-ab.sh MORPHRAY_A MORPHRAY_B OUT_DIR VOLUME...   (VOLUME `phantom`: the
# built-in one). Environment: SIZE (500x500), ROUNDS (3), REPEAT (3), EXTRA (more bench options,
# `--shading on` when unset).
set -uo pipefail
A=${1:?usage: $0 MORPHRAY_A MORPHRAY_B OUT_DIR VOLUME...}
B=${2:?usage: $0 MORPHRAY_A MORPHRAY_B OUT_DIR VOLUME...}
OUT=${3:?usage: $0 MORPHRAY_A MORPHRAY_B OUT_DIR VOLUME...}
shift 3
SIZE=${SIZE:-500x500}
ROUNDS=${ROUNDS:-3}
REPEAT=${REPEAT:-3}
EXTRA=${EXTRA-"--shading on"}
mkdir -p "$OUT"
SUMMARY="$OUT/summary.txt"
{ echo "A: $("$A" --version)"; echo "B: $("$B" --version)"
  echo "size $SIZE, $ROUNDS rounds, repeat $REPEAT, extra: $EXTRA"; } | tee "$SUMMARY"
for round in $(seq 1 "$ROUNDS"); do
    for vol in "$@"; do
        input=$vol
        [ "$vol" = phantom ] && input=""
        name=$(basename "$vol" | sed 's/\.nii\(\.gz\)\?$//')
        for side in A B; do
            bin=$A
            [ "$side" = B ] && bin=$B
            log="$OUT/$name-$side-$round.txt"
            # shellcheck disable=SC2086
            "$bin" bench $input --size "$SIZE" --frames 1 --repeat "$REPEAT" --trials 0 $EXTRA \
                > "$log" 2>&1 || echo "$name $side round $round: bench failed (see $log)"
            # Pass rows: a name (words), then the median in ms as the first number.
            awk -v n="$name" -v s="$side" '
                /^pass / {on = 1; next}
                /^raymarch:/ {on = 0}
                on && NF > 3 {
                    for (i = 1; i <= NF; i++) if ($i ~ /^[0-9]+\.[0-9]+$/) break
                    label = $1; for (j = 2; j < i; j++) label = label " " $j
                    print n "\t" label "\t" s "\t" $i
                }' "$log" >> "$OUT/rows.tsv"
        done
    done
done
python3 - "$OUT/rows.tsv" <<'PY' | tee -a "$SUMMARY"
import collections, statistics, sys
rows = collections.defaultdict(list)
for line in open(sys.argv[1]):
    vol, name, side, ms = line.rstrip("\n").split("\t")
    rows[(vol, name, side)].append(float(ms))
print(f"{'volume':<12} {'pass':<28} {'A ms':>10} {'B ms':>10} {'B/A':>6}")
for (vol, name, side) in sorted(rows):
    if side != "A" or (vol, name, "B") not in rows:
        continue
    a = statistics.median(rows[(vol, name, "A")])
    b = statistics.median(rows[(vol, name, "B")])
    print(f"{vol:<12} {name:<28} {a:>10.2f} {b:>10.2f} {b / a if a else float('nan'):>6.2f}")
PY
