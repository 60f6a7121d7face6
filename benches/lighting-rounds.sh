#!/usr/bin/env bash
# The rounds of the lighting benchmark (issue 34), shared by benches/device-lighting.sh (H200)
# and benches/lavapipe-lighting.sh: for each volume given, `morphray bench` of seven looks
# alternated in one order per round, 3 rounds; one line per run with the raymarch's frame.
# Environment: M (the binary), SIZE, FRAMES, LOG (appended to).
set -uo pipefail
: "${M:?binary}" "${SIZE:?WxH}" "${FRAMES:?frames}" "${LOG:?log file}"
T=$(mktemp -d)
looks=(
    "headlight|--lighting headlight --depth-cues off"
    "studio|--lighting studio --depth-cues off"
    "studio+cues|--lighting studio --depth-cues on"
    "headlight+cues|--lighting headlight --depth-cues on"
    "cutaway|--lighting studio --depth-cues on --cutaway --azimuth 40 --elevation 25"
    "matcap|--lighting matcap --depth-cues off"
    "matcap+cues|--lighting matcap --depth-cues on"
)
for round in 1 2 3; do
    for file in "$@"; do
        for look in "${looks[@]}"; do
            name=${look%%|*}
            # shellcheck disable=SC2086 # the flags are words
            $M bench "$file" --size "$SIZE" --frames "$FRAMES" --repeat 1 --trials 0 --shading on \
                ${look#*|} > "$T/run.txt" 2>&1
            echo "$(basename "$file") $name r$round: $(grep -E '^raymarch:' "$T/run.txt" | head -1 | cut -c1-160)" | tee -a "$LOG"
        done
    done
done
