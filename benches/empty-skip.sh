#!/usr/bin/env bash
# Issue 33 item 3: empty-space skipping by the distance map against the occupancy bits alone
# (`--empty-skip distance` vs `bricks`, the same picture), per volume, rounds alternated.
# For each run: the raymarch's GPU median, the occupied share, and the distance map's rebuild
# time (the "brick distance" pass, run when the classification changes).
# Usage: benches/empty-skip.sh MORPHRAY OUT_DIR VOLUME...   (VOLUME `phantom`: the built-in one)
# Environment: SIZE (500x500), FRAMES (6), ROUNDS (3), REPEAT (1), EXTRA (more bench options,
# `--shading on` when unset; EXTRA= runs bench's own default scene).
set -uo pipefail
M=${1:?usage: $0 MORPHRAY OUT_DIR VOLUME...}
OUT=${2:?usage: $0 MORPHRAY OUT_DIR VOLUME...}
shift 2
SIZE=${SIZE:-500x500}
FRAMES=${FRAMES:-6}
ROUNDS=${ROUNDS:-3}
REPEAT=${REPEAT:-1}
EXTRA=${EXTRA-"--shading on"}
mkdir -p "$OUT"
SUMMARY="$OUT/summary.txt"
"$M" --version | tee "$SUMMARY"
echo "size $SIZE, $FRAMES frames, $ROUNDS rounds, extra: $EXTRA" | tee -a "$SUMMARY"
for round in $(seq 1 "$ROUNDS"); do
    for vol in "$@"; do
        input=$vol
        [ "$vol" = phantom ] && input=""
        name=$(basename "$vol" | sed 's/\.nii\(\.gz\)\?$//')
        for mode in bricks distance; do
            log="$OUT/$name-$mode-$round.txt"
            # shellcheck disable=SC2086
            "$M" bench $input --size "$SIZE" --frames "$FRAMES" --repeat "$REPEAT" --trials 0 \
                --empty-skip "$mode" $EXTRA --json "$OUT/$name-$mode-$round.json" > "$log" 2>&1
            raymarch=$(grep -E '^raymarch:' "$log" | sed 's/ ms GPU median.*//; s/raymarch: //')
            share=$(grep -E '^empty-space' "$log" | grep -oE '[0-9.]+ % of the [0-9]+' | head -1)
            rebuild=$(grep -E '^brick distance ' "$log" | awk '{print $3}')
            echo "$name $mode round $round: raymarch ${raymarch:-?} ms | occupied ${share:-?} bricks | distance map ${rebuild:-?} ms" | tee -a "$SUMMARY"
        done
    done
done
echo "medians per volume and mode (ms):" | tee -a "$SUMMARY"
awk '/ round [0-9]+: raymarch/ {k=$1" "$2; v[k]=v[k]" "$6} END {for (k in v) print k, v[k]}' "$SUMMARY" |
    while read -r name mode values; do
        median=$(echo "$values" | tr ' ' '\n' | sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}')
        echo "  $name $mode: $median (of $values)"
    done | sort | tee -a "$SUMMARY"
